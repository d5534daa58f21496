"""What the query modes measure with, and where: their passes and their geometry.

The modes themselves (:mod:`pycinder.focused.modes`) decide what a query asks and what it
reports; this room holds what they measure with, one module each:

* :mod:`~pycinder.focused.measure.pair_work`: what passes C1 and H1 share (an item per cluster
  pair, a frame per candidate pair);
* :mod:`~pycinder.focused.measure.c1_distance`: pass C1, the least distance between two
  clusters' faces;
* :mod:`~pycinder.focused.measure.h1_depth`: pass H1, the directional depth along 19 lines;
* :mod:`~pycinder.focused.measure.h1_items`: which cluster pairs H1 measures along which lines;
* :mod:`~pycinder.focused.measure.regions`: pairs too large for one frame, cut to tiles where
  they meet in float64 before single precision;
* :mod:`~pycinder.focused.measure.local_depth`: a pair with a non-convex body measured where
  its bodies overlap.

Nothing here imports a mode.
"""

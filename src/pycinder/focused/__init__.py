"""The focused strategy (the default): a broad phase, then a small tile per candidate pair with
pixels as wide as the tolerance, and the CInDeR passes run in every tile.

The stages, in the order a query flows through them, one subpackage each:

- :mod:`~pycinder.focused.broad`: world boxes and candidate pairs (NumPy, or passes B1-B8);
- :mod:`~pycinder.focused.plan`: each pair's window and the atlas of tiles (NumPy, or passes
  P0-P3);
- :mod:`~pycinder.focused.frame`: the frame's passes F0-F8, their buffers and their readback;
- :mod:`~pycinder.focused.measure`: what those modes measure with (passes H1 and C1, the
  cluster pairs they measure, regions and local depth);
- :mod:`~pycinder.focused.modes`: the query modes that measure pairs exactly (hard clashes,
  clearance), plug-ins the strategy calls and that never import it.

:mod:`~pycinder.focused.focused_strategy` joins them;
:mod:`~pycinder.focused.frame.rerun_policy` runs the pairs a frame left undecided again.
"""

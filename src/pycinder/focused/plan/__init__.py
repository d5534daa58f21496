"""Tile planning: each candidate pair's window (view, origin, size, depth slab) and the atlas the
windows are packed into, in rounds. :mod:`~pycinder.focused.plan.tiles` is the NumPy planner (the
reference in tests); :mod:`~pycinder.focused.plan.gpu` runs the same plan as passes P0-P3
(:mod:`~pycinder.focused.plan.bodies`, :mod:`~pycinder.focused.plan.windows`,
:mod:`~pycinder.focused.plan.atlas`, :mod:`~pycinder.focused.plan.tilewords`)."""

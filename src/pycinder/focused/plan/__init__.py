"""Tile planning: each candidate pair's window (view, origin, size, depth slab) and the atlas the
windows are packed into, in rounds. :mod:`~pycinder.focused.plan.plan_numpy` is the NumPy planner
(the reference in tests); :mod:`~pycinder.focused.plan.plan_gpu` runs the same plan as passes P0-P3
(:mod:`~pycinder.focused.plan.p0_bodies`, :mod:`~pycinder.focused.plan.p1_windows`,
:mod:`~pycinder.focused.plan.p2_atlas`, :mod:`~pycinder.focused.plan.p3_tile_words`)."""

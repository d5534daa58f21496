"""Query modes that measure candidate pairs exactly, triangle pair by triangle pair: hard clashes
(``min_depth``, pass H1) and clearance (``clearance``, pass C1).

A mode is a plug-in: the focused strategy hands it what it needs (the device, the shapes, the
request, its broad phase's pairs) through :class:`~pycinder.focused.modes.base.ModeHost`, and a
mode never imports the strategy. What the modes measure with (their passes and geometry) is in
:mod:`pycinder.focused.measure`.
"""

"""Looking inside a frame: the whole-scene strategy's buffers after each pass
(:mod:`~pycinder.debug.pass_buffers`, ``pycinder debug-buffers``), as in the paper's Figures 9-13,
and one labelled picture of them (:mod:`~pycinder.debug.montage`)."""

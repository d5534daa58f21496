"""The focused frame: the passes F0-F8 that run in every tile of the atlas (one class per pass,
one module each), the buffers they share (:mod:`~pycinder.focused.frame.atlas_buffers`), and
:mod:`~pycinder.focused.frame.frames`, which encodes, submits and reads back a frame."""

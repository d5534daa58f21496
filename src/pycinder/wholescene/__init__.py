"""The paper's whole-scene strategy (``strategy="scene"``): passes 1-7 over the whole scene at
one resolution, the self-interference filter, the mip reduction and the readbacks.

Modules, in the order a frame runs them: :mod:`~pycinder.wholescene.raycast` (passes 1-7, render
state from :mod:`pycinder.gpu.states`), :mod:`~pycinder.wholescene.selfint` (section 4.3),
:mod:`~pycinder.wholescene.filter` and :mod:`~pycinder.wholescene.reduce` (the compact and mipmap
readbacks' compute passes), :mod:`~pycinder.wholescene.scene_frame` (one frame's encoding and
submission) and :mod:`~pycinder.wholescene.readback` (the readback strategies);
:mod:`~pycinder.wholescene.scene_strategy` joins them.
"""

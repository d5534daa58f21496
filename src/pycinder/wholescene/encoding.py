"""What every pass of a whole-scene frame encodes onto (:class:`SceneFrame`), apart from the
frame that makes it (:mod:`~pycinder.wholescene.scene_frame`), so that the passes need not know the
frame."""

from __future__ import annotations

from dataclasses import dataclass

import wgpu

from ..gpu.bindings import Profiler
from ..gpu.buffers import GrowableBuffer, SceneBuffers, Targets


@dataclass(frozen=True)
class SceneFrame:
    """What every pass of a whole-scene frame encodes onto.

    Attributes
    ----------
    encoder : wgpu.GPUCommandEncoder
    profiler : Profiler
        Gives each pass its timestamp writes (none when profiling is off).
    targets : Targets
        The records and depth-stencil targets of the resolution.
    buffers : SceneBuffers
        The uploaded scene, with the view's matrices written.
    filtered : GrowableBuffer
        The filter's output: level 0 of the mip-map reduction.
    """

    encoder: wgpu.GPUCommandEncoder
    profiler: Profiler
    targets: Targets
    buffers: SceneBuffers
    filtered: GrowableBuffer

"""Indirect arguments between the passes (``frame_arguments.wgsl``): after a pass, one thread turns
its counters into the next pass's indirect dispatch or draw arguments, clamped to what the buffers
hold, and keeps the largest counts for the host to size the buffers."""

from __future__ import annotations

from typing import ClassVar

import wgpu

from ...gpu.bindings import Stage, dispatch
from ...gpu.device import Gpu
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .atlas_buffers import Encoding

PARAMS = Struct("FinalizeParams", [
    ("face_cap", "u32", "face items the buffer holds"),
    ("edge_cap", "u32", "edge items the buffer holds"),
    ("tri_cap", "u32", "clipped triangles the buffer holds"),
    ("list_cap", "u32", "edges the edge list holds"),
], uniform=True)

STEPS = ("after_cull", "after_clip_faces", "after_clip", "after_crossings", "after_edge_list")
"""The entry points, each run after the pass it names (and its sub-step)."""


class Arguments:
    """The indirect arguments of the next pass, written after each pass by one thread."""

    SHADER: ClassVar[str] = "frame_arguments"
    """Its shader, ``shaders/frame_arguments.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "F*", "indirect arguments", "counters of the last pass into the next pass's indirect "
        "dispatch or draw (IndirectArgs)", when="after F1, F2 (twice), F3 and F5's list")
    PARAMS: ClassVar[Struct] = PARAMS

    def __init__(self, gpu: Gpu) -> None:
        self.stages = {step: Stage(gpu, self.SHADER, step, structs=(PARAMS,)) for step in STEPS}

    def write_params(self, e: Encoding) -> None:
        p, caps = e.frame_params("finalize"), e.buffers.caps
        p["face_cap"] = p["edge_cap"] = e.state.items
        p["tri_cap"] = caps.tris
        p["list_cap"] = caps.edges

    def encode(self, cpass: wgpu.GPUComputePassEncoder, e: Encoding, step: str) -> None:
        """Dispatch entry point ``step`` (one of :data:`STEPS`)."""
        stage = self.stages[step]
        dispatch(cpass, stage, stage.group(counters=e.buffers.counters, args=e.buffers.args,
                                           params=e.frame_params.binding("finalize")), 1)


__all__ = ["Arguments", "STEPS"]

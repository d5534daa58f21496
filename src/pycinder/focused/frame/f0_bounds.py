"""Pass F0, cluster bounds: the body-space box of every cluster of the shapes whose vertices
changed (compute, before the rounds of a frame that uploaded new vertices)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import wgpu

from ...gpu.bindings import Profiler, Stage, dispatch
from ...gpu.device import Gpu
from ...gpu.layout import WORKGROUP
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .atlas_buffers import Encoding

PARAMS = Struct("BoundsParams", [("count", "u32", "clusters to update")], uniform=True)


class Bounds:
    """F0: cluster bounds, one thread per cluster to update (``which``)."""

    SHADER: ClassVar[str] = "frame_bounds"
    """Its shader, ``shaders/frame_bounds.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "F0", "cluster bounds", "body-space box of every cluster of the shapes that changed",
        when="when vertices changed")
    PARAMS: ClassVar[Struct] = PARAMS

    def __init__(self, gpu: Gpu) -> None:
        self.stage = Stage(gpu, self.SHADER, "cluster_bounds", label=self.INFO.title,
                           structs=(PARAMS,))

    def write_params(self, e: Encoding, which: np.ndarray | None) -> None:
        e.frame_params("bounds")["count"] = 0 if which is None else len(which)

    def encode(self, encoder: wgpu.GPUCommandEncoder, profiler: Profiler, e: Encoding,
               which: np.ndarray | None) -> None:
        """Bound the clusters ``which`` (none: nothing is encoded)."""
        if which is None or len(which) == 0:
            return
        b = e.buffers
        b.which.ensure(which.nbytes)
        b.which.write(which)
        group = self.stage.group(
            positions=b.positions, faces=b.faces, clusters=b.clusters, which=b.which,
            bounds=b.cluster_bounds, params=e.frame_params.binding("bounds"))
        cpass = encoder.begin_compute_pass(label=self.INFO.title,
                                           **profiler.writes(self.INFO.title))
        dispatch(cpass, self.stage, group, -(-len(which) // WORKGROUP))
        cpass.end()


__all__ = ["Bounds"]

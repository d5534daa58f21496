"""Pass 9 of the whole-scene strategy: the mip-map reduction of the records (paper 4.3.2.2) and
its adaptive, lossless variant (4.3.2.3).

Level 0 is the filter's packed image. Level k+1 keeps one record of each 2x2 block of level k,
and counts the blocks where records of different pairs met (``lost[k + 1]``). All levels are
computed in one submission and kept, so the adaptive mode can read back the deepest level that
lost nothing after looking at the counters.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np
import wgpu

from ..gpu.bindings import PARAM_STRIDE, Stage
from ..gpu.device import Gpu
from ..gpu.structs import Struct
from ..gpu.table import PassInfo
from .filter import RECORD_BYTES, WORKGROUP

if TYPE_CHECKING:
    from .encoding import SceneFrame

PARAMS = Struct("ReduceParams", [
    ("src_width", "u32", "level k - 1"),
    ("src_height", "u32", ""),
    ("dst_width", "u32", "level k"),
    ("dst_height", "u32", ""),
    ("level", "u32", "k: where blocks that merged two pairs are counted"),
], uniform=True, doc="One level of the reduction, written by the host once per resolution.")


def level_sizes(width: int, height: int, levels: int) -> list[tuple[int, int]]:
    """(width, height) of levels 0..levels."""
    sizes = [(width, height)]
    for _ in range(levels):
        w, h = sizes[-1]
        sizes.append(((w + 1) // 2, (h + 1) // 2))
    return sizes


class MipReduce:
    """Pass 9: the reduction chain for one resolution.

    Parameters
    ----------
    gpu : Gpu
    width, height : int
        Of level 0 (the records target).
    levels : int
        How many 2x2 reductions to compute.

    Attributes
    ----------
    lost : wgpu.GPUBuffer
        (levels + 1,) uint32; ``lost[k]`` counts the blocks of level k where pairs met.
    """

    SHADER: ClassVar[str] = "wholescene_reduce"
    """Its shader, ``shaders/wholescene_reduce.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "9", "mip-map reduction", "keep one record per 2x2 block, level by level; count the "
        "blocks where two pairs met", when="every view (readback mipmap, adaptive)")

    def __init__(self, gpu: Gpu, width: int, height: int, levels: int) -> None:
        if levels < 1:
            raise ValueError("mipmap_levels must be at least 1")
        self.gpu, self.levels = gpu, levels
        device = gpu.device
        self.stage = Stage(gpu, self.SHADER, "reduce", label=self.INFO.title, structs=(PARAMS,),
                           consts={"WORKGROUP_SIDE": WORKGROUP})
        usage = wgpu.BufferUsage
        self.sizes = level_sizes(width, height, levels)
        self.buffers = [device.create_buffer(label=f"mip level {k}", size=w * h * RECORD_BYTES,
                                             usage=usage.STORAGE | usage.COPY_SRC)
                        for k, (w, h) in enumerate(self.sizes) if k > 0]
        self.lost = device.create_buffer(label="mip loss", size=4 * (levels + 1),
                                         usage=usage.STORAGE | usage.COPY_SRC | usage.COPY_DST)
        self._zeros = np.zeros(levels + 1, dtype=np.uint32)
        params = PARAMS.zeros(levels, stride=PARAM_STRIDE)
        for k in range(1, levels + 1):
            block = params[k - 1]
            (block["src_width"], block["src_height"]), (block["dst_width"], block["dst_height"]) \
                = self.sizes[k - 1], self.sizes[k]
            block["level"] = k
        self.params = device.create_buffer(label="mip params", size=params.nbytes,
                                           usage=usage.UNIFORM | usage.COPY_DST)
        device.queue.write_buffer(self.params, 0, params)

    def level_buffer(self, k: int) -> wgpu.GPUBuffer:
        """The buffer of level ``k`` (1..levels)."""
        return self.buffers[k - 1]

    def level_bytes(self, k: int) -> int:
        """Bytes of level ``k``."""
        w, h = self.sizes[k]
        return w * h * RECORD_BYTES

    def _group(self, k: int, source: wgpu.GPUBuffer) -> wgpu.GPUBindGroup:
        """The bindings of level ``k`` (reduced from level 0 ``source`` when k is 1)."""
        src = source if k == 1 else self.buffers[k - 2]
        return self.stage.group(
            f"level {k}", src=(src, 0, self.level_bytes(k - 1)), dst=self.buffers[k - 1],
            lost=self.lost, params=(self.params, (k - 1) * PARAM_STRIDE, PARAMS.size))

    def encode(self, frame: SceneFrame) -> None:
        """Reduce the filter's packed level 0 ``levels`` times, in one compute pass."""
        groups = [self._group(k, frame.filtered.buffer) for k in range(1, self.levels + 1)]
        self.gpu.device.queue.write_buffer(self.lost, 0, self._zeros)
        cpass = frame.encoder.begin_compute_pass(label=self.INFO.title,
                                                 **frame.profiler.writes(self.INFO.title))
        cpass.set_pipeline(self.stage.pipeline)
        for k, group in enumerate(groups, start=1):
            w, h = self.sizes[k]
            cpass.set_bind_group(0, group)
            cpass.dispatch_workgroups(-(-w // WORKGROUP), -(-h // WORKGROUP))
        cpass.end()


__all__ = ["MipReduce", "PARAMS", "level_sizes"]

"""Mip-map reduction of the records (paper 4.3.2.2) and its adaptive, lossless variant (4.3.2.3).

Level 0 is the filter's packed image. Level k+1 keeps one record of each 2x2 block of level k,
and counts the blocks where records of different pairs met (``lost[k + 1]``). All levels are
computed in one submission and kept, so the adaptive mode can read back the deepest level that
lost nothing after looking at the counters.
"""

from __future__ import annotations

import numpy as np
import wgpu

from ..gpu.device import Gpu, shader_source
from .filter import RECORD_BYTES, WORKGROUP


def level_sizes(width: int, height: int, levels: int) -> list[tuple[int, int]]:
    """(width, height) of levels 0..levels."""
    sizes = [(width, height)]
    for _ in range(levels):
        w, h = sizes[-1]
        sizes.append(((w + 1) // 2, (h + 1) // 2))
    return sizes


class MipReduce:
    """The reduction chain for one resolution.

    levels : how many 2x2 reductions to compute
    lost : (levels + 1,) uint32 buffer; lost[k] counts the blocks of level k where pairs met
    """

    def __init__(self, gpu: Gpu, width: int, height: int, levels: int) -> None:
        if levels < 1:
            raise ValueError("mipmap_levels must be at least 1")
        self.gpu, self.levels = gpu, levels
        device = gpu.device
        module = device.create_shader_module(label="reduce", code=shader_source("reduce"))
        self.pipeline = device.create_compute_pipeline(
            label="mip-map reduce", layout="auto", compute={"module": module, "entry_point": "reduce"})
        usage = wgpu.BufferUsage
        self.sizes = level_sizes(width, height, levels)
        self.buffers = [device.create_buffer(label=f"mip level {k}", size=w * h * RECORD_BYTES,
                                             usage=usage.STORAGE | usage.COPY_SRC)
                        for k, (w, h) in enumerate(self.sizes) if k > 0]
        self.lost = device.create_buffer(label="mip loss", size=4 * (levels + 1),
                                         usage=usage.STORAGE | usage.COPY_SRC | usage.COPY_DST)
        self._zeros = np.zeros(levels + 1, dtype=np.uint32)
        self._params = []
        for k in range(1, levels + 1):
            p = device.create_buffer(size=32, usage=usage.UNIFORM | usage.COPY_DST)
            (sw, sh), (dw, dh) = self.sizes[k - 1], self.sizes[k]
            device.queue.write_buffer(p, 0, np.array([sw, sh, dw, dh, k, 0, 0, 0], np.uint32))
            self._params.append(p)
        self._bind_groups: list[wgpu.GPUBindGroup] = []
        self._source: wgpu.GPUBuffer | None = None

    def level_buffer(self, k: int) -> wgpu.GPUBuffer:
        return self.buffers[k - 1]

    def level_bytes(self, k: int) -> int:
        w, h = self.sizes[k]
        return w * h * RECORD_BYTES

    def _bind(self, source: wgpu.GPUBuffer) -> None:
        if source is self._source:
            return
        chain = [source] + self.buffers
        layout = self.pipeline.get_bind_group_layout(0)
        self._bind_groups = [
            self.gpu.device.create_bind_group(layout=layout, entries=[
                {"binding": 0, "resource": {"buffer": chain[k - 1], "offset": 0,
                                            "size": self.level_bytes(k - 1)}},
                {"binding": 1, "resource": {"buffer": chain[k]}},
                {"binding": 2, "resource": {"buffer": self.lost}},
                {"binding": 3, "resource": {"buffer": self._params[k - 1]}},
            ]) for k in range(1, self.levels + 1)]
        self._source = source

    def encode(self, encoder: wgpu.GPUCommandEncoder, source: wgpu.GPUBuffer) -> None:
        """Reduce ``source`` (the filter's packed level 0) ``levels`` times."""
        self._bind(source)
        self.gpu.device.queue.write_buffer(self.lost, 0, self._zeros)
        cpass = encoder.begin_compute_pass(label="mip-map reduce")
        cpass.set_pipeline(self.pipeline)
        for k, bind_group in enumerate(self._bind_groups, start=1):
            w, h = self.sizes[k]
            cpass.set_bind_group(0, bind_group)
            cpass.dispatch_workgroups(-(-w // WORKGROUP), -(-h // WORKGROUP))
        cpass.end()

"""Passes B6-B8 of the broad phase (``shaders/broad_sweep.wgsl``): the boxes in sorted order,
then the pairs of boxes that overlap, appended to ``pairs`` through an atomic count."""

from __future__ import annotations

import wgpu

from ...gpu.bindings import dispatch
from ...gpu.layout import WORKGROUP
from ...gpu.table import PassInfo
from .broad_common import BroadBuffers, BroadFrame, BroadPass


class _SweepPass(BroadPass):
    SHADER = "broad_sweep"


class Gather(_SweepPass):
    """B6: one thread per sorted position, the box in sorted order (``sorted_lo``,
    ``sorted_hi``: (N, 4) float32; ``sorted_body``: (N,) uint32), so that the sweep reads the
    boxes in sequence; the sorted positions of the wide boxes are listed in the grid."""

    INFO = PassInfo("B6", "gather", "the boxes in sorted order; the list of wide boxes")
    ENTRY = "gather"

    def encode(self, cpass: wgpu.GPUComputePassEncoder, buffers: BroadBuffers,
               frame: BroadFrame) -> None:
        group = self.stage.group(
            params=buffers.params_binding, elements=buffers.elements, boxes_lo=buffers.boxes_lo,
            boxes_hi=buffers.boxes_hi, sorted_lo=buffers.sorted_lo, sorted_hi=buffers.sorted_hi,
            sorted_body=buffers.sorted_body, counts=buffers.counts, grid=buffers.grid)
        dispatch(cpass, self.stage, group, -(-frame.n // WORKGROUP))


class Sweep(_SweepPass):
    """B7: one thread per sorted box that is not wide, its pairs in the grid.

    In its own and the 8 neighbouring columns (a binary search each), the boxes after it in
    (start, body) order that start before it ends and have its within key are tested on all
    axes and groups; of each overlapping pair, the box that starts first finds the other, so
    every pair is appended once, ``(i, j)`` with ``i < j``. A sweep that meets more than 4096
    boxes stops and is listed in ``unfinished`` (llvmpipe stops an invocation's loops after
    65,535 steps in all); the host finishes it.
    """

    INFO = PassInfo("B7", "sweep", "pairs of each box with the boxes after it in its own and "
                    "the 8 neighbouring columns", when="every frame; again when pairs overflow")
    ENTRY = "sweep"

    def encode(self, cpass: wgpu.GPUComputePassEncoder, buffers: BroadBuffers,
               frame: BroadFrame) -> None:
        group = self.stage.group(
            params=buffers.params_binding, sorted_lo=buffers.sorted_lo,
            sorted_hi=buffers.sorted_hi, sorted_body=buffers.sorted_body, counts=buffers.counts,
            pairs=buffers.pairs, elements=buffers.elements, unfinished=buffers.unfinished)
        dispatch(cpass, self.stage, group, -(-frame.n // WORKGROUP))


class WideSweep(_SweepPass):
    """B8: one thread per sorted box, tested against every wide box of its within key (a pair
    of two wide boxes once, from the later of the two in sorted order)."""

    INFO = PassInfo("B8", "wide sweep", "pairs of every box with the wide boxes",
                    when="every frame; again when pairs overflow")
    ENTRY = "wide_sweep"

    def encode(self, cpass: wgpu.GPUComputePassEncoder, buffers: BroadBuffers,
               frame: BroadFrame) -> None:
        group = self.stage.group(
            params=buffers.params_binding, sorted_lo=buffers.sorted_lo,
            sorted_hi=buffers.sorted_hi, sorted_body=buffers.sorted_body, counts=buffers.counts,
            pairs=buffers.pairs, elements=buffers.elements, grid=buffers.grid)
        dispatch(cpass, self.stage, group, -(-frame.n // WORKGROUP))


__all__ = ["Gather", "Sweep", "WideSweep"]

"""Passes B1-B3 of the broad phase (``shaders/broad_boxes.wgsl``): each body's world box, the
grid across the sweep axis, and each box's sort element."""

from __future__ import annotations

from typing import ClassVar

import wgpu

from ...gpu.bindings import dispatch
from ...gpu.layout import WORKGROUP
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .broad_common import BODY, PARAMS, BroadBuffers, BroadFrame, BroadPass


class _BoxesPass(BroadPass):
    SHADER = "broad_boxes"
    STRUCTS: ClassVar[tuple[Struct, ...]] = (PARAMS, BODY)


class WorldBoxes(_BoxesPass):
    """B1: one thread per body, its world box in float32, grown to be conservative.

    Reads ``bodies`` ((N,) :data:`~pycinder.focused.broad.broad_common.BODY`); writes ``boxes_lo``
    and ``boxes_hi`` ((N, 4) float32, ``w``: the within key's and the group's bits), and gathers in
    the grid the range of the boxes' centres along each axis and a histogram of their widths
    across the sweep axis (atomics, reduced per workgroup first).
    """

    INFO = PassInfo("B1", "world boxes", "each body's conservative world box; the centres' "
                    "range and a histogram of widths")
    ENTRY = "world_boxes"

    def encode(self, cpass: wgpu.GPUComputePassEncoder, buffers: BroadBuffers,
               frame: BroadFrame) -> None:
        group = self.stage.group(params=buffers.params_binding, bodies=buffers.bodies,
                                 boxes_lo=buffers.boxes_lo, boxes_hi=buffers.boxes_hi,
                                 grid=buffers.grid)
        dispatch(cpass, self.stage, group, -(-frame.n // WORKGROUP))


class GridSetup(_BoxesPass):
    """B2: one thread sets the grid up from what B1 gathered.

    The widest boxes (at most :data:`~pycinder.focused.broad.broad_common.WIDE_BODIES`, whole bins
    of the histogram) are "wide" and kept out of the grid; the grid's cells across the sweep axis
    are 1/16 wider than the widest of the others (or the centres' range over 65,000 cells, if
    larger). Writes the grid's set-up: cell sizes, the width from which a box is wide, and how
    many are.
    """

    INFO = PassInfo("B2", "grid setup", "the widest boxes (at most 32) are wide; cells 1/16 "
                    "wider than the widest other box")
    ENTRY = "grid_setup"

    def encode(self, cpass: wgpu.GPUComputePassEncoder, buffers: BroadBuffers,
               frame: BroadFrame) -> None:
        group = self.stage.group(params=buffers.params_binding, grid=buffers.grid)
        dispatch(cpass, self.stage, group, 1)


class Columns(_BoxesPass):
    """B3: one thread per sort element, the box's place in the sort.

    Writes ``elements`` ((count, 4) uint32): the within key, the column (the grid cell holding
    the box's centre, or a column of its own, last, for wide boxes), the order-preserving bits
    of the box's start on the sweep axis, and the body; padding elements (past N) sort last.
    """

    INFO = PassInfo("B3", "columns", "each box's sort element: within key, column, start on "
                    "the sweep axis, body")
    ENTRY = "columns"

    def encode(self, cpass: wgpu.GPUComputePassEncoder, buffers: BroadBuffers,
               frame: BroadFrame) -> None:
        group = self.stage.group(params=buffers.params_binding, boxes_lo=buffers.boxes_lo,
                                 boxes_hi=buffers.boxes_hi, elements=buffers.elements,
                                 grid=buffers.grid)
        dispatch(cpass, self.stage, group, -(-frame.count // WORKGROUP))


__all__ = ["Columns", "GridSetup", "WorldBoxes"]

"""Pass F1, cull: per tile, side and cluster, keep the cluster's faces (when its bounds meet the
tile's window) and its edges (when they meet the tile's box) as work items of passes F2 and F5."""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar

import wgpu

from ...gpu.bindings import Stage, dispatch, workgroup_grid
from ...gpu.device import Gpu
from ...gpu.layout import WORKGROUP
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .arguments import Arguments
from .atlas_buffers import Encoding, Round
from .scope import ComputeScope

RetryDispatch = Callable[[wgpu.GPUComputePassEncoder, Encoding, Round], None]
"""Encodes a retry round's cull dispatch (``frame_retry.wgsl``'s ``retry_args``)."""

PARAMS = Struct("CullParams", [
    ("total", "u32", "threads of this round"),
    ("first_entry", "u32", "first (tile, side) entry of this round"),
    ("n_entries", "u32", "entries in this round"),
    ("face_cap", "u32", "face items the buffer holds"),
    ("edge_cap", "u32", "edge items the buffer holds"),
    ("pair_offset", "u32", "where the per-pair hit flags start in `counts`"),
    ("retry_offset", "u32", "where the per-tile retry flags start in `counts`"),
    ("retry_round", "u32", "a retry round's number from 1 (its tiles' retry flag); 0: a round"),
    ("retry_row", "u32", "a retry round: its first row of the retry rounds' layout"),
    ("list_offset", "u32", "where the list of the retry rounds' tiles starts in `counts`"),
    ("cull_x", "u32", "this round's cull workgroups (x, y, z: its indirect dispatch)"),
    ("cull_y", "u32", ""),
    ("cull_z", "u32", ""),
], uniform=True)


class Cull:
    """F1: one thread per (tile, side, cluster of that side's body) of a round, with a dispatch
    read from the round's parameters, so that the round's commands do not depend on its size
    (see :meth:`pycinder.focused.frame.frames.FocusedFrames._encode_round`); a retry round
    culls only the tiles pass F7 laid out in it, a workgroup per side of each tile listed
    (``cull_retry``), with a dispatch written on the GPU (``frame_retry.wgsl``'s ``retry_args``)."""

    SHADER: ClassVar[str] = "frame_cull"
    """Its shader, ``shaders/frame_cull.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "F1", "cull", "clusters per tile: face and edge work items", when="every round")
    PARAMS: ClassVar[Struct] = PARAMS

    def __init__(self, gpu: Gpu, arguments: Arguments, retry_dispatch: RetryDispatch) -> None:
        self.stage = Stage(gpu, self.SHADER, "cull", label=self.INFO.title, structs=(PARAMS,))
        self.retry_stage = Stage(gpu, self.SHADER, "cull_retry", label=f"{self.INFO.title} (retry)",
                                 structs=(PARAMS,))
        self.arguments = arguments
        self.retry_dispatch = retry_dispatch

    def write_params(self, e: Encoding, r: Round) -> None:
        s = e.state
        p = e.round_params("cull", r.block)
        p["total"] = r.threads
        p["first_entry"] = 2 * r.first_tile
        p["n_entries"] = 2 * (r.end_tile - r.first_tile)
        p["face_cap"] = p["edge_cap"] = s.items
        p["pair_offset"] = s.pair_offset
        p["retry_offset"] = s.retry_offset
        p["retry_round"] = r.retry_round
        p["retry_row"] = (r.retry_round - 1) * s.retry_rows if r.retry else 0
        p["list_offset"] = s.list_offset
        x, y = workgroup_grid(-(-r.threads // WORKGROUP))
        p["cull_x"], p["cull_y"], p["cull_z"] = x, y, 1

    def encode(self, scope: ComputeScope, e: Encoding, r: Round) -> None:
        b = e.buffers
        stage = self.retry_stage if r.retry else self.stage
        group = stage.group(
            f"round {r.block}", tiles=b.tiles, clusters=b.clusters, bounds=b.cluster_bounds,
            entries=b.entries, face_items=b.face_items, edge_items=b.edge_items,
            counters=b.counters, params=e.round_params.binding("cull", r.block),
            counts=b.tile_counts)
        cpass = scope.begin(self.INFO.title)
        if r.retry:
            self.retry_dispatch(cpass, e, r)
            indirect = b.args_at("retry_cull")
        else:
            indirect = e.round_params.indirect("cull", r.block, "cull_x")
        dispatch(cpass, stage, group, indirect=indirect)
        self.arguments.encode(cpass, e, "after_cull")


__all__ = ["Cull"]

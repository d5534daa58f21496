"""Pass F6, crossing test: for tiles with an open body (which has no inside), its surface is
tested instead: two surfaces cross exactly where an edge of one passes through a face of the
other. One workgroup per kept edge cluster; the test is exact and watertight
(``frame_crossing_test.wgsl``)."""

from __future__ import annotations

from typing import ClassVar

from ...gpu.bindings import Stage, dispatch
from ...gpu.device import Gpu
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .atlas_buffers import Encoding, Round
from .f5_edge_test import early_out
from .scope import ComputeScope
from .f4_surface_test import pair_records, record_cap

CROSSING_BUDGET = 49152
"""Loop steps a thread of pass F6 may take before it stops and counts its tile undecided: well
below the 65,535 after which llvmpipe (lavapipe, OpenGL without a GPU) silently ends a thread's
loops (see ``frame_crossing_test.wgsl``)."""

COPLANAR = 2.0**-18
"""Distance from a face's plane, per unit of the tile coordinates' reach, within which both ends
of an edge put it in the plane (``frame_crossing_test.wgsl``: an edge in a face's plane never
crosses it): 16 times the rounding of a point in tile coordinates."""

PARAMS = Struct("CrossingTestParams", [
    ("record_cap", "u32", "0: count hits without writing records"),
    ("item_cap", "u32", "edge items the buffer holds"),
    ("pair_offset", "u32", "where the per-pair hit flags start in tile_counts"),
    ("early_out", "u32", "1: skip tiles whose pair is already found"),
    ("pair_records", "u32", "records kept per pair"),
    ("budget", "u32", "loop steps a thread may take (CROSSING_BUDGET)"),
], uniform=True)


class CrossingTest:
    """F6: edges of each body through the other's faces, for tiles with an open body."""

    SHADER: ClassVar[str] = "frame_crossing_test"
    """Its shader, ``shaders/frame_crossing_test.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "F6", "crossing test", "edges through the other body's faces (tiles with an open body)",
        when="rounds with an open body")
    PARAMS: ClassVar[Struct] = PARAMS

    def __init__(self, gpu: Gpu) -> None:
        self.stage = Stage(gpu, self.SHADER, "crossing_test", label=self.INFO.title,
                           structs=(PARAMS,), consts={"COPLANAR": COPLANAR})

    def write_params(self, e: Encoding) -> None:
        p = e.frame_params("cross")
        p["record_cap"] = record_cap(e)
        p["item_cap"] = e.state.items
        p["pair_offset"] = e.state.pair_offset
        p["early_out"] = early_out(e)
        p["pair_records"] = pair_records(e)
        p["budget"] = CROSSING_BUDGET

    def encode(self, scope: ComputeScope, e: Encoding, r: Round) -> None:
        if not e.state.any_open:
            return
        b = e.buffers
        cpass = scope.begin(self.INFO.title)
        dispatch(cpass, self.stage, self.stage.group(
            f"slot {r.slot}", tiles=b.tiles, clusters=b.clusters, bounds=b.cluster_bounds,
            positions=b.positions, faces=b.faces, edges=b.edges, edge_items=b.edge_items,
            entries=b.entries, tile_counts=b.tile_counts, records=b.records(r.slot),
            counters=b.counters, params=e.frame_params.binding("cross")),
            indirect=b.args_at("edges"))


__all__ = ["COPLANAR", "CROSSING_BUDGET", "CrossingTest"]

"""Pass F5, edge test: every edge of both bodies inside a tile's box, sampled at steps of at most
a pixel, and each sample tested at its own depth against the other body's winding from the
crossings of pass F3 (``frame_edge_test.wgsl``: ``list_edges`` lists the edges reaching into the box
as segments, ``edge_test`` samples and tests one segment per thread). Samples at pixels whose
list overflowed are counted undecided."""

from __future__ import annotations

from typing import ClassVar

from ...gpu.bindings import Stage, dispatch
from ...gpu.device import Gpu
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .arguments import Arguments
from .atlas_buffers import Encoding, Round
from .scope import ComputeScope
from .f4_surface_test import pair_records, record_cap

PARAMS = Struct("EdgeTestParams", [
    ("atlas_width", "u32", "atlas pixels per row"),
    ("capacity", "u32", "list entries per pixel"),
    ("record_cap", "u32", "0: count hits without writing records"),
    ("item_cap", "u32", "edge items the buffer holds"),
    ("pair_offset", "u32", "where the per-pair hit flags start in tile_counts"),
    ("early_out", "u32", "1: skip tiles whose pair is already found (records \"found\", \"none\")"),
    ("pair_records", "u32", "records kept per pair"),
    ("list_cap", "u32", "edges the edge list holds"),
], uniform=True)


def early_out(e: Encoding) -> int:
    """1 where tiles of pairs already found are skipped (not when every tile is wanted)."""
    return 0 if e.state.records.every_tile else 1


class EdgeTest:
    """F5: list the edges reaching into each box, then sample and test them."""

    SHADER: ClassVar[str] = "frame_edge_test"
    """Its shader, ``shaders/frame_edge_test.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "F5", "edge test", "kept edges sampled, each sample tested against the other body",
        when="every round")
    PARAMS: ClassVar[Struct] = PARAMS

    def __init__(self, gpu: Gpu, arguments: Arguments) -> None:
        self.list_edges = Stage(gpu, self.SHADER, "list_edges", label="F5 edge test: list",
                                structs=(PARAMS,))
        self.edge_test = Stage(gpu, self.SHADER, "edge_test", label=self.INFO.title,
                               structs=(PARAMS,))
        self.arguments = arguments

    def write_params(self, e: Encoding) -> None:
        s = e.state
        for name, retry in (("edges", False), ("edges retry", True)):
            p = e.frame_params(name)
            p["atlas_width"] = s.atlas_width
            p["capacity"] = s.capacity_of(retry)
            p["record_cap"] = record_cap(e)
            p["item_cap"] = s.items
            p["pair_offset"] = s.pair_offset
            p["early_out"] = early_out(e)
            p["pair_records"] = pair_records(e)
            p["list_cap"] = e.buffers.caps.edges

    def encode(self, scope: ComputeScope, e: Encoding, r: Round) -> None:
        b = e.buffers
        bind = dict(tiles=b.tiles, positions=b.positions, edges=b.edges,
                    tile_counts=b.tile_counts, counters=b.counters, edge_list=b.edge_list,
                    params=e.frame_params.binding("edges retry" if r.retry else "edges"))
        cpass = scope.begin(self.INFO.title)
        dispatch(cpass, self.list_edges, self.list_edges.group(
            r.kind, clusters=b.clusters, edge_items=b.edge_items, **bind),
            indirect=b.args_at("edges"))
        self.arguments.encode(cpass, e, "after_edge_list")
        dispatch(cpass, self.edge_test, self.edge_test.group(
            f"{r.kind} slot {r.slot}", pixels=b.pixels, crossings=b.lists,
            records=b.records(r.slot), **bind), indirect=b.args_at("edge_test"))


__all__ = ["EdgeTest", "early_out"]

"""Pass F4, surface test: every surface point of both bodies that pass F3 listed in a tile's box
(a face crossing a pixel centre's ray) tested against the other body's winding at the same pixel
(``frame_surface_test.wgsl``). It finds overlaps in the middle of faces, between edges, which edge
samples miss; it runs before the edge test, which then skips pairs it found."""

from __future__ import annotations

from typing import ClassVar

from ...gpu.bindings import Stage, dispatch
from ...gpu.device import Gpu
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .arguments import Arguments
from .atlas_buffers import Encoding, Round
from .scope import ComputeScope

PARAMS = Struct("SurfaceTestParams", [
    ("atlas_width", "u32", "atlas pixels per row"),
    ("rows", "u32", "rows of this round"),
    ("capacity", "u32", "list entries per pixel"),
    ("record_cap", "u32", "0: count hits without writing records"),
    ("pair_offset", "u32", "where the per-pair hit flags start in tile_counts"),
    ("pair_records", "u32", "records kept per pair"),
], uniform=True)


def pair_records(e: Encoding) -> int:
    """Records a pair keeps (all of them: the largest u32)."""
    per_pair = e.state.records.per_pair
    return 0xFFFFFFFF if per_pair is None else per_pair


def record_cap(e: Encoding) -> int:
    """Records the frame's buffer holds (0: records are not read, only counted)."""
    return e.buffers.caps.records if e.state.records.read else 0


class SurfaceTest:
    """F4: one thread per pixel that pass F3 listed a crossing at."""

    SHADER: ClassVar[str] = "frame_surface_test"
    """Its shader, ``shaders/frame_surface_test.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "F4", "surface test", "listed surface points tested against the other body",
        when="every round")
    PARAMS: ClassVar[Struct] = PARAMS

    def __init__(self, gpu: Gpu, arguments: Arguments) -> None:
        self.stage = Stage(gpu, self.SHADER, "surface_test", label=self.INFO.title,
                           structs=(PARAMS,))
        self.arguments = arguments

    def write_params(self, e: Encoding, r: Round) -> None:
        s = e.state
        p = e.round_params("surface", r.block)
        p["atlas_width"] = s.atlas_width
        p["rows"] = r.rows
        p["capacity"] = s.capacity_of(r.retry)
        p["record_cap"] = record_cap(e)
        p["pair_offset"] = s.pair_offset
        p["pair_records"] = pair_records(e)

    def encode(self, scope: ComputeScope, e: Encoding, r: Round) -> None:
        b = e.buffers
        cpass = scope.begin(self.INFO.title)
        self.arguments.encode(cpass, e, "after_crossings")
        dispatch(cpass, self.stage, self.stage.group(
            f"round {r.block} slot {r.slot}", tiles=b.tiles, pixels=b.pixels, crossings=b.lists,
            tile_counts=b.tile_counts, records=b.records(r.slot), counters=b.counters,
            params=e.round_params.binding("surface", r.block), active_pixels=b.active),
            indirect=b.args_at("surface"))


__all__ = ["SurfaceTest", "pair_records", "record_cap"]

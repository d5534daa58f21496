"""Decisions after the rounds (``retry.wgsl``): F7 chooses the tiles of the frame's retry rounds
(run in the same submission, one per round, with longer lists), and F8 counts the tiles the
host must still run again. Tiles of pairs already found are never retried (no record comes
twice); a tile that pass F6 left at its loop budget is not retried here (longer lists cannot
help it): it stays undecided for the host, which cuts its box."""

from __future__ import annotations

from typing import ClassVar

import wgpu

from ...gpu.bindings import Profiler, Stage, dispatch
from ...gpu.device import Gpu
from ...gpu.layout import WORKGROUP
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .atlas import Encoding, Round
from .cull import PARAMS as CULL_PARAMS

PARAMS = Struct("RetryParams", [
    ("tiles", "u32", "tiles of the frame"),
    ("pair_offset", "u32", "where the per-pair hit flags start in `tile_counts`"),
    ("retry_offset", "u32", "where the per-tile retry flags start"),
    ("every_tile", "u32", "1: every tile's records are wanted (records \"all\"), found or not"),
], uniform=True)

_STRUCTS = (CULL_PARAMS, PARAMS)


class _Decision:
    """One thread per tile of the frame, over ``retry.wgsl``."""

    INFO: ClassVar[PassInfo]
    ENTRY: ClassVar[str]

    def __init__(self, gpu: Gpu) -> None:
        self.stage = Stage(gpu, "retry", self.ENTRY, label=self.INFO.title, structs=_STRUCTS)

    def encode(self, encoder: wgpu.GPUCommandEncoder, profiler: Profiler, e: Encoding) -> None:
        b = e.buffers
        cpass = encoder.begin_compute_pass(label=self.INFO.title,
                                           **profiler.writes("decisions"))
        dispatch(cpass, self.stage, self.stage.group(
            tiles=b.tiles, tile_counts=b.tile_counts, counters=b.counters,
            params=e.frame_params.binding("retry")), -(-e.state.tiles // WORKGROUP))
        cpass.end()


class RetryChoice(_Decision):
    """F7: the tiles left undecided whose pair was not found are flagged for the retry rounds
    (their undecided counts cleared: the retry counts its own)."""

    INFO: ClassVar[PassInfo] = PassInfo(
        "F7", "retry choice", "flag undecided tiles of pairs not found; F1-F6 run again for "
        "them with lists four times longer", when="when the frame retries")
    ENTRY: ClassVar[str] = "select_retry"
    PARAMS: ClassVar[Struct] = PARAMS

    def __init__(self, gpu: Gpu) -> None:
        super().__init__(gpu)
        self.args = Stage(gpu, "retry", "retry_args", label="F7 retry dispatch",
                          structs=_STRUCTS)

    def write_params(self, e: Encoding) -> None:
        p, s = e.frame_params("retry"), e.state
        p["tiles"] = s.tiles
        p["pair_offset"] = s.pair_offset
        p["retry_offset"] = s.retry_offset
        p["every_tile"] = int(s.records.every_tile)

    def cull_dispatch(self, cpass: wgpu.GPUComputePassEncoder, e: Encoding, r: Round) -> None:
        """The indirect dispatch of retry round ``r``'s cull (nothing when no tile is retried)."""
        b = e.buffers
        dispatch(cpass, self.args, self.args.group(
            f"round {r.block}", counters=b.counters, args=b.args,
            round=e.round_params.binding("cull", r.block)), 1)


class CountAgain(_Decision):
    """F8: at the end of the frame, count the tiles still undecided whose answer could change;
    none, and the per-pair flags are the whole answer (the host reads nothing per tile)."""

    INFO: ClassVar[PassInfo] = PassInfo(
        "F8", "count undecided", "count the tiles the host must run again", when="every frame")
    ENTRY: ClassVar[str] = "count_again"


__all__ = ["CountAgain", "RetryChoice"]

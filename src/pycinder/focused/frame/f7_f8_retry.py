"""Decisions after the rounds (``frame_retry.wgsl``): F7 chooses the tiles of the frame's retry
rounds (run in the same submission, with longer lists) and lays them out in them, and F8 counts the
tiles the host must still run again. Tiles of pairs already found are never retried (no record comes
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
from ..plan.plan_numpy import HEIGHT_CLASS_CONSTS, HEIGHT_CLASSES
from .atlas_buffers import CLASS_WORDS, GROUP_WORDS, Encoding, Round
from .f1_cull import PARAMS as CULL_PARAMS

PARAMS = Struct("RetryParams", [
    ("tiles", "u32", "tiles of the frame"),
    ("pair_offset", "u32", "where the per-pair hit flags start in `tile_counts`"),
    ("retry_offset", "u32", "where the per-tile retry flags start"),
    ("every_tile", "u32", "1: every tile's records are wanted (records \"all\"), found or not"),
    ("atlas_width", "u32", "atlas pixels per row"),
    ("retry_rows", "u32", "atlas rows of each retry round (0: the frame has none)"),
    ("retry_rounds", "u32", "the frame's retry rounds"),
    ("groups", "u32", "workgroups of the per-tile dispatches"),
    ("group_offset", "u32", "where the layout's per-workgroup words start in `tile_counts`"),
    ("layout_offset", "u32", "where its per-class words start"),
    ("list_offset", "u32", "where the list of the tiles laid out starts"),
], uniform=True)

_CONSTS = {"CLASSES": len(HEIGHT_CLASSES), "GROUP_WORDS": GROUP_WORDS, "CLASS_WORDS": CLASS_WORDS,
           **HEIGHT_CLASS_CONSTS}

_STRUCTS = (CULL_PARAMS, PARAMS)


class _Decision:
    """One thread per tile of the frame, over ``frame_retry.wgsl``."""

    SHADER: ClassVar[str] = "frame_retry"
    """Its shader, ``shaders/frame_retry.wgsl``."""
    INFO: ClassVar[PassInfo]
    ENTRY: ClassVar[str]

    def __init__(self, gpu: Gpu) -> None:
        self.stage = self._stage(gpu, self.ENTRY, self.INFO.title)

    @classmethod
    def _stage(cls, gpu: Gpu, entry: str, label: str) -> Stage:
        return Stage(gpu, cls.SHADER, entry, label=label, structs=_STRUCTS, consts=_CONSTS)

    def _per_tile(self, cpass: wgpu.GPUComputePassEncoder, stage: Stage, e: Encoding) -> None:
        """Dispatch ``stage`` with a thread per tile of the frame."""
        dispatch(cpass, stage, self._group(stage, e), -(-e.state.tiles // WORKGROUP))

    @staticmethod
    def _group(stage: Stage, e: Encoding) -> wgpu.GPUBindGroup:
        b = e.buffers
        return stage.group(tiles=b.tiles, tile_counts=b.tile_counts, counters=b.counters,
                           params=e.frame_params.binding("retry"))

    def encode(self, encoder: wgpu.GPUCommandEncoder, profiler: Profiler, e: Encoding) -> None:
        cpass = encoder.begin_compute_pass(label=self.INFO.title,
                                           **profiler.writes("decisions"))
        self._passes(cpass, e)
        cpass.end()

    def _passes(self, cpass: wgpu.GPUComputePassEncoder, e: Encoding) -> None:
        self._per_tile(cpass, self.stage, e)


class RetryChoice(_Decision):
    """F7: the tiles left undecided whose pair was not found are chosen for the retry rounds and
    laid out in their rows, in tile order (their undecided counts cleared: the retry counts its
    own); those that do not fit stay undecided, for the host."""

    INFO: ClassVar[PassInfo] = PassInfo(
        "F7", "retry choice", "choose the undecided tiles of pairs not found and lay them out in "
        "the retry rounds, where F1-F6 run again for them with lists four times longer",
        when="when the frame retries")
    ENTRY: ClassVar[str] = "select_retry"
    PARAMS: ClassVar[Struct] = PARAMS

    def __init__(self, gpu: Gpu) -> None:
        super().__init__(gpu)
        self.layout = self._stage(gpu, "retry_layout", "F7 retry layout")
        self.place = self._stage(gpu, "place_retry", "F7 retry places")
        self.args = self._stage(gpu, "retry_args", "F7 retry dispatch")

    def _passes(self, cpass: wgpu.GPUComputePassEncoder, e: Encoding) -> None:
        super()._passes(cpass, e)
        dispatch(cpass, self.layout, self.layout.group(
            tile_counts=e.buffers.tile_counts, counters=e.buffers.counters,
            params=e.frame_params.binding("retry")), 1)
        self._per_tile(cpass, self.place, e)

    def write_params(self, e: Encoding) -> None:
        p, s = e.frame_params("retry"), e.state
        p["tiles"] = s.tiles
        p["pair_offset"] = s.pair_offset
        p["retry_offset"] = s.retry_offset
        p["every_tile"] = int(s.records.every_tile)
        p["atlas_width"] = s.atlas_width
        p["retry_rows"] = s.retry_rows
        p["retry_rounds"] = s.retry_rounds
        groups = -(-s.tiles // WORKGROUP)
        p["groups"] = groups
        p["group_offset"] = s.layout_offset
        p["layout_offset"] = s.layout_offset + GROUP_WORDS * groups
        p["list_offset"] = s.list_offset

    def cull_dispatch(self, cpass: wgpu.GPUComputePassEncoder, e: Encoding, r: Round) -> None:
        """The indirect dispatch of retry round ``r``'s cull (nothing when no tile is laid out
        in it)."""
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

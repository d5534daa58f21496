"""What a focused frame is submitted with and what it brings back: the inputs kept to run it
again, the one readback (counters, a hit flag per candidate pair, the first records, the
timestamps; the per-tile counts and the other records in a second map only when needed), and
the tiles as the GPU reads them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import wgpu

from ...gpu.bindings import Profiler
from ...gpu.buffers import Readback
from ...gpu import native
from ...gpu.device import Gpu
from ...gpu.layout import (C_AGAIN, C_RECORDS, C_RETRY_CHOSEN, C_RETRY_ROWS, C_RETRY_TILES,
                           C_UNDECIDED, COUNTERS, RECORD, TILE)
from ...request import RecordMode
from ...scene.pack import ShapePack
from ..plan.plan_numpy import TilePlan
from .atlas_buffers import LIST_CAPACITY, AtlasBuffers, FrameState

SPECULATIVE_RECORDS = 4096
"""Fewest records copied into the frame's one readback; a frame copies a quarter more than the
last frame found (frames of an animation are alike), so that most frames need one round trip."""


@dataclass
class FocusedOutput:
    """What one frame of the focused passes found.

    Attributes
    ----------
    pair_found : (K,) bool
        Per candidate pair: whether a tile of it found a sample inside the other body (or a
        crossing). Decided on the GPU, where the tiles of a pair meet.
    tile_counts : (T, 2) int64 or None
        Per tile: samples found, samples undecided (list overflow;
        :data:`~pycinder.gpu.layout.UNDECIDED_BUDGET_BIT` set where pass F6 ran out of its loop
        budget). Read only when some tile is left undecided and its answer could still change;
        None otherwise.
    records : (R,) structured array of :data:`~pycinder.gpu.layout.RECORD`
        In the order the GPU kept them (:func:`sort_records` orders them when they are
        decoded: most queries never read them).
    counters : (COUNTERS,) int64
    bytes_read : int
    reruns : int
        Times the frame ran again because a buffer had to grow.
    gpu_ms : dict of str to float
        GPU milliseconds per pass (summed over rounds), when profiling.
    dropped_records : int
        Records found but not kept: more than one records buffer of this device holds.
    undecided : int
        Samples undecided (list overflow), in every round and retry round of the frame.
    retried_tiles : int
        Tiles run again in the frame's own retry rounds.
    retry_rows_needed : int
        Atlas rows the retry rounds' layout needed for every tile pass F7 chose (laid out or
        not: what the next frame's retry rounds are sized by).
    capacity : int
        The list capacity the frame's undecided tiles last ran with: the retry rounds' where
        every tile chosen for them fitted, else the frame's.
    """

    pair_found: np.ndarray
    tile_counts: np.ndarray | None
    records: np.ndarray
    counters: np.ndarray
    bytes_read: int
    gpu_ms: dict[str, float]
    reruns: int = 0
    dropped_records: int = 0
    undecided: int = 0
    retried_tiles: int = 0
    retry_rows_needed: int = 0
    capacity: int = LIST_CAPACITY


@dataclass
class FrameInputs:
    """What a frame is submitted with (kept to run it again)."""

    plan: TilePlan
    transforms: np.ndarray
    """(N, 4, 4) world-from-body matrices (what the tiles' matrices are composed of)."""
    body_shape: np.ndarray
    """(N,) each body's shape in ``pack``."""
    pack: ShapePack
    pairs: int
    shapes: list | None
    records: RecordMode
    capacity: int
    retry: int
    """Atlas rows of each of the frame's retry rounds (0: none; see
    :func:`~pycinder.focused.frame.rerun_policy.retry_on_gpu`)."""
    gpu_tiles: wgpu.GPUBuffer | None = None
    """A GPU buffer holding the plan's tiles as the passes read them
    (:data:`~pycinder.gpu.layout.TILE`, written by the GPU planner's pass P3 in an earlier
    submission), copied into the frame's own on the GPU; None: the host composes them
    (:meth:`words`). A frame run again composes them on the host: a later plan may have
    replaced the planner's."""
    retry_rounds: int = 1
    """The frame's retry rounds (with :attr:`retry`)."""

    def words(self) -> np.ndarray:
        """(T,) :data:`~pycinder.gpu.layout.TILE` records of the plan, composed on the host
        (:meth:`~pycinder.focused.plan.plan_numpy.TilePlan.tile_from_body` in float64, then
        :func:`tile_words`)."""
        return tile_words(self.plan, self.plan.tile_from_body(self.transforms))


@dataclass
class ReadLayout:
    """Where the parts of a frame's readback lie."""

    head: int
    stamps: int
    nbytes: int
    timed: list[str]
    waiting: str


@dataclass(eq=False)
class Submitted:
    """A frame submitted to the GPU, and what it found once read (``output``)."""

    inputs: FrameInputs
    slot: int
    state: FrameState | None = None
    layout: ReadLayout | None = None
    pending: object = None
    output: FocusedOutput | None = None
    reruns: int = 0
    gpu_tiles: wgpu.GPUBuffer | None = None
    """The GPU buffer the tiles of this submission are copied from (None: written by the
    host)."""

    @property
    def ready(self) -> bool:
        """Whether the GPU has finished the frame (reading it will not wait)."""
        return self.output is not None or Readback.ready(self.pending)


class FrameReadback:
    """The readback of focused frames: what is copied into it, and how it is decoded.

    Parameters
    ----------
    gpu : Gpu
    buffers : AtlasBuffers
    profiler : Profiler
    timeout : float
        Seconds a readback may wait for the GPU.
    """

    def __init__(self, gpu: Gpu, buffers: AtlasBuffers, profiler: Profiler,
                 timeout: float) -> None:
        self.gpu, self.buffers, self.profiler, self.timeout = gpu, buffers, profiler, timeout
        self.recent_records = 0
        """Records the last frame that read records kept (the next copies a quarter more)."""

    def speculative(self, s: FrameState) -> int:
        """Records copied into frame ``s``'s first readback."""
        if not s.records.read:
            return 0
        return min(max(SPECULATIVE_RECORDS, self.recent_records * 5 // 4),
                   self.buffers.caps.records)

    def copy(self, encoder: wgpu.GPUCommandEncoder, s: FrameState) -> ReadLayout:
        """Copy the counters, the per-pair flags, the first records and the timestamps into the
        frame's staging buffer (and the per-tile counts into the slot's copy)."""
        b = self.buffers
        flags = 4 * s.pairs
        head = -(-(4 * COUNTERS + flags) // 16) * 16
        stamps = -(-(head + RECORD.size * s.speculative) // 8) * 8
        nbytes = stamps + self.profiler.nbytes
        staging = b.readbacks[s.slot].ensure(nbytes)
        encoder.copy_buffer_to_buffer(b.counters, 0, staging, 0, 4 * COUNTERS)
        if s.tiles:
            encoder.copy_buffer_to_buffer(b.tile_counts.buffer, 8 * s.tiles, staging,
                                          4 * COUNTERS, flags)
            copy = b.tile_copies[s.slot]
            copy.ensure(8 * s.tiles)
            encoder.copy_buffer_to_buffer(b.tile_counts.buffer, 0, copy.buffer, 0, 8 * s.tiles)
        if s.speculative:
            encoder.copy_buffer_to_buffer(b.records(s.slot).buffer, 0, staging, head,
                                          RECORD.size * s.speculative)
        self.profiler.resolve(encoder, staging, stamps)
        return ReadLayout(head, stamps, nbytes, list(self.profiler.names),
                          f"a frame of {s.tiles} tiles in {s.rounds} rounds")

    def read(self, sub: Submitted) -> FocusedOutput:
        """Wait for a submitted frame's readback (one map) and decode it. A second map reads the
        per-tile counts when some tile must run again, and the records beyond those the first
        brought."""
        s, lay, b = sub.state, sub.layout, self.buffers
        data = b.readbacks[s.slot].wait(sub.pending, lay.nbytes, timeout=self.timeout,
                                        waiting_for=lay.waiting)
        gpu_ms = self.profiler.times(data[lay.stamps // 4:], lay.timed)
        counters = data[:COUNTERS].astype(np.int64)
        pair_found = data[COUNTERS:COUNTERS + s.pairs] != 0
        n_records = int(min(counters[C_RECORDS], b.caps.records)) if s.records.read else 0
        if s.records.read:
            self.recent_records = n_records
        words = RECORD.size // 4
        recs = data[lay.head // 4: lay.head // 4 + words * n_records]
        tiles = 8 * s.tiles if counters[C_AGAIN] else 0
        more = RECORD.size * n_records if n_records > s.speculative else 0
        tile_counts = None
        if tiles or more:
            second = self._more(s, tiles, more, n_records)
            if tiles:
                tile_counts = second[:2 * s.tiles].reshape(s.tiles, 2).astype(np.int64)
            if more:
                recs = second[tiles // 4:]
        recs = np.ascontiguousarray(recs).view(RECORD.dtype)
        retried = int(counters[C_RETRY_TILES])
        # The tiles' lists were longer only where every tile chosen fitted the retry rounds: the
        # others ran with the frame's lists (the host runs them again with longer ones first).
        longer = retried > 0 and retried == int(counters[C_RETRY_CHOSEN])
        return FocusedOutput(pair_found, tile_counts, recs, counters,
                             lay.nbytes + tiles + more, gpu_ms,
                             undecided=int(counters[C_UNDECIDED]), retried_tiles=retried,
                             retry_rows_needed=int(counters[C_RETRY_ROWS]),
                             capacity=s.capacity_of(longer))

    def _more(self, s: FrameState, tiles: int, more: int, n_records: int) -> np.ndarray:
        """The second map: ``tiles`` bytes of per-tile counts, then ``more`` bytes of records."""
        b = self.buffers
        encoder = native.encoder(self.gpu.device, "focused readback")
        readback = b.readbacks_more[s.slot]
        staging = readback.ensure(tiles + more)
        if tiles:
            encoder.copy_buffer_to_buffer(b.tile_copies[s.slot].buffer, 0, staging, 0, tiles)
        if more:
            encoder.copy_buffer_to_buffer(b.records(s.slot).buffer, 0, staging, tiles, more)
        self.gpu.device.queue.submit([encoder.finish()])
        return readback.read(tiles + more, timeout=self.timeout,
                             waiting_for=f"the counts of {s.tiles} tiles and {n_records} "
                                         "records")


def sort_records(recs: np.ndarray) -> np.ndarray:
    """Records in one order whatever order the GPU's atomics kept them in: by (tile, uv, z_bits,
    ident), as two 64-bit keys.

    Parameters
    ----------
    recs : (R,) structured array of :data:`~pycinder.gpu.layout.RECORD`

    Returns
    -------
    (R,) structured array of :data:`~pycinder.gpu.layout.RECORD`
    """
    if len(recs) < 2:
        return recs
    words = np.ascontiguousarray(recs).view(np.uint32).reshape(len(recs), 4).astype(np.uint64)
    first = (words[:, 0] << np.uint64(32)) | words[:, 1]     # tile, uv
    second = (words[:, 2] << np.uint64(32)) | words[:, 3]    # z_bits, ident
    return recs[np.lexsort((second, first))]


_TILE_WORD = {name: TILE.dtype.fields[name][1] // 4 for name in TILE.dtype.names}
"""The first 32-bit word of each field of :data:`~pycinder.gpu.layout.TILE`."""


def tile_words(plan: TilePlan, matrices: np.ndarray) -> np.ndarray:
    """The tiles as the GPU reads them.

    Parameters
    ----------
    plan : TilePlan
    matrices : (T, 2, 3, 4) float
        Tile-from-body matrices of both sides.

    Returns
    -------
    (T,) structured array of :data:`~pycinder.gpu.layout.TILE`
    """
    n = len(plan)
    # Written as rows of 32-bit words, field by field (the same casts as assigning the
    # structured array's fields: float64 to float32 rounded, integers to uint32 wrapped).
    words = np.empty((n, TILE.dtype.itemsize // 4), dtype=np.uint32)
    floats = words.view(np.float32)
    at = _TILE_WORD
    floats[:, at["m0"]:at["m0"] + 12] = matrices[:, 0].reshape(n, 12)
    floats[:, at["m1"]:at["m1"] + 12] = matrices[:, 1].reshape(n, 12)
    words[:, at["window"]:at["window"] + 4] = plan.window
    floats[:, at["slab"]:at["slab"] + 2] = plan.slab
    words[:, at["slab"] + 2:at["slab"] + 4] = 0
    words[:, at["bodies"]:at["bodies"] + 2] = plan.bodies
    words[:, at["flags"]] = plan.flags
    words[:, at["pair"]] = plan.pair
    return words.view(TILE.dtype).reshape(n)


__all__ = ["FocusedOutput", "FrameInputs", "FrameReadback", "ReadLayout", "SPECULATIVE_RECORDS",
           "Submitted", "sort_records", "tile_words"]

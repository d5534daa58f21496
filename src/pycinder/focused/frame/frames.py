"""The focused strategy's frames: the passes F0-F8 encoded in order over one frame's state,
submitted once, and read back with one map.

    F0 bounds (when vertices changed)
    per round:        F1 cull -> F2 clip -> F3 crossings -> F4 surface test -> F5 edge test
                      -> F6 crossing test (tiles with an open body)
    when retrying:    F7 retry choice and layout, then per retry round F1-F6 for the chosen
                      tiles (from every round) laid out in it, with longer lists
    F8 count undecided

Each pass is an object owning its pipelines, its parameters struct and its bindings by name
(``passes/<pass>.py``); :data:`PASSES` lists them in the order they run, and the pass table of
the docs is generated from it. The readback brings the counters, a hit flag per candidate pair,
the first records and the timestamps; the per-tile counts only when a tile must run again.
What makes a frame run again is decided in :mod:`pycinder.focused.frame.rerun_policy`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import wgpu

from ...gpu.bindings import Profiler
from ...gpu.buffers import DEFAULT_TIMEOUT
from ...gpu import native
from ...gpu.device import Gpu
from ...gpu.layout import C_AGAIN, C_CUTS, C_EDGES, C_RECORDS, FLAG_OPEN, ROUND_COUNTERS, TILE
from ...scene.pack import ShapePack
from .rerun_policy import grown_caps
from .arguments import Arguments
from .atlas_buffers import (LIST_CAPACITY, PIXEL_BYTES, SLOTS, AtlasBuffers, Encoding, FrameState,
                            Round)
from .blocks import ParamBlocks
from .f0_bounds import Bounds
from .f2_clip import Clip
from .f3_crossings import Crossings
from .f6_crossing_test import CrossingTest
from .f1_cull import Cull
from .f5_edge_test import EdgeTest
from .frameio import FocusedOutput, FrameInputs, FrameReadback, Submitted
from .f7_f8_retry import CountAgain, RetryChoice
from .scope import ComputeScope
from .f4_surface_test import SurfaceTest

PASSES = (Bounds, Cull, Clip, Crossings, SurfaceTest, EdgeTest, CrossingTest, RetryChoice,
          CountAgain, Arguments)
"""The pass classes in the order they run (the indirect arguments run between them)."""

ROUND_PASSES = (Cull, Clip, Crossings, SurfaceTest, EdgeTest, CrossingTest)
"""The passes of every round."""

TIMED_PASSES = tuple(p.INFO.title for p in ROUND_PASSES)
"""Names of the passes timed per round when profiling (F0, and "decisions" (passes F7 and F8),
are timed once per frame)."""


def _counter_ranges(reset: set[int], idle: set[int]) -> list[tuple[int, int]]:
    """(offset, size) in bytes of the counters ``reset``, as few ranges as clear them: a range
    may run over counters ``idle`` (zero while the rounds run)."""
    ranges: list[list[int]] = []
    for c in sorted(reset):
        if ranges and all(i in idle for i in range(ranges[-1][1], c)):
            ranges[-1][1] = c + 1
        else:
            ranges.append([c, c + 1])
    return [(4 * lo, 4 * (hi - lo)) for lo, hi in ranges]


RECORDED_ROUNDS = 64
"""Rounds kept to replay (the oldest dropped first): a frame's rounds and retry rounds in each
slot (their keys hold no sizes), with and without pass F6."""

ROUND_CLEARS = _counter_ranges({*range(ROUND_COUNTERS), C_CUTS, C_EDGES}, {C_AGAIN})
"""The counters reset before every round but the frame's first (ROUND_COUNTERS, C_CUTS and
C_EDGES; C_AGAIN, between them, is counted by pass F8 at the end of the frame, after every
round): two clears instead of three."""


@dataclass
class _Slots:
    """The frames in flight, by slot, and the slot of the next frame."""

    next_slot: int = 0
    in_flight: list = field(default_factory=lambda: [None] * SLOTS)


class FocusedFrames:
    """The passes F0-F8 and their buffers, made once per detector.

    Parameters
    ----------
    gpu : Gpu
    list_capacity : int
        Crossings kept per pixel.
    profile : bool
        Time every pass of every round.
    timeout : float
        Seconds the readback may wait for the GPU.
    """

    def __init__(self, gpu: Gpu, list_capacity: int = LIST_CAPACITY, profile: bool = False,
                 timeout: float = DEFAULT_TIMEOUT) -> None:
        self.gpu = gpu
        self.capacity = int(list_capacity)
        self.timeout = float(timeout)
        self.profiler = Profiler(gpu, profile)
        self.buffers = AtlasBuffers(gpu.device)
        self.arguments = Arguments(gpu)
        self.bounds = Bounds(gpu)
        self.retry_choice = RetryChoice(gpu)
        self.count_again = CountAgain(gpu)
        self.rounds = (Cull(gpu, self.arguments, self.retry_choice.cull_dispatch),
                       Clip(gpu, self.arguments), Crossings(gpu),
                       SurfaceTest(gpu, self.arguments), EdgeTest(gpu, self.arguments),
                       CrossingTest(gpu))
        self.cull, self.clip, self.crossings, self.surface_test, self.edge_test, \
            self.crossing_test = self.rounds
        frame_blocks = {"finalize": Arguments.PARAMS, "clip": Clip.PARAMS,
                        "atlas": Crossings.PARAMS, "atlas retry": Crossings.PARAMS,
                        "edges": EdgeTest.PARAMS, "edges retry": EdgeTest.PARAMS,
                        "bounds": Bounds.PARAMS, "cross": CrossingTest.PARAMS,
                        "retry": RetryChoice.PARAMS}
        self.frame_params = ParamBlocks(gpu.device, "frame parameters", frame_blocks)
        self.round_params = ParamBlocks(gpu.device, "round parameters",
                                        {"cull": Cull.PARAMS, "surface": SurfaceTest.PARAMS},
                                        indirect=True)
        self.readback = FrameReadback(gpu, self.buffers, self.profiler, self.timeout)
        self._up = _Slots()
        self._recorded: dict[tuple, native.Recording] = {}
        """Rounds encoded, by what their commands depend on (see :meth:`_encode_round`)."""
        self._recorded_version: tuple | None = None

    @property
    def records_limit(self) -> int:
        """Records one records buffer of this device holds."""
        return self.buffers.limits.records

    # -- shapes -----------------------------------------------------------------------------

    def upload(self, pack: ShapePack, shapes: list) -> int:
        """Upload the shapes (see :meth:`AtlasBuffers.upload`); the vertex bytes written."""
        return self.buffers.upload(pack, shapes)

    # -- one frame --------------------------------------------------------------------------

    def run(self, inputs: FrameInputs) -> FocusedOutput:
        """Run a frame and read back what it found (see :meth:`submit`)."""
        return self.finish(self.submit(inputs))

    def submit(self, inputs: FrameInputs) -> Submitted:
        """Encode the frame's passes in one command buffer, submit it and start its readback;
        :meth:`finish` waits for it. Two frames can be in flight: a third waits for the
        oldest.

        Retry rounds (``inputs.retry``) leave out the tiles of pairs already found: not with a
        records mode that tests every tile. The caller checks that lists that long fit its
        memory budget.
        """
        if inputs.retry and inputs.records.every_tile:
            raise ValueError("retry rounds leave out the tiles of pairs already found: not with "
                             "a records mode that tests every tile")
        up = self._up
        slot = up.next_slot
        up.next_slot = (slot + 1) % SLOTS
        older = up.in_flight[slot]
        if older is not None:
            self.finish(older)  # its staging buffers are about to be reused
        sub = Submitted(inputs, slot)
        up.in_flight[slot] = sub
        self._submit(sub)
        return sub

    def finish(self, sub: Submitted) -> FocusedOutput:
        """Wait for a submitted frame and read what it found; run it again while a buffer had to
        grow (:func:`pycinder.focused.frame.rerun_policy.grown_caps`), so nothing is dropped.

        Raises
        ------
        RoundTooLarge
            A round needs more than this device's largest buffer holds.
        """
        b, up = self.buffers, self._up
        while sub.output is None:
            out = self.readback.read(sub)
            records_read = sub.inputs.records.read
            try:
                grown = grown_caps(out.counters, b.caps, b.limits, records_read,
                                   sub.state.items)
            except Exception:
                up.in_flight[sub.slot] = None
                raise
            if grown is not None:
                b.caps = grown
                sub.reruns += 1
                shapes = sub.inputs.shapes
                if shapes is not None and b.uploaded is not None \
                        and any(x is not y for x, y in zip(shapes, b.uploaded)):
                    self.upload(sub.inputs.pack, shapes)  # a later frame replaced the vertices
                self._submit(sub)
                continue
            out.reruns = sub.reruns
            out.dropped_records = max(int(out.counters[C_RECORDS]) - b.caps.records, 0) \
                if records_read else 0
            sub.output = out
            if up.in_flight[sub.slot] is sub:
                up.in_flight[sub.slot] = None
        return sub.output

    def _state(self, sub: Submitted) -> tuple[FrameState, np.ndarray]:
        """The frame's state, and its (tile, side) entries: the first cull thread of each (a
        prefix over the frame) and the first cluster of its body."""
        inputs = sub.inputs
        plan, pack = inputs.plan, inputs.pack
        start = pack.cluster_start
        shapes = inputs.body_shape.take(plan.bodies).reshape(-1)    # entry e = 2 * tile + side
        count = (start[1:] - start[:-1]).take(shapes)
        prefix = np.empty(len(shapes) + 1, dtype=count.dtype)
        prefix[0] = 0
        np.cumsum(count, out=prefix[1:])
        if prefix[-1] >= 2**32:
            raise ValueError("too many cluster tests in one frame; raise the tolerance or split "
                             "the scene into several queries")
        entries = np.empty((len(shapes) + 1, 2), dtype=np.uint32)
        entries[:, 0] = prefix
        entries[:-1, 1] = start.take(shapes)
        entries[-1, 1] = 0
        round_tiles = np.searchsorted(plan.round, np.arange(len(plan.round_rows) + 1))
        threads_at = prefix[2 * round_tiles]
        round_threads = threads_at[1:] - threads_at[:-1]
        state = FrameState(
            tiles=len(plan), pairs=inputs.pairs, atlas_width=plan.atlas_width,
            round_rows=list(plan.round_rows), round_threads=round_threads,
            round_tiles=round_tiles,
            items=max(int(round_threads.max()) if len(round_threads) else 0,
                      self.buffers.caps.items),
            capacity=int(inputs.capacity or self.capacity), retry_rows=int(inputs.retry),
            retry_rounds=int(inputs.retry_rounds),
            any_open=bool((plan.flags & (FLAG_OPEN[0] | FLAG_OPEN[1])).any()),
            records=inputs.records, slot=sub.slot)
        return state, entries

    def _submit(self, sub: Submitted) -> None:
        state, entries = self._state(sub)
        inputs = sub.inputs
        # The planner's tiles hold for the frame's first submission only (see FrameInputs).
        sub.gpu_tiles = inputs.gpu_tiles if sub.reruns == 0 else None
        self.buffers.ensure_frame(state, entries,
                                  None if sub.gpu_tiles is not None else inputs.words())
        rows = max(state.round_rows) if state.round_rows else 1
        self.crossings.ensure_target(state.atlas_width, rows)
        sub.state = state
        e = Encoding(self.buffers, self.frame_params, self.round_params, state)
        self._write_params(e)
        self._encode_and_submit(sub, e)

    def _write_params(self, e: Encoding) -> None:
        """Every pass's parameters of the frame, by name."""
        s = e.state
        self.frame_params.begin()
        self.round_params.begin(s.rounds + s.retry * s.retry_rounds)
        for r in self._rounds(s):
            self.cull.write_params(e, r)
            self.surface_test.write_params(e, r)
        self.arguments.write_params(e)
        self.clip.write_params(e)
        self.crossings.write_params(e)
        self.edge_test.write_params(e)
        self.crossing_test.write_params(e)
        self.bounds.write_params(e, self.buffers.bound_pending)
        self.retry_choice.write_params(e)
        self.round_params.write()
        self.frame_params.write()

    @staticmethod
    def _rounds(s: FrameState, retry: bool | None = None) -> list[Round]:
        """The frame's rounds (``retry`` None: all; False: the first ones; True: its retry
        rounds, after them)."""
        out = []
        if retry is not True:
            for k in range(s.rounds):
                out.append(Round(k, int(s.round_threads[k]), s.round_rows[k], 0, s.slot,
                                 int(s.round_tiles[k]), int(s.round_tiles[k + 1])))
        if retry is not False and s.retry:
            threads = int(s.round_threads.sum())  # of every tile: each round culls its own
            for j in range(s.retry_rounds):
                out.append(Round(s.rounds + j, threads, s.retry_rows, j + 1, s.slot, 0, s.tiles))
        return out

    def _encode_round(self, encoder: wgpu.GPUCommandEncoder, e: Encoding, r: Round,
                      first: bool = False) -> None:
        """Passes F1-F6 of round ``r``, in order, after its clears (``first``: the frame's
        first round, right after every counter was cleared).

        A round's passes depend only on its buffers and a few flags (its sizes are read from its
        parameters, written anew each frame; its cull is an indirect dispatch): passes like
        those of a round already encoded replay that round's C calls
        (:class:`~pycinder.gpu.native.Recording`), with none of the Python that chose them.
        The clears, whose sizes are the round's, are recorded each time."""
        b = e.buffers
        if not first:
            for offset, size in ROUND_CLEARS:
                encoder.clear_buffer(b.counters, offset, size)
        encoder.clear_buffer(b.pixels.buffer, 0, PIXEL_BYTES * e.state.atlas_width * r.rows)
        key = self._round_key(encoder, e, r)
        if key is None:
            self._encode_passes(encoder, e, r)
            return
        recording = self._recorded.get(key)
        if recording is not None:
            encoder.replay(recording)
            return
        recording = encoder.record()
        try:
            self._encode_passes(encoder, e, r)
        finally:
            encoder.stop()
        if recording.complete:
            if len(self._recorded) >= RECORDED_ROUNDS:
                self._recorded.pop(next(iter(self._recorded)))
            self._recorded[key] = recording

    def _round_key(self, encoder: wgpu.GPUCommandEncoder, e: Encoding, r: Round
                   ) -> tuple | None:
        """What round ``r``'s passes depend on: its block and slot, whether it is a retry
        round, whether pass F6 runs, and which buffers, parameter blocks and render target are
        bound; None where they cannot be replayed (timed passes, or an encoder that is not
        :class:`~pycinder.gpu.native.Encoder`)."""
        if self.profiler.enabled or not isinstance(encoder, native.Encoder):
            return None
        return r.block, r.slot, r.retry, e.state.any_open

    def _forget_stale_rounds(self, e: Encoding) -> None:
        """Drop the recorded rounds when a buffer they bind was made anew (once a frame, after
        its buffers are sized and before its rounds are encoded)."""
        version = (self.buffers.version(), e.frame_params.buffer.generation,
                   e.round_params.buffer.generation, self.crossings.generation)
        if version != self._recorded_version:
            self._recorded.clear()  # they name buffers no longer bound
            self._recorded_version = version

    def _encode_passes(self, encoder: wgpu.GPUCommandEncoder, e: Encoding, r: Round) -> None:
        """:meth:`_encode_round`'s passes, chosen and recorded."""
        scope = ComputeScope(encoder, self.profiler, f"round {r.block}")
        self.cull.encode(scope, e, r)
        self.clip.encode(scope, e)
        scope.end()
        self.crossings.encode(encoder, self.profiler, e, r)
        self.surface_test.encode(scope, e, r)
        self.edge_test.encode(scope, e, r)
        self.crossing_test.encode(scope, e, r)
        scope.end()

    def _encode_and_submit(self, sub: Submitted, e: Encoding) -> None:
        """Encode the frame, submit it and start mapping its readback."""
        s, b = e.state, e.buffers
        self.profiler.begin(3 + len(TIMED_PASSES) * (s.rounds + s.retry * s.retry_rounds))
        encoder = native.encoder(self.gpu.device, "focused frame")
        if sub.gpu_tiles is not None:
            encoder.copy_buffer_to_buffer(sub.gpu_tiles, 0, b.tiles.buffer, 0,
                                          TILE.size * s.tiles)
        self.bounds.encode(encoder, self.profiler, e, b.bound_pending)
        self._forget_stale_rounds(e)
        encoder.clear_buffer(b.counters)
        encoder.clear_buffer(b.tile_counts.buffer, 0, 8 * s.tiles + 4 * s.pairs)
        first = True
        for r in self._rounds(s, retry=False):
            if r.threads:
                self._encode_round(encoder, e, r, first)
                first = False
        if s.retry:
            self.retry_choice.encode(encoder, self.profiler, e)
            for r in self._rounds(s, retry=True):
                if r.threads:
                    self._encode_round(encoder, e, r)
        if s.tiles:
            self.count_again.encode(encoder, self.profiler, e)
        s.speculative = self.readback.speculative(s)
        sub.layout = self.readback.copy(encoder, s)
        self.gpu.device.queue.submit([encoder.finish()])
        b.bound_pending = None
        sub.pending = b.readbacks[s.slot].start(sub.layout.nbytes)


__all__ = ["PASSES", "ROUND_PASSES", "TIMED_PASSES", "FocusedFrames", "FocusedOutput",
           "FrameInputs", "Submitted"]

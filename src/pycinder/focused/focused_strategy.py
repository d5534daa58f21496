"""The focused strategy: broad phase, a tile per candidate pair, the focused passes, the result.

    scene -> world boxes -> sweep and prune (NumPy; on the GPU for large scenes)
          -> tolerance per pair -> tiles and atlas
          -> passes F0-F8 (one submission) -> per-pair hit flags and records -> pairs and records

A pair collides when any of its tiles found a sample inside the other body. A tile whose samples
could not all be decided (a pixel held more crossings within the tile's box than its list) and
whose pair was not found by another tile is run again, with lists four times longer and then
with its box cut in two along the view, until nothing is undecided; whatever is still undecided
after that is counted in ``stats.possibly_lost`` and warned about. Once a query has run tiles
again, the next ones run their first retry, with longer lists, on the GPU in the frame's own
submission: retry rounds whose tiles are laid out anew on the GPU (records "none" and "found",
as many retry rounds as the last query's tiles needed, each within a quarter of the memory
budget); the tiles that do not fit them, and cutting boxes, are planned by the host.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from ..errors import GpuMemoryError, LossWarning, warn_at_caller
from ..gpu.device import Gpu
from ..gpu.layout import (C_SAMPLES, C_TOTAL_TRIS, FLAG_STOP_AT_FIRST, RECORD_ID_MASK,
                          RECORD_KIND_SHIFT, RECORD_SIDE_BIT, RECORD_SURFACE)
from ..records import RECORD_DTYPE, empty_records, pair_keys, unique_pairs
from ..request import CollisionRequest, RecordMode, record_mode
from ..result import CollisionResult, Stats
from ..scene import Scene
from ..scene.bodies import world_edge_normals, world_face_normals
from ..scene.pack import ShapePack, pack_shapes, shape_layout
from ..strategy import Query
from ..tolerance import pair_tolerances
from ..util.text import plural
from .broad import GpuBroadPhase, in_range
from .broad.broad_numpy import PairList, sweep_and_prune
from .frame.rerun_policy import (LARGER_LISTS, RETRIES, RoundTooLarge, retry_on_gpu, retry_rounds,
                          smaller_rounds, undecided_tiles)
from .frame.atlas_buffers import ENTRY_BYTES, LIST_CAPACITY, PIXEL_BYTES, RETRY_LISTS
from .frame.frameio import sort_records
from .frame.frames import FocusedFrames, FocusedOutput, FrameInputs, Submitted

if TYPE_CHECKING:
    from .modes.clearance import Clearance
    from ..contacts import Contacts
    from .plan.plan_gpu import GpuPlanner
    from .modes.hardclash import HardClash
from .plan.plan_numpy import (LEAD_FROM, LEAD_PAIRS, TilePlan, concat_plans, likely_pairs,
                              plan_tiles)


MEASURED_FACE_PAIRS = 2**24
"""Most face pairs (both bodies' face counts multiplied, summed over the pairs) that a query
whose records overflowed measures whole, to give pairs left with no record a contact (pass H1;
beyond it those pairs have none, and the LossWarning says how many)."""


class FocusedStrategy:
    """Runs queries with one tile per candidate pair.

    Parameters
    ----------
    gpu : Gpu
    request : CollisionRequest
    """

    REFUSED: ClassVar[dict[str, str]] = {
        "view": "view applies to strategy='scene'; the focused strategy chooses a view per "
                "candidate pair",
    }
    """What the focused strategy cannot do (:attr:`pycinder.strategy.Strategy.REFUSED`)."""

    def __init__(self, gpu: Gpu, request: CollisionRequest) -> None:
        self.gpu = gpu
        self.request = request
        self.frames = FocusedFrames(gpu, LIST_CAPACITY, profile=request.profile,
                                    timeout=request.timeout)
        per_pixel = PIXEL_BYTES + ENTRY_BYTES * LIST_CAPACITY
        self.budget_pixels = int(min(request.memory_budget // per_pixel,
                                     gpu.max_binding // (ENTRY_BYTES * LIST_CAPACITY),
                                     gpu.max_resolution * 2048))
        self._pack: ShapePack | None = None
        self._broad: GpuBroadPhase | None = None  # made on first use
        self._clearance: Clearance | None = None  # made on first clearance query
        self._hard_clash: HardClash | None = None  # made on first hard-clash query
        self._planner: GpuPlanner | None = None  # made on first query with planner="gpu"
        self.recently_retried = False
        """Whether the last query ran tiles again (their samples were left undecided)."""
        self.retry_rows_needed = 0
        """Rows of the retry rounds' layout the last query's tiles to run again needed (see
        :func:`~pycinder.focused.frame.rerun_policy.retry_rounds`)."""

    def _budget(self, capacity: int) -> int:
        """Atlas pixels per round with lists of ``capacity`` crossings."""
        return self.budget_pixels * self.frames.capacity // capacity

    def pack(self, scene: Scene, stats: Stats) -> ShapePack:
        """The scene's shapes packed and uploaded (packed again when the set of shapes
        changed)."""
        if self._pack is None or self._pack.layout != shape_layout(scene.shapes):
            self._pack = pack_shapes(scene.shapes)
        stats.uploaded_vertex_bytes = self.frames.upload(self._pack, scene.shapes)
        return self._pack

    def submit(self, scene: Scene, stats: Stats, query: Query) -> PendingFocused:
        """Find the colliding pairs of a validated scene, up to the first frame's submission
        (see :meth:`submit_interference`): of bodies in different ``query.groups``, when given;
        of bodies with the same ``query.within`` key (N,), or of its pairs, when given; keeping
        ``query.records`` ("found", "all" or "none"; default: the request's), each pair at its
        first body's ``query.body_tolerances`` where given and not NaN. A clearance query (the
        request's ``clearance``) or a hard-clash query (its ``min_depth``) runs whole here
        (:class:`~pycinder.focused.modes.clearance.Clearance`,
        :class:`~pycinder.focused.modes.hardclash.HardClash`)."""
        c, d = self.request.clearance, self.request.min_depth
        groups, within = query.groups, query.within
        if c is not None:
            if self._clearance is None:
                from .modes.clearance import Clearance

                self._clearance = Clearance(self)
            pending = PendingFocused(self, self._clearance.run(scene, stats, c, groups, within))
        elif d is not None:
            pending = PendingFocused(self,
                                     self._hard_clashes().run(scene, stats, d, groups, within))
        else:
            pending = self.submit_interference(scene, stats, groups, query.records, within,
                                               query.body_tolerances, query.stop_at_first)
        pending.records_kept = query.records or self.request.records
        return pending

    def submit_interference(self, scene: Scene, stats: Stats,
                            groups: np.ndarray | None = None, records: str | None = None,
                            within: np.ndarray | PairList | None = None,
                            body_tolerances: np.ndarray | None = None,
                            stop_at_first: bool = False) -> PendingFocused:
        """The interference test up to the first frame's submission: the broad phase, the
        tiles, the upload and the frame's command buffer. The GPU then works while the caller
        does.

        ``stop_at_first``: the query asks only whether anything collides; every tile is flagged
        :data:`~pycinder.gpu.layout.FLAG_STOP_AT_FIRST`, so that the GPU skips what has not started
        once a pair is found, and the host runs nothing again once one is (records "none":
        the pairs are then those found before the GPU stopped, at least one)."""
        mode = record_mode(records or self.request.records)
        if stop_at_first and mode.read:
            raise ValueError("stop_at_first answers whether anything collides: records 'none' "
                             "only")
        t0 = time.perf_counter()
        if len(scene) < 2:
            return PendingFocused(self, CollisionResult.empty(stats))
        lo, hi = scene.world_boxes()
        pairs, stats.broad_phase = self._candidates(scene, lo, hi, within, groups, stats)
        stats.candidates = len(pairs)
        t1 = time.perf_counter()
        stats.add_ms("broad phase", (t1 - t0) * 1e3)
        if len(pairs) == 0:
            return PendingFocused(self, CollisionResult.empty(stats))
        tol = pair_tolerances(scene, pairs, self.request.tolerance, body_tolerances)
        stats.tolerance = (float(tol.min()), float(tol.max()))
        # A query that stops at its first pair runs the likeliest pairs first, in rounds of
        # their own: in a dense scene the rest is then skipped.
        lead = None
        if stop_at_first and len(pairs) >= LEAD_FROM:
            lead = likely_pairs(lo, hi, pairs, min(LEAD_PAIRS, max(len(pairs) // 4, 1)))
        gpu_tiles = None
        # A query that stops at its first pair plans on the host: its lead pairs, and the flag
        # that stops the GPU, are the host's.
        planned_on_gpu = not stop_at_first and self.request.gpu_planner(len(pairs),
                                                                        self.gpu.cpu_adapter)
        stats.planner = "gpu" if planned_on_gpu else "numpy"
        if planned_on_gpu:
            if self._planner is None:
                from .plan.plan_gpu import GpuPlanner

                self._planner = GpuPlanner(self.gpu, self.request.timeout)
            plan, gpu_tiles = self._planner.plan(
                pairs, tol, scene.local_lo, scene.local_hi, lo, hi, scene.transforms,
                budget_pixels=self.budget_pixels, probe=mode.probe, open_bodies=scene.open,
                max_pixels=self.request.max_pixels, faces=scene.face_counts)
            stats.waited_ms += self._planner.waited_ms
        else:
            plan = plan_tiles(pairs, tol, scene.local_lo, scene.local_hi, lo, hi,
                              scene.transforms, budget_pixels=self.budget_pixels,
                              probe=mode.probe, open_bodies=scene.open,
                              max_pixels=self.request.max_pixels, faces=scene.face_counts,
                              lead=lead)
        stats.separated = plan.separated
        if stop_at_first:
            plan.flags |= FLAG_STOP_AT_FIRST
        t2 = time.perf_counter()
        stats.add_ms("tiles", (t2 - t1) * 1e3)
        if len(plan) == 0:
            return PendingFocused(self, CollisionResult.empty(stats))
        pack = self.pack(scene, stats)
        # Retry rounds (lists RETRY_LISTS times longer) within the memory budget, as many as the
        # last query's tiles to run again needed.
        retry = retry_on_gpu(self.recently_retried, mode, plan,
                             self._budget(self.frames.capacity * RETRY_LISTS))
        inputs = self._inputs(plan, scene, pack, len(pairs), mode, None, retry)
        inputs.gpu_tiles = gpu_tiles
        inputs.retry_rounds = retry_rounds(self.retry_rows_needed, retry)
        first = self.frames.submit(inputs)
        t3 = time.perf_counter()
        stats.add_ms("upload", (t3 - t2) * 1e3)
        stats.submitted_ms = (t3 - t0) * 1e3
        return PendingFocused(self, None, _Query(scene, stats, mode, pairs, plan, pack, first,
                                                 t3, stop_at_first))

    @staticmethod
    def _inputs(plan: TilePlan, scene: Scene, pack: ShapePack, n_pairs: int,
                records: RecordMode, capacity: int | None, retry: int = 0) -> FrameInputs:
        return FrameInputs(plan, scene.transforms, scene.body_shape, pack, n_pairs,
                           scene.shapes, records, capacity or 0, retry)

    def _candidates(self, scene: Scene, lo: np.ndarray, hi: np.ndarray,
                    within: np.ndarray | PairList | None, groups: np.ndarray | None, stats: Stats
                    ) -> tuple[np.ndarray, str]:
        """(K, 2) candidate pairs: bodies whose world boxes (``lo``, ``hi``) overlap, with equal
        ``within`` keys and different ``groups`` when given (or the pairs of a
        :class:`~pycinder.focused.broad.broad_numpy.PairList` given as ``within`` whose boxes
        overlap: on the host whatever the request says, as no sweep runs); found on the GPU or by
        NumPy as the request says (see :attr:`~pycinder.request.CollisionRequest.broad_phase`), and
        which of the two found them. The GPU's pairs are exactly NumPy's: those its padded boxes add
        are dropped against ``lo`` and ``hi``. The GPU's wait is added to
        ``stats.waited_ms``."""
        if isinstance(within, PairList) or not self.request.gpu_broad_phase(len(scene)):
            return sweep_and_prune(lo, hi, within, groups), "numpy"
        body = (scene.local_lo, scene.local_hi, scene.bounding_radii(), scene.transforms)
        if self.request.broad_phase != "gpu" and not in_range(*body):
            return sweep_and_prune(lo, hi, within, groups), "numpy"
        if self._broad is None:
            self._broad = GpuBroadPhase(self.gpu, timeout=self.request.timeout)
        pairs = self._broad.pairs(*body, within=within, groups=groups)
        stats.waited_ms += self._broad.stats.waited_ms
        a, b = pairs[:, 0], pairs[:, 1]
        meet = ((lo[a] <= hi[b]) & (lo[b] <= hi[a])).all(axis=1)
        return pairs[meet], "gpu"

    def _complete(self, q: _Query) -> CollisionResult:
        """The rest of :meth:`submit` once the first frame is submitted: its readback, the runs
        again of undecided tiles (as :mod:`pycinder.focused.frame.rerun_policy` decides), and the
        decoding."""
        scene, stats, records, pairs = q.scene, q.stats, q.records, q.pairs
        found = np.zeros(len(pairs), dtype=bool)
        rows: list[tuple[TilePlan, np.ndarray]] = []
        current, capacity, submitted = q.plan, self.frames.capacity, q.first
        lists_overflowed = False
        for k in range(RETRIES + 1):
            current, out = self._run_plan(current, scene, q.pack, len(pairs), records, capacity,
                                          submitted)
            submitted = None
            self._count(stats, current, out)
            if out.retry_rows_needed:
                # The frame chose tiles to run again itself: its retry rounds' size, next time.
                self.retry_rows_needed = out.retry_rows_needed
            if out.retried_tiles:
                # The frame ran its undecided tiles again itself, with longer lists.
                lists_overflowed = True
                stats.retries += 1
                capacity = out.capacity
            found |= out.pair_found
            rows.append((current, out.records))
            if out.tile_counts is None or (q.stop_at_first and found.any()):
                break  # no tile left undecided whose answer could change
            again, retry = undecided_tiles(current, out.tile_counts, found, records.every_tile,
                                           capacity, self.frames.capacity, self._budget)
            if retry is None:
                break
            if stats.retries == RETRIES:
                self._report_loss(stats, current.bodies[again], pairs[found], capacity)
                break
            stats.retries += 1
            lists_overflowed |= retry.lists_overflowed
            if k == 0 and not q.first.inputs.retry:  # the first frame had no retry rounds
                self.retry_rows_needed = int(sum(retry.plan.round_rows))
            # The retry covers these tiles' whole boxes again: their records from this run
            # would come twice.
            done, kept = rows[-1]
            rows[-1] = (done, kept[~np.isin(kept["tile"], retry.tiles)])
            current, capacity = retry.plan, retry.capacity
        # Retry rounds in the next frames pay only when lists overflowed.
        self.recently_retried = lists_overflowed
        t4 = time.perf_counter()
        stats.add_ms("gpu", (t4 - q.t3) * 1e3)
        return self._result(q, found, rows, t4)

    def _result(self, q: _Query, found: np.ndarray, rows: list[tuple[TilePlan, np.ndarray]],
                t4: float) -> CollisionResult:
        """The result: the pairs found, and the records, decoded when first read."""
        stats, pairs = q.stats, q.pairs
        result_pairs = unique_pairs(pairs[found, 0], pairs[found, 1])
        stats.records = sum(len(r) for _, r in rows)
        decode = partial(decode_records, rows, q.pack.edge_original, q.pack.face_original,
                         q.scene, self.request.encode)
        # Records are decoded when first read (most callers read only the pairs); normals come
        # from the bodies' vertices, which the caller may change once the query returns.
        records = decode() if self.request.encode == "normal" else (stats.records, decode)
        measured, unmeasured = None, 0
        if stats.dropped_records:
            bare = self._pairs_without_records(result_pairs, rows)
            if q.records.every_tile and len(bare):
                faces = q.scene.face_counts
                work = np.cumsum(faces[bare[:, 0]].astype(np.float64) * faces[bare[:, 1]])
                affordable = work <= MEASURED_FACE_PAIRS
                unmeasured = int((~affordable).sum())
                if affordable.any():
                    measured = self._measured_contacts(q.scene, stats, bare[affordable])
            warn_at_caller(
                f"{stats.dropped_records} records were dropped: more than one buffer of this "
                f"device holds ({self.frames.records_limit} records); every pair is "
                f"reported, but contacts come from the records kept"
                + (f", and for {plural(len(measured), 'pair')} left with none, from a depth "
                   "measured per pair (result.measured_contacts)" if measured else "")
                + (f"; {plural(unmeasured, 'other pair')} left with none: no contact "
                   f"(measuring them whole would take more than {MEASURED_FACE_PAIRS:.3g} face "
                   "pairs)" if unmeasured else "")
                + "; see stats.dropped_records", LossWarning)
        stats.add_ms("decode", (time.perf_counter() - t4) * 1e3)
        result = CollisionResult(result_pairs, records, stats,
                                 tiles=concat_plans([p for p, _ in rows]), scene=q.scene)
        result.measured_contacts = measured
        return result

    @staticmethod
    def _pairs_without_records(pairs: np.ndarray, rows: list[tuple[TilePlan, np.ndarray]]
                               ) -> np.ndarray:
        """(P, 2) the ``pairs`` (K, 2) none of whose records was kept."""
        kept = [plan.bodies[r["tile"].astype(np.int64)] for plan, r in rows if len(r)]
        if not kept or not len(pairs):
            return pairs
        bodies = np.concatenate(kept)
        return pairs[~_member(pairs, unique_pairs(bodies[:, 0], bodies[:, 1]))]

    def _measured_contacts(self, scene: Scene, stats: Stats, pairs: np.ndarray) -> Contacts:
        """One contact per pair of ``pairs`` (P, 2) measured whole by pass H1: its directional
        depth, along the direction that clears it, at the middle of its bodies' box overlap."""
        from ..contacts import Contacts

        depth, normal, _ = self._hard_clashes().measure(scene, stats, pairs)
        lo, hi = scene.world_boxes()
        a, b = pairs[:, 0], pairs[:, 1]
        point = 0.5 * (np.maximum(lo[a], lo[b]) + np.minimum(hi[a], hi[b]))
        return Contacts.measured(pairs, point, normal, depth)

    def _hard_clashes(self) -> HardClash:
        """The hard-clash queries' pass on this strategy (made on first use)."""
        if self._hard_clash is None:
            from .modes.hardclash import HardClash

            self._hard_clash = HardClash(self)
        return self._hard_clash

    def _run_plan(self, plan: TilePlan, scene: Scene, pack: ShapePack, n_pairs: int,
                  records: RecordMode, capacity: int, submitted: Submitted | None = None
                  ) -> tuple[TilePlan, FocusedOutput]:
        """Run ``plan``'s passes (or read ``submitted``, the plan's frame already on the GPU);
        when a round is too large for the device's buffers, run the frame again without its
        retry rounds where it had any (their tiles come from every round: they may be what was
        too large), else plan the same tiles in smaller rounds and run them again
        (:func:`pycinder.focused.frame.rerun_policy.smaller_rounds`). Returns the plan run."""
        budget, width = self._budget(capacity), plan.atlas_width
        while True:
            try:
                if submitted is not None:
                    return plan, self.frames.finish(submitted)
                # A frame submitted since may have replaced the shapes on the GPU.
                pack = self.pack(scene, Stats())
                return plan, self.frames.run(self._inputs(plan, scene, pack, n_pairs, records,
                                                          capacity))
            except RoundTooLarge as exc:
                had_retry_rounds = submitted is not None and bool(submitted.inputs.retry)
                submitted = None
                if had_retry_rounds:
                    continue
                smaller = smaller_rounds(plan, exc, budget, width)
                if smaller is None:
                    raise GpuMemoryError(
                        f"one round of tiles has {exc.needed} {exc.what}, more than this "
                        f"device's buffers hold ({exc.limit}), even in rounds of one atlas "
                        "band; use a coarser tolerance or split the scene") from None
                plan, budget, width = smaller

    @staticmethod
    def _report_loss(stats: Stats, bodies: np.ndarray, decided: np.ndarray, capacity: int
                     ) -> None:
        """Warn about the tiles still undecided after the last retry (``bodies`` (T, 2)): pairs
        not found elsewhere may be lost; pairs found elsewhere may lack records."""
        known = _member(bodies, decided)
        thinner = 2 ** (RETRIES - LARGER_LISTS)
        why = (f"more than {capacity} surface crossings per pixel, or (with an open body) more "
               f"face tests than one GPU thread may run, even in boxes cut {thinner} or more "
               "times thinner")
        if (~known).any():
            lost = unique_pairs(bodies[~known, 0], bodies[~known, 1])
            stats.possibly_lost = len(lost)
            warn_at_caller(
                f"{plural(len(lost), 'candidate pair')} could not be decided: their tiles hold "
                f"{why} "
                f"(first pair: bodies {lost[0].tolist()}); see stats.possibly_lost",
                LossWarning)
        if known.any():
            short = unique_pairs(bodies[known, 0], bodies[known, 1])
            stats.incomplete_records = len(short)
            warn_at_caller(
                f"records of {len(short)} colliding pairs may be incomplete: some of their tiles "
                f"hold {why} (first pair: bodies {short[0].tolist()}); the pairs are reported; "
                "see stats.incomplete_records", LossWarning)

    def _count(self, stats: Stats, plan: TilePlan, out: FocusedOutput) -> None:
        stats.tiles += len(plan)
        stats.pixels += plan.pixels
        stats.atlas_pixels += plan.atlas_pixels
        stats.rounds += len(plan.round_rows)
        stats.triangles += int(out.counters[C_TOTAL_TRIS])
        stats.samples += int(out.counters[C_SAMPLES])
        stats.undecided += out.undecided
        stats.bytes_read += out.bytes_read
        stats.reruns += out.reruns
        stats.dropped_records += out.dropped_records
        for name, ms in out.gpu_ms.items():
            stats.gpu_ms[name] = stats.gpu_ms.get(name, 0.0) + ms


def decode_records(rows: list[tuple[TilePlan, np.ndarray]], edge_original: np.ndarray,
                   face_original: np.ndarray, scene: Scene, encode: str) -> np.ndarray:
    """Records from the rows each plan's passes F4-F6 found (:data:`~pycinder.gpu.layout.RECORD`:
    tile, u | v << 16, z bits, id | kind | side): ``id`` is a packed face (F4) or edge (F5, F6),
    numbered in its shape's own order by ``edge_original`` and ``face_original`` (of the
    :class:`~pycinder.scene.pack.ShapePack` the frame ran on).

    Every attempt's records name tiles of its own plan: they are numbered in the plans' order, so
    that ``records["view"]`` indexes the concatenated plan the result carries. ``encode``
    "normal" fills ``normal`` from the bodies' vertices.

    Returns
    -------
    structured array of :data:`~pycinder.RECORD_DTYPE`
    """
    first_tile = np.cumsum([0] + [len(p) for p, _ in rows[:-1]])
    return np.concatenate([
        _decode(scene, plan, edge_original, face_original, r, int(o), encode)
        for (plan, r), o in zip(rows, first_tile)])


def _decode(scene: Scene, plan: TilePlan, edge_original: np.ndarray, face_original: np.ndarray,
            rows: np.ndarray, first_tile: int, encode: str) -> np.ndarray:
    """:func:`decode_records` of one plan's rows (in the order the GPU kept them; decoded in
    :func:`~pycinder.focused.frame.frameio.sort_records`' order); a record's ``view`` is its
    tile's index in ``plan`` plus ``first_tile``."""
    if len(rows) == 0:
        return empty_records()
    rows = sort_records(rows)
    tile = rows["tile"].astype(np.int64)
    u = (rows["uv"] & 0xFFFF).astype(np.int64)
    v = (rows["uv"] >> 16).astype(np.int64)
    z = rows["z_bits"].view(np.float32)
    ident = (rows["ident"] & RECORD_ID_MASK).astype(np.int64)
    surface = (rows["ident"] >> RECORD_KIND_SHIFT) & 3 == RECORD_SURFACE
    side = (rows["ident"] >> RECORD_SIDE_BIT).astype(np.int64)
    rec = np.zeros(len(rows), dtype=RECORD_DTYPE)
    rec["penetrating"] = plan.bodies[tile, side]
    rec["penetrated"] = plan.bodies[tile, 1 - side]
    rec["edge"] = np.where(surface, -1, edge_original[np.where(surface, 0, ident)])
    rec["face"] = np.where(surface, face_original[np.where(surface, ident, 0)], -1)
    rec["view"] = tile + first_tile
    rec["pixel_x"], rec["pixel_y"], rec["pixel_z"] = u, v, z
    rec["point"] = plan.to_world(tile, u + 0.5, v + 0.5, z)
    rec["normal"] = np.nan
    if encode == "normal":
        e = ~surface
        rec["normal"][e] = world_edge_normals(scene, rec["penetrating"][e], rec["edge"][e])
        rec["normal"][surface] = world_face_normals(scene, rec["penetrating"][surface],
                                                    rec["face"][surface])
    return rec


def _member(bodies: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """(T,) whether each tile's pair is among ``pairs`` (K, 2), both sorted i < j."""
    if len(pairs) == 0:
        return np.zeros(len(bodies), dtype=bool)
    return np.isin(pair_keys(bodies[:, 0], bodies[:, 1]), pair_keys(pairs[:, 0], pairs[:, 1]))


@dataclass
class _Query:
    """A focused query whose first frame is on the GPU: what :meth:`FocusedStrategy._complete`
    finishes it with."""

    scene: Scene
    stats: Stats
    records: RecordMode
    pairs: np.ndarray
    plan: TilePlan
    pack: ShapePack
    first: Submitted
    t3: float
    stop_at_first: bool


class PendingFocused:
    """A focused query whose first frame is on the GPU; :meth:`result` finishes it."""

    def __init__(self, strategy: FocusedStrategy, result: CollisionResult | None,
                 query: _Query | None = None) -> None:
        self.strategy, self._result, self._query = strategy, result, query
        self.records_kept: str | None = None
        """The records the query kept, written into an interference result (set by
        :meth:`FocusedStrategy.submit`)."""

    @property
    def ready(self) -> bool:
        """Whether the GPU has finished the first frame (retries, if any, still take time)."""
        return self._result is not None or self._query.first.ready

    def result(self) -> CollisionResult:
        """The query's result, waiting for the GPU if it has not finished."""
        if self._result is None:
            query, self._query = self._query, None
            self._result = self.strategy._complete(query)
        if self.records_kept is not None and self._result.depths is None:
            self._result.records_kept = self.records_kept
        return self._result

"""The focused strategy's GPU passes over a tile atlas, and their buffers.

    F0 bounds     (compute, when vertices changed)  cluster bounds in body space
    F1 cull       (compute)  per tile, side and cluster: keep the cluster's faces and/or edges
    F2 clip       (compute, indirect)  kept faces into their tile's window, clipped watertight
    F3 crossings  (render, indirect)   every clipped face once: per-pixel ray crossings
    F5 surface test (compute, indirect) every listed surface point tested against the other body
    F4 edge test  (compute, indirect)  kept edges sampled and tested, unless F5 found the pair
    F6 crossing test (compute, indirect) tiles with an open body: edges through the other's faces
    retry         (compute)  tiles left undecided, unless their pair was found: F1-F6 again with
                             lists four times longer, in the same submission (when they fit)

Each pass is a :class:`~pycinder.passes.bindings.Stage` (a pipeline, its bindings by name) and
is encoded by :meth:`FocusedPasses._encode_round`. F1 to F6 run once per round of the atlas (one
round unless the memory budget is exceeded), F0 before them when vertices changed, and then,
when asked, a retry round per round for the tiles left undecided, with longer lists: all in one
submission; one readback brings back the counters, a hit flag per candidate pair, the first
records and the timestamps (the per-tile counts only when a tile must be run again by the host).
Pipelines and buffers are created once and grown when a frame needs more; a frame
whose counts outgrow a buffer is run again with the buffer grown, so nothing is dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import wgpu

from ..gpu.buffers import DEFAULT_TIMEOUT, GrowableBuffer, Readback
from ..gpu.device import Gpu
from ..layout import (C_AGAIN, C_CUTS, C_EDGES, C_MAX_EDGES, C_MAX_TRIS, C_RECORDS,
                      C_RETRY_TILES, C_UNDECIDED, COUNTERS, FLAG_OPEN, ROUND_COUNTERS, ROW,
                      TILE, WORKGROUP)
from ..request import RecordMode
from ..scene.pack import ShapePack
from ..tiles import TilePlan
from .bindings import Profiler, Stage
from .states import FOCUSED_CROSSINGS

LIST_CAPACITY = 8
"""Crossings kept per pixel within a tile's box (both bodies together)."""

RETRY_LISTS = 4
"""The retry round's lists are this many times longer than the frame's."""

SPECULATIVE_RECORDS = 4096
"""Fewest records copied into the frame's one readback; a frame copies a quarter more than the
last frame found (frames of an animation are alike), so that most frames need one round trip."""

CROSSING_BUDGET = 49152
"""Loop steps a thread of pass F6 may take before it stops and counts its tile undecided: well
below the 65,535 after which llvmpipe (lavapipe, OpenGL without a GPU) silently ends a thread's
loops (see ``crossingtest.wgsl``)."""

PARAM_STRIDE = 256
"""Bytes between parameter blocks (the uniform offset alignment)."""
ROUND_STRIDE = 2 * PARAM_STRIDE
"""Bytes of one round's parameters: the cull's block, then the surface test's."""
PIXEL_BYTES = 12
"""Per atlas pixel: crossings listed, winding outside the box, tile."""
ENTRY_BYTES = 8
"""Per listed crossing: depth and flags, face."""
EDGE_ENTRY_BYTES = 16
"""Per listed edge segment of pass F4: tile and side, edge, segment, steps."""
P_FINALIZE, P_CLIP, P_ATLAS, P_EDGES, P_BOUNDS, P_CROSS, P_RETRY, P_ATLAS_RETRY, P_EDGES_RETRY = \
    range(9)
"""Blocks of the frame parameter buffer (the last two: P_ATLAS and P_EDGES of the retry round)."""
ARGS_CLIP, ARGS_EDGES, ARGS_DRAW, ARGS_SURFACE, ARGS_RETRY_CULL, ARGS_CUT, ARGS_EDGE_TEST = \
    0, 12, 24, 40, 52, 64, 76
"""Byte offsets of the indirect arguments written by ``finalize.wgsl``."""

_U = wgpu.BufferUsage


def _groups(n: int) -> tuple[int, int]:
    """Workgroup grid (x, y) for ``n`` workgroups laid out in rows of :data:`ROW`."""
    return min(n, ROW), -(-n // ROW)


def tile_words(plan: TilePlan, matrices: np.ndarray) -> np.ndarray:
    """The tiles as the GPU reads them.

    Parameters
    ----------
    plan : TilePlan
    matrices : (T, 2, 3, 4) float
        Tile-from-body matrices of both sides.

    Returns
    -------
    (T,) structured array of :data:`~pycinder.layout.TILE`
    """
    out = TILE.zeros(len(plan))
    out["m0"] = matrices[:, 0]
    out["m1"] = matrices[:, 1]
    out["window"] = plan.window
    out["slab"][:, :2] = plan.slab
    out["bodies"] = plan.bodies
    out["flags"] = plan.flags
    out["pair"] = plan.pair
    return out


@dataclass
class FocusedOutput:
    """What one frame of the focused passes found.

    Attributes
    ----------
    pair_found : (K,) bool
        Per candidate pair: whether a tile of it found a sample inside the other body (or a
        crossing). Decided on the GPU, where the tiles of a pair meet.
    tile_counts : (T, 2) int64 or None
        Per tile: samples found inside the other body (or crossings), samples undecided (list
        overflow; :data:`~pycinder.layout.UNDECIDED_BUDGET_BIT` set where pass F6 ran out of
        its loop budget). Read only when some tile is left undecided and its answer could
        still change (the host then runs it again); None otherwise.
    records : (R, 4) uint32
        tile, u | v << 16, f32 bits of z, id | kind | side (see :mod:`pycinder.layout`); sorted.
    counters : (COUNTERS,) int64
    bytes_read : int
    reruns : int
        Frames run again because a buffer had to grow.
    gpu_ms : dict of str to float
        GPU milliseconds per pass (summed over rounds), when profiling.
    dropped_records : int
        Records found but not kept: more than one records buffer of this device holds.
    undecided : int
        Samples undecided (list overflow), in every round and retry round of the frame.
    retried_tiles : int
        Tiles run again in the frame's own retry rounds (``tile_counts`` then holds the retry's
        counts for them).
    capacity : int
        The list capacity of the frame's last round (the retry's when it ran).
    """

    pair_found: np.ndarray
    tile_counts: np.ndarray | None
    records: np.ndarray
    counters: np.ndarray
    bytes_read: int
    reruns: int
    gpu_ms: dict[str, float]
    dropped_records: int = 0
    undecided: int = 0
    retried_tiles: int = 0
    capacity: int = LIST_CAPACITY


SLOTS = 2
"""Frames that can be in flight at once (each has its own records and staging buffers)."""


@dataclass(eq=False)
class Submitted:
    """A frame submitted to the GPU, and what it found once read (``output``)."""

    args: tuple
    options: dict
    slot: int
    layout: dict | None = None
    pending: object = None
    output: FocusedOutput | None = None
    reruns: int = 0

    @property
    def ready(self) -> bool:
        """Whether the GPU has finished the frame (reading it will not wait)."""
        return self.output is not None or Readback.ready(self.pending)


class RoundTooLarge(Exception):
    """A round clipped more triangles (or listed more edges) than one buffer of this device
    holds: the caller plans the tiles in smaller rounds and runs them again."""

    def __init__(self, needed: int, limit: int, what: str = "clipped triangles") -> None:
        super().__init__(f"{needed} {what} in one round, {limit} fit")
        self.needed, self.limit, self.what = needed, limit, what


class _ComputeScope:
    """Compute dispatches of a round. Consecutive dispatches share one compute pass (each
    dispatch is its own usage scope, so later ones see earlier ones' writes, indirect arguments
    included), saving a pass's fixed cost; when profiling, each pass gets its own timed one."""

    def __init__(self, encoder: wgpu.GPUCommandEncoder, profiler: Profiler, r: int) -> None:
        self.encoder, self.profiler, self.round = encoder, profiler, r
        self.current: wgpu.GPUComputePassEncoder | None = None

    def begin(self, name: str) -> wgpu.GPUComputePassEncoder:
        if self.current is not None and not self.profiler.enabled:
            return self.current
        self.end()
        self.current = self.encoder.begin_compute_pass(label=f"{name}, round {self.round}",
                                                       **self.profiler.writes(name))
        return self.current

    def end(self) -> None:
        if self.current is not None:
            self.current.end()
            self.current = None


def _dispatch(cpass: wgpu.GPUComputePassEncoder, stage: Stage, group: wgpu.GPUBindGroup,
              groups: tuple[int, ...] | None = None, indirect: tuple | None = None) -> None:
    cpass.set_pipeline(stage.pipeline)
    cpass.set_bind_group(0, group)
    if indirect is not None:
        cpass.dispatch_workgroups_indirect(*indirect)
    else:
        cpass.dispatch_workgroups(*groups)


TIMED_PASSES = ("F1 cull", "F2 clip", "F3 crossings", "F5 surface test", "F4 edge test",
                "F6 crossing test")
"""Names of the passes timed per round when profiling (F0, and "decisions" (the choice of the retry
rounds' tiles and the count of tiles left undecided), are timed once per frame)."""


class FocusedPasses:
    """Pipelines and buffers of passes F0-F6, made once per detector.

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
        device = gpu.device
        self.profiler = Profiler(gpu, profile)
        self.profile = self.profiler.enabled

        self.bounds = Stage(gpu, "bounds", "cluster_bounds", label="F0 cluster bounds")
        self.cull = Stage(gpu, "cull", "cull", label="F1 cull")
        self.after_cull = Stage(gpu, "finalize", "after_cull")
        self.clip = Stage(gpu, "clip", "clip", label="F2 clip")
        self.after_clip_faces = Stage(gpu, "finalize", "after_clip_faces")
        self.cut = Stage(gpu, "clip", "cut", label="F2 clip: cuts")
        self.after_clip = Stage(gpu, "finalize", "after_clip")
        state = FOCUSED_CROSSINGS
        self.crossings = Stage(gpu, "crossings", render={
            "primitive": {"topology": "triangle-list", "cull_mode": state.cull},
            "targets": [{"format": "r8unorm", "write_mask": state.write_mask}]},
            label=f"pass {state.number}: {state.purpose}")
        self.after_crossings = Stage(gpu, "finalize", "after_crossings")
        self.surface_test = Stage(gpu, "surfacetest", "surface_test", label="F5 surface test")
        self.list_edges = Stage(gpu, "edgetest", "list_edges", label="F4 edge test: list")
        self.after_edge_list = Stage(gpu, "finalize", "after_edge_list")
        self.edge_test = Stage(gpu, "edgetest", "edge_test", label="F4 edge test")
        self.crossing_test = Stage(gpu, "crossingtest", "crossing_test",
                                   label="F6 crossing test")
        self.select_retry = Stage(gpu, "retry", "select_retry", label="retry: choose tiles")
        self.retry_args = Stage(gpu, "retry", "retry_args")
        self.count_again = Stage(gpu, "retry", "count_again", label="count tiles left undecided")

        storage = _U.STORAGE | _U.COPY_DST

        def grow(label: str, usage: int = storage) -> GrowableBuffer:
            return GrowableBuffer(device, label, usage)

        # The shapes (rewritten when the set of shapes changes).
        self.positions = grow("positions")
        self.faces = grow("faces")
        self.edges = grow("edges")
        self.clusters = grow("clusters")
        self.cluster_bounds = grow("cluster bounds", _U.STORAGE)
        self.which = grow("clusters to bound")
        # One frame's tiles and what the passes hand each other.
        self.tiles = grow("tiles")
        self.entries = grow("tile entries")
        self.face_items = grow("face items", _U.STORAGE)
        self.edge_items = grow("edge items", _U.STORAGE)
        self.tris = grow("clipped triangles", _U.STORAGE)
        self.tri_face = grow("triangle faces", _U.STORAGE)
        self.cuts = grow("faces to cut", _U.STORAGE)
        self.edge_list = grow("edges to sample", _U.STORAGE)
        self.active = grow("active pixels", _U.STORAGE)
        self.pixels = grow("pixel counts", _U.STORAGE | _U.COPY_DST)
        self.lists = grow("pixel crossings", _U.STORAGE)
        self.tile_counts = grow("tile counts", _U.STORAGE | _U.COPY_SRC | _U.COPY_DST)
        # Per frame in flight: its per-tile counts, copied on the GPU, mapped only when needed.
        self.tile_copies = [grow(f"tile counts {k}", _U.COPY_SRC | _U.COPY_DST)
                            for k in range(SLOTS)]
        # Per frame in flight: the records and the staging buffers they are read through.
        self.records_slots = [grow(f"records {k}", _U.STORAGE | _U.COPY_SRC)
                              for k in range(SLOTS)]
        self.counters = device.create_buffer(label="counters", size=4 * COUNTERS,
                                             usage=_U.STORAGE | _U.COPY_SRC | _U.COPY_DST)
        self.args = device.create_buffer(label="indirect args", size=96,
                                         usage=_U.STORAGE | _U.INDIRECT)
        self.round_params = grow("round parameters", _U.UNIFORM | _U.COPY_DST)
        self.frame_params = device.create_buffer(label="frame parameters", size=9 * PARAM_STRIDE,
                                                 usage=_U.UNIFORM | _U.COPY_DST)
        self.readbacks = [Readback(device, f"focused readback {k}") for k in range(SLOTS)]
        self.readbacks_more = [Readback(device, f"focused tiles and records {k}")
                               for k in range(SLOTS)]
        self.in_flight: list[Submitted | None] = [None] * SLOTS
        self._next_slot = 0
        self.target: wgpu.GPUTexture | None = None
        self.target_view: wgpu.GPUTextureView | None = None
        self.caps = {"tris": 1 << 16, "records": 1 << 16, "edges": 1 << 16}
        self.recent_records = 0
        self.layout: tuple | None = None
        self.uploaded: list | None = None
        self._bound_pending: np.ndarray | None = None

    # -- shapes -----------------------------------------------------------------------------

    def upload(self, pack: ShapePack, shapes: list) -> int:
        """Upload the shapes; returns the vertex bytes written.

        Index buffers are written when the layout (topologies, vertex counts) changed; vertices
        only for shapes that are new objects (a shape object is made for new vertex content).
        Cluster bounds of those shapes are recomputed by pass F0 at the start of the next frame.
        """
        changed: list[int]
        if pack.layout != self.layout:
            for buf, data in ((self.positions, pack.positions), (self.faces, pack.faces),
                              (self.edges, pack.edges), (self.clusters, pack.clusters)):
                buf.ensure(data.nbytes)
                buf.write(data)
            self.cluster_bounds.ensure(32 * len(pack.clusters))
            self.layout = pack.layout
            changed = list(range(len(shapes)))
            written = pack.positions.nbytes
        else:
            changed = [k for k, s in enumerate(shapes) if s is not self.uploaded[k]]
            written = 0
            for k in changed:
                # The pack's positions are those of the frame that made it: write the shape's own.
                vertices = shapes[k].vertices
                self.positions.write(vertices, offset=12 * int(pack.vertex_start[k]))
                written += vertices.nbytes
        self.uploaded = list(shapes)
        if changed:
            which = np.concatenate([np.arange(pack.cluster_start[k], pack.cluster_start[k + 1])
                                    for k in changed]).astype(np.uint32)
            if self._bound_pending is not None:
                which = np.union1d(which, self._bound_pending).astype(np.uint32)
            self._bound_pending = which
        return written

    def _encode_bounds(self, encoder: wgpu.GPUCommandEncoder) -> None:
        """Pass F0 for the clusters of shapes whose vertices changed."""
        which = self._bound_pending
        if which is None or len(which) == 0:
            return
        self.which.ensure(which.nbytes)
        self.which.write(which)
        group = self.bounds.group(
            positions=self.positions, faces=self.faces, clusters=self.clusters, which=self.which,
            bounds=self.cluster_bounds, params=(self.frame_params, P_BOUNDS * PARAM_STRIDE, 16))
        cpass = encoder.begin_compute_pass(label="F0 cluster bounds",
                                           **self.profiler.writes("F0 cluster bounds"))
        _dispatch(cpass, self.bounds, group, _groups(-(-len(which) // WORKGROUP)))
        cpass.end()

    # -- one frame --------------------------------------------------------------------------

    def run(self, plan: TilePlan, matrices: np.ndarray, body_shape: np.ndarray,
            pack: ShapePack, n_pairs: int, *, shapes: list | None = None,
            records: RecordMode, list_capacity: int | None = None,
            retry: bool = False) -> FocusedOutput:
        """Run passes F0-F6 for every tile and read back what they found (see :meth:`submit`)."""
        return self.finish(self.submit(plan, matrices, body_shape, pack, n_pairs, shapes=shapes,
                                       records=records, list_capacity=list_capacity,
                                       retry=retry))

    def submit(self, plan: TilePlan, matrices: np.ndarray, body_shape: np.ndarray,
               pack: ShapePack, n_pairs: int, *, shapes: list | None = None,
               records: RecordMode, list_capacity: int | None = None,
               retry: bool = False) -> Submitted:
        """Encode passes F0-F6 for every tile in one command buffer, submit it and start its
        readback; :meth:`finish` waits for it. Two frames can be in flight: a third waits for
        the oldest.

        Parameters
        ----------
        plan : TilePlan
        matrices : (T, 2, 3, 4) float
            Tile-from-body matrices.
        body_shape : (N,) int
            Each body's shape in ``pack``.
        pack : ShapePack
            The uploaded shapes.
        n_pairs : int
            Candidate pairs (``plan.pair`` indexes them).
        shapes : list of Shape, optional
            The shapes uploaded for this frame: uploaded again should the frame have to run
            again after a later frame replaced them.
        records : RecordMode
            Whether records are read back (otherwise only the per-pair flags), whether every
            tile is tested (otherwise tiles of pairs already found are skipped) and how many
            records a pair keeps.
        list_capacity : int, optional
            Crossings kept per pixel in this run (default: the one given at construction).
        retry : bool
            End the frame with retry rounds (one per round): the tiles left undecided whose pair
            was not found run again with lists :data:`RETRY_LISTS` times longer, in the same
            submission. Not when ``records`` tests every tile (a found pair's tiles are not
            retried, so their records would be missing). The caller checks that lists that long
            fit its memory budget.
        """
        if retry and records.every_tile:
            raise ValueError("retry rounds leave out the tiles of pairs already found: not with "
                             "a records mode that tests every tile")
        slot = self._next_slot
        self._next_slot = (slot + 1) % SLOTS
        older = self.in_flight[slot]
        if older is not None:
            self.finish(older)  # its staging buffers are about to be reused
        sub = Submitted((plan, matrices, body_shape, pack, n_pairs),
                        dict(shapes=shapes, records=records, list_capacity=list_capacity,
                             retry=retry), slot)
        self.in_flight[slot] = sub
        self._submit(sub)
        return sub

    def finish(self, sub: Submitted) -> FocusedOutput:
        """Wait for a submitted frame and read what it found; run it again while a buffer had to
        grow, so nothing is dropped."""
        while sub.output is None:
            out = self._read(sub)
            c = out.counters
            grown = False
            max_records = self.records.limit // 16
            for cap, counter, limit, what in (
                    ("tris", C_MAX_TRIS, self.tris.limit // 48, "clipped triangles"),
                    ("edges", C_MAX_EDGES, self.edge_list.limit // EDGE_ENTRY_BYTES,
                     "edges to sample")):
                if c[counter] > self.caps[cap]:
                    self.in_flight[sub.slot] = None
                    if c[counter] > limit:
                        raise RoundTooLarge(int(c[counter]), limit, what)
                    self.caps[cap] = min(int(c[counter] * 1.5) + 1024, limit)
                    grown = True
            if c[C_RECORDS] > self.caps["records"] and sub.options["records"].read \
                    and self.caps["records"] < max_records:
                # More records than one buffer holds are dropped (and counted): pairs come
                # from the per-pair flags, which are complete.
                self.caps["records"] = min(int(c[C_RECORDS] * 1.5) + 1024, max_records)
                grown = True
            if grown:
                sub.reruns += 1
                shapes = sub.options["shapes"]
                if shapes is not None and self.uploaded is not None \
                        and any(a is not b for a, b in zip(shapes, self.uploaded)):
                    self.upload(sub.args[3], shapes)  # a later frame replaced the vertices
                self._submit(sub)
                continue
            out.reruns = sub.reruns
            out.dropped_records = max(int(c[C_RECORDS]) - self.caps["records"], 0) \
                if sub.options["records"].read else 0
            sub.output = out
            if self.in_flight[sub.slot] is sub:
                self.in_flight[sub.slot] = None
        return sub.output

    def _records(self, slot: int) -> GrowableBuffer:
        return self.records_slots[slot]

    @property
    def records(self) -> GrowableBuffer:
        """The records buffer of the first slot (its limit is every slot's)."""
        return self.records_slots[0]

    def _submit(self, sub: Submitted) -> None:
        plan, matrices, body_shape, pack, n_pairs = sub.args
        opts = sub.options
        self.run_capacity = int(opts["list_capacity"] or self.capacity)
        self.record_mode = opts["records"]
        t = len(plan)
        words = tile_words(plan, matrices)
        shapes = body_shape[plan.bodies].reshape(-1)                    # entry e = 2 * tile + side
        count = np.diff(pack.cluster_start)[shapes]
        prefix = np.concatenate([[0], np.cumsum(count)])
        if prefix[-1] >= 2**32:
            raise ValueError("too many cluster tests in one frame; raise the tolerance or split "
                             "the scene into several queries")
        entries = np.zeros((len(shapes) + 1, 2), dtype=np.uint32)
        entries[:, 0] = prefix
        entries[:-1, 1] = pack.cluster_start[shapes]
        bounds = np.searchsorted(plan.round, np.arange(len(plan.round_rows) + 1))
        round_threads = np.diff(prefix[2 * bounds])
        self.tiles.ensure(words.nbytes)
        self.tiles.write(words)
        self.entries.ensure(entries.nbytes)
        self.entries.write(entries)
        items = int(round_threads.max()) if len(round_threads) else 0
        self.face_items.ensure(8 * max(items, 1))
        self.edge_items.ensure(8 * max(items, 1))
        self.retry = bool(opts["retry"])
        # Per tile (found, undecided), per pair a hit flag, per tile a retry flag.
        self.tile_counts.ensure(8 * t + 4 * n_pairs + 4 * t + 4)
        self.n_pairs = n_pairs
        self.any_open = bool((plan.flags & (FLAG_OPEN[0] | FLAG_OPEN[1])).any())
        width = plan.atlas_width
        rows = max(plan.round_rows) if plan.round_rows else 1
        self._ensure_target(width, rows)
        self.pixels.ensure(PIXEL_BYTES * width * rows)
        longest = self.run_capacity * (RETRY_LISTS if self.retry else 1)
        self.lists.ensure(ENTRY_BYTES * longest * width * rows)
        self.active.ensure(4 * width * rows)
        self.caps["tris"] = min(self.caps["tris"], self.tris.limit // 48)
        self.caps["records"] = min(self.caps["records"], self.records.limit // 16)
        self.tris.ensure(48 * self.caps["tris"])
        self.tri_face.ensure(4 * self.caps["tris"])
        self.cuts.ensure(8 * self.caps["tris"])
        self.caps["edges"] = min(self.caps["edges"], self.edge_list.limit // EDGE_ENTRY_BYTES)
        self.edge_list.ensure(EDGE_ENTRY_BYTES * self.caps["edges"])
        self._records(sub.slot).ensure(16 * self.caps["records"])
        self._frame(sub, plan, bounds, round_threads, items, opts["records"].read)

    def _ensure_target(self, width: int, rows: int) -> None:
        if self.target is not None and self.target.width >= width and self.target.height >= rows:
            return
        height = max(rows, self.target.height if self.target is not None else 0)
        limit = self.gpu.max_resolution
        if width > limit or height > limit:
            raise ValueError(f"an atlas of {width} x {height} pixels is over this device's "
                             f"texture limit of {limit}; lower memory_budget")
        self.target = self.gpu.device.create_texture(
            label="atlas", size=(width, height, 1), format="r8unorm",
            usage=wgpu.TextureUsage.RENDER_ATTACHMENT)
        self.target_view = self.target.create_view()

    def _write_params(self, plan: TilePlan, bounds: np.ndarray, round_threads: np.ndarray,
                      items: int, want_records: bool) -> None:
        n_rounds = len(plan.round_rows)
        caps = self.caps
        record_cap = caps["records"] if want_records else 0
        per_pair = self.record_mode.per_pair
        pair_records = 0xFFFFFFFF if per_pair is None else per_pair
        t = len(plan)
        pairs_at, retry_at = 2 * t, 2 * t + self.n_pairs
        # Per-round parameters of the cull and the surface test, one uniform block each; the
        # retry rounds' (one per round) come after the last round's.
        blocks = n_rounds * (1 + self.retry)
        self.round_params.ensure(ROUND_STRIDE * max(blocks, 1))
        block = np.zeros((max(blocks, 1), ROUND_STRIDE // 4), dtype=np.uint32)
        surface = PARAM_STRIDE // 4
        for r in range(blocks):
            retry = r >= n_rounds
            b = r % n_rounds
            block[r, :7] = (round_threads[b], 2 * bounds[b], 2 * (bounds[b + 1] - bounds[b]),
                            items, items, pairs_at, retry_at if retry else 0)
            block[r, surface:surface + 6] = (plan.atlas_width, plan.round_rows[b],
                                             self.round_capacity(retry), record_cap, pairs_at,
                                             pair_records)
        self.round_params.write(block)
        frame = np.zeros((9, PARAM_STRIDE // 4), dtype=np.uint32)
        early_out = 0 if self.record_mode.every_tile else 1
        frame[P_FINALIZE, :4] = (items, items, caps["tris"], caps["edges"])
        frame[P_CLIP, :4] = (caps["tris"], items, 0, 0)
        frame[P_CROSS, :6] = (record_cap, items, pairs_at, early_out, pair_records,
                              CROSSING_BUDGET)
        frame[P_BOUNDS, 0] = 0 if self._bound_pending is None else len(self._bound_pending)
        frame[P_RETRY, :4] = (t, pairs_at, retry_at, int(self.record_mode.every_tile))
        for at, edges, retry in ((P_ATLAS, P_EDGES, False), (P_ATLAS_RETRY, P_EDGES_RETRY, True)):
            capacity = self.round_capacity(retry)
            frame[at, :4] = (plan.atlas_width, self.target.height, capacity, self.target.width)
            frame[edges, :8] = (plan.atlas_width, capacity, record_cap, items, pairs_at,
                                early_out, pair_records, caps["edges"])
        self.gpu.device.queue.write_buffer(self.frame_params, 0, frame)

    def round_capacity(self, retry: bool = False) -> int:
        """List entries per pixel of this frame's rounds (of its retry round)."""
        return self.run_capacity * (RETRY_LISTS if retry else 1)

    def _encode_round(self, encoder: wgpu.GPUCommandEncoder, r: int, threads: int,
                      rows: int, slot: int, retry: bool = False) -> None:
        """Passes F1-F6 of round ``r`` (``threads`` cull threads, ``rows`` atlas rows), writing
        records to the buffer of frame slot ``slot``. A retry round (``retry``, numbered after
        the last round; the tiles it may run were chosen by :meth:`_encode_retry_choice`) culls
        only the chosen tiles of its round, with longer lists."""
        records = self._records(slot)
        b = self
        finalize = dict(counters=b.counters, args=b.args,
                        params=(b.frame_params, P_FINALIZE * PARAM_STRIDE, 16))
        round_block = (b.round_params.buffer, r * ROUND_STRIDE, 32)
        surface_block = (b.round_params.buffer, r * ROUND_STRIDE + PARAM_STRIDE, 32)
        atlas_block = (b.frame_params, (P_ATLAS_RETRY if retry else P_ATLAS) * PARAM_STRIDE, 16)
        edges_block = (b.frame_params, (P_EDGES_RETRY if retry else P_EDGES) * PARAM_STRIDE, 32)
        kind = "retry" if retry else "rounds"
        encoder.clear_buffer(self.counters, 0, 4 * ROUND_COUNTERS)
        encoder.clear_buffer(self.counters, 4 * C_CUTS, 4)
        encoder.clear_buffer(self.counters, 4 * C_EDGES, 4)
        encoder.clear_buffer(self.pixels.buffer, 0, PIXEL_BYTES * self.target_width * rows)
        scope = _ComputeScope(encoder, self.profiler, r)
        cull_group = self.cull.group(
            f"round {r}", tiles=b.tiles, clusters=b.clusters, bounds=b.cluster_bounds,
            entries=b.entries, face_items=b.face_items, edge_items=b.edge_items,
            counters=b.counters, params=round_block, counts=b.tile_counts)
        if retry:
            cpass = scope.begin("F1 cull")
            _dispatch(cpass, self.retry_args, self.retry_args.group(
                f"round {r}", counters=b.counters, args=b.args,
                round=(b.round_params.buffer, r * ROUND_STRIDE, 16)), (1,))
            _dispatch(cpass, self.cull, cull_group, indirect=(self.args, ARGS_RETRY_CULL))
        else:
            cpass = scope.begin("F1 cull")
            _dispatch(cpass, self.cull, cull_group, _groups(-(-threads // WORKGROUP)))
        _dispatch(cpass, self.after_cull, self.after_cull.group(**finalize), (1,))
        cpass = scope.begin("F2 clip")
        clip = dict(tiles=b.tiles, clusters=b.clusters, positions=b.positions, faces=b.faces,
                    face_items=b.face_items, tris=b.tris, counters=b.counters,
                    params=(b.frame_params, P_CLIP * PARAM_STRIDE, 16), tri_face=b.tri_face,
                    cuts=b.cuts)
        _dispatch(cpass, self.clip, self.clip.group(**clip), indirect=(self.args, ARGS_CLIP))
        _dispatch(cpass, self.after_clip_faces, self.after_clip_faces.group(**finalize), (1,))
        _dispatch(cpass, self.cut, self.cut.group(**clip), indirect=(self.args, ARGS_CUT))
        _dispatch(cpass, self.after_clip, self.after_clip.group(**finalize), (1,))
        scope.end()
        rpass = encoder.begin_render_pass(
            label=f"F3 crossings, round {r}",
            color_attachments=[{"view": self.target_view, "load_op": "load",
                                "store_op": "discard"}], **self.profiler.writes("F3 crossings"))
        rpass.set_pipeline(self.crossings.pipeline)
        rpass.set_bind_group(0, self.crossings.group(
            kind, tris=b.tris, tiles=b.tiles, pixels=b.pixels, crossings=b.lists,
            atlas=atlas_block, tri_face=b.tri_face,
            active_pixels=b.active, counters=b.counters))
        rpass.draw_indirect(self.args, ARGS_DRAW)
        rpass.end()
        cpass = scope.begin("F5 surface test")
        _dispatch(cpass, self.after_crossings, self.after_crossings.group(**finalize), (1,))
        _dispatch(cpass, self.surface_test, self.surface_test.group(
            f"round {r} slot {slot}", tiles=b.tiles, pixels=b.pixels, crossings=b.lists,
            tile_counts=b.tile_counts, records=records, counters=b.counters,
            params=surface_block, active_pixels=b.active), indirect=(self.args, ARGS_SURFACE))
        cpass = scope.begin("F4 edge test")
        edges = dict(tiles=b.tiles, positions=b.positions, edges=b.edges,
                     tile_counts=b.tile_counts, counters=b.counters, params=edges_block,
                     edge_list=b.edge_list)
        _dispatch(cpass, self.list_edges, self.list_edges.group(
            kind, clusters=b.clusters, edge_items=b.edge_items, **edges),
            indirect=(self.args, ARGS_EDGES))
        _dispatch(cpass, self.after_edge_list, self.after_edge_list.group(**finalize), (1,))
        _dispatch(cpass, self.edge_test, self.edge_test.group(
            f"{kind} slot {slot}", pixels=b.pixels, crossings=b.lists, records=records, **edges),
            indirect=(self.args, ARGS_EDGE_TEST))
        if self.any_open:
            cpass = scope.begin("F6 crossing test")
            _dispatch(cpass, self.crossing_test, self.crossing_test.group(
                f"slot {slot}", tiles=b.tiles, clusters=b.clusters, bounds=b.cluster_bounds,
                positions=b.positions, faces=b.faces, edges=b.edges, edge_items=b.edge_items,
                entries=b.entries, tile_counts=b.tile_counts, records=records,
                counters=b.counters, params=(b.frame_params, P_CROSS * PARAM_STRIDE, 32)),
                indirect=(self.args, ARGS_EDGES))
        scope.end()

    def _encode_decision(self, encoder: wgpu.GPUCommandEncoder, stage: Stage) -> None:
        """One thread per tile of ``stage`` (retry.wgsl): choosing the tiles of the retry
        rounds, or counting the tiles the host must run again."""
        b = self
        cpass = encoder.begin_compute_pass(label=stage.label,
                                           **self.profiler.writes("decisions"))
        _dispatch(cpass, stage, stage.group(
            tiles=b.tiles, tile_counts=b.tile_counts, counters=b.counters,
            params=(b.frame_params, P_RETRY * PARAM_STRIDE, 16)),
            _groups(-(-self.n_tiles // WORKGROUP)))
        cpass.end()

    def _frame(self, sub: Submitted, plan: TilePlan, bounds: np.ndarray,
               round_threads: np.ndarray, items: int, want_records: bool) -> None:
        """Encode the frame, submit it and start mapping its readback."""
        device = self.gpu.device
        n_rounds = len(plan.round_rows)
        t = len(plan)
        self.target_width = plan.atlas_width
        self.n_tiles = t
        self._write_params(plan, bounds, round_threads, items, want_records)
        self.profiler.begin(3 + len(TIMED_PASSES) * n_rounds * (1 + self.retry))
        encoder = device.create_command_encoder()
        self._encode_bounds(encoder)
        encoder.clear_buffer(self.counters)
        encoder.clear_buffer(self.tile_counts.buffer, 0, 8 * t + 4 * self.n_pairs)
        for r in range(n_rounds):
            if round_threads[r]:
                self._encode_round(encoder, r, int(round_threads[r]), plan.round_rows[r],
                                   sub.slot)
        if self.retry:
            self._encode_decision(encoder, self.select_retry)
            for r in range(n_rounds):
                if round_threads[r]:
                    self._encode_round(encoder, n_rounds + r, int(round_threads[r]),
                                       plan.round_rows[r], sub.slot, retry=True)
        if t:
            self._encode_decision(encoder, self.count_again)
        speculative = min(max(SPECULATIVE_RECORDS, self.recent_records * 5 // 4),
                          self.caps["records"]) if want_records else 0
        # The readback: the counters, the per-pair flags, the first records, the timestamps.
        flags = 4 * self.n_pairs
        head = -(-(4 * COUNTERS + flags) // 16) * 16
        stamps = -(-(head + 16 * speculative) // 8) * 8
        nbytes = stamps + self.profiler.nbytes
        readback = self.readbacks[sub.slot]
        staging = readback.ensure(nbytes)
        encoder.copy_buffer_to_buffer(self.counters, 0, staging, 0, 4 * COUNTERS)
        if t:
            encoder.copy_buffer_to_buffer(self.tile_counts.buffer, 8 * t, staging, 4 * COUNTERS,
                                          flags)
            copy = self.tile_copies[sub.slot]
            copy.ensure(8 * t)
            encoder.copy_buffer_to_buffer(self.tile_counts.buffer, 0, copy.buffer, 0, 8 * t)
        if speculative:
            encoder.copy_buffer_to_buffer(self._records(sub.slot).buffer, 0, staging, head,
                                          16 * speculative)
        self.profiler.resolve(encoder, staging, stamps)
        device.queue.submit([encoder.finish()])
        self._bound_pending = None
        sub.layout = dict(t=t, head=head, stamps=stamps, nbytes=nbytes, speculative=speculative,
                          timed=list(self.profiler.names), records=want_records,
                          capacity=(self.run_capacity, self.round_capacity(retry=True)),
                          pairs=self.n_pairs,
                          waiting=f"a frame of {t} tiles in {n_rounds} rounds")
        sub.pending = readback.start(nbytes)

    def _read(self, sub: Submitted) -> FocusedOutput:
        """Wait for a submitted frame's readback (one map) and decode its words. A second map
        reads the per-tile counts when some tile must run again, and the records beyond those
        the first brought."""
        lay = sub.layout
        t, head, stamps, speculative = lay["t"], lay["head"], lay["stamps"], lay["speculative"]
        data = self.readbacks[sub.slot].wait(sub.pending, lay["nbytes"], timeout=self.timeout,
                                             waiting_for=lay["waiting"])
        gpu_ms = self.profiler.times(data[stamps // 4:], lay["timed"])
        counters = data[:COUNTERS].astype(np.int64)
        pair_found = data[COUNTERS:COUNTERS + lay["pairs"]] != 0
        n_records = int(min(counters[C_RECORDS], self.caps["records"])) if lay["records"] else 0
        if lay["records"]:
            self.recent_records = n_records
        bytes_read = lay["nbytes"]
        tiles = 8 * t if counters[C_AGAIN] else 0
        more_records = 16 * n_records if n_records > speculative else 0
        tile_counts = None
        recs = data[head // 4: head // 4 + 4 * n_records].reshape(-1, 4)
        if tiles or more_records:
            device = self.gpu.device
            encoder = device.create_command_encoder()
            more = self.readbacks_more[sub.slot]
            staging = more.ensure(tiles + more_records)
            if tiles:
                encoder.copy_buffer_to_buffer(self.tile_copies[sub.slot].buffer, 0, staging, 0,
                                              tiles)
            if more_records:
                encoder.copy_buffer_to_buffer(self._records(sub.slot).buffer, 0, staging, tiles,
                                              more_records)
            device.queue.submit([encoder.finish()])
            words = more.read(tiles + more_records, timeout=self.timeout,
                              waiting_for=f"the counts of {t} tiles and {n_records} records")
            bytes_read += tiles + more_records
            if tiles:
                tile_counts = words[:2 * t].reshape(t, 2).astype(np.int64)
            if more_records:
                recs = words[tiles // 4:].reshape(-1, 4)
        if len(recs):
            recs = recs[np.lexsort((recs[:, 3], recs[:, 2], recs[:, 1], recs[:, 0]))]
        return FocusedOutput(pair_found, tile_counts, recs, counters, bytes_read, 0, gpu_ms,
                             undecided=int(counters[C_UNDECIDED]),
                             retried_tiles=int(counters[C_RETRY_TILES]),
                             capacity=lay["capacity"][1 if counters[C_RETRY_TILES] else 0])

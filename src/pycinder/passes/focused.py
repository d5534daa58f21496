"""The focused strategy's GPU passes over a tile atlas, and their buffers.

    F0 bounds     (compute, when vertices changed)  cluster bounds in body space
    F1 cull       (compute)  per tile, side and cluster: keep the cluster's faces and/or edges
    F2 clip       (compute, indirect)  kept faces into their tile's window, clipped watertight
    F3 crossings  (render, indirect)   every clipped face once: per-pixel ray crossings
    F5 surface test (compute, indirect) every listed surface point tested against the other body
    F4 edge test  (compute, indirect)  kept edges sampled and tested, unless F5 found the pair

F1 to F5 run once per round of the atlas (one round unless the memory budget is exceeded), all
in one submission; one readback brings back the counters, the per-tile hit counts and the first
records. Pipelines and buffers are created once and grown when a frame needs more; a frame whose
counts outgrow a buffer is run again with the buffer grown, so nothing is dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import wgpu

from ..gpu.buffers import GrowableBuffer, Readback
from ..gpu.device import Gpu, shader_source
from ..scene.pack import ShapePack
from ..tiles import TilePlan
from .states import FOCUSED_CROSSINGS

LIST_CAPACITY = 8
"""Crossings kept per pixel within a tile's box (both bodies together)."""

TILE_WORDS = 36
"""32-bit words of one ``Tile`` in ``tiles.wgsl``."""

COUNTERS = 16
C_FACE_ITEMS, C_EDGE_ITEMS, C_TRIS = 0, 1, 2
C_RECORDS, C_UNDECIDED, C_SAMPLES = 4, 5, 6
C_MAX_FACE_ITEMS, C_MAX_EDGE_ITEMS, C_MAX_TRIS = 8, 9, 10
C_TOTAL_TRIS, C_TOTAL_FACE_ITEMS, C_TOTAL_EDGE_ITEMS = 11, 12, 13

ROW = 32768
"""Workgroups per row of an indirect dispatch (``tiles.wgsl``)."""

PASS_NAMES = ("F1 cull", "F2 clip", "F3 crossings", "F5 surface test", "F4 edge test")
MAX_PROFILED_ROUNDS = 8

SPECULATIVE_RECORDS = 4096
"""Records copied into the first readback, so that most frames need one round trip."""

PARAM_STRIDE = 256
"""Bytes between parameter blocks (the uniform offset alignment)."""
ROUND_STRIDE = 2 * PARAM_STRIDE
"""Bytes of one round's parameters: the cull's block, then the surface test's."""
PIXEL_BYTES = 12
"""Per atlas pixel: crossings listed, winding outside the box, tile."""
ENTRY_BYTES = 8
"""Per listed crossing: depth and flags, face."""
P_FINALIZE, P_CLIP, P_ATLAS, P_EDGES, P_BOUNDS = range(5)
"""Blocks of the frame parameter buffer."""

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
    (T, 36) uint32
    """
    t = len(plan)
    out = np.zeros((t, TILE_WORDS), dtype=np.uint32)
    f = out.view(np.float32)
    f[:, 0:24] = matrices.reshape(t, 24)
    out[:, 24:28] = plan.window
    f[:, 28:30] = plan.slab
    out[:, 32:34] = plan.bodies
    out[:, 34] = plan.flags
    out[:, 35] = plan.pair
    return out


class _Stages:
    """Compute stages of a round. Normally consecutive stages share one compute pass (each
    dispatch is its own usage scope, so later ones see earlier ones' writes, indirect arguments
    included), saving a pass's fixed cost; when profiling, each stage gets its own timed pass."""

    def __init__(self, encoder: wgpu.GPUCommandEncoder, passes: FocusedPasses, r: int) -> None:
        self.encoder, self.passes, self.round = encoder, passes, r
        self.current: wgpu.GPUComputePassEncoder | None = None

    def compute(self, k: int, name: str) -> wgpu.GPUComputePassEncoder:
        if self.current is not None and not self.passes.profile:
            return self.current
        self.end()
        self.current = self.encoder.begin_compute_pass(
            label=f"{name}, round {self.round}", **self.passes._timestamps(self.round, k))
        return self.current

    def end(self) -> None:
        if self.current is not None:
            self.current.end()
            self.current = None


@dataclass
class FocusedOutput:
    """What one frame of the focused passes found.

    Attributes
    ----------
    tile_counts : (T, 2) int64
        Per tile: samples found inside the other body, samples undecided (list overflow).
    records : (R, 4) uint32
        tile, u | v << 16, f32 bits of z, edge | side << 31; sorted.
    counters : (16,) int64
    """

    tile_counts: np.ndarray
    records: np.ndarray
    counters: np.ndarray
    bytes_read: int
    reruns: int


class FocusedPasses:
    """Pipelines and buffers of passes F0-F4, made once per detector.

    Parameters
    ----------
    gpu : Gpu
    list_capacity : int
        Crossings kept per pixel.
    """

    def __init__(self, gpu: Gpu, list_capacity: int = LIST_CAPACITY, profile: bool = False
                 ) -> None:
        self.gpu = gpu
        self.capacity = int(list_capacity)
        device = gpu.device
        self.profile = profile and gpu.timestamps
        if self.profile:
            n = 2 * len(PASS_NAMES) * MAX_PROFILED_ROUNDS
            self.queries = device.create_query_set(type="timestamp", count=n)
            self.query_buf = device.create_buffer(size=8 * n,
                                                  usage=_U.QUERY_RESOLVE | _U.COPY_SRC)
            self.query_readback = Readback(device, "timestamps")
        self.gpu_ms: dict[str, float] = {}
        modules: dict[str, wgpu.GPUShaderModule] = {}

        def compute(name: str, entry: str) -> wgpu.GPUComputePipeline:
            if name not in modules:
                modules[name] = device.create_shader_module(label=name, code=shader_source(name))
            return device.create_compute_pipeline(
                label=f"{name}: {entry}", layout="auto",
                compute={"module": modules[name], "entry_point": entry})

        self.bounds = compute("bounds", "cluster_bounds")
        self.cull = compute("cull", "cull")
        self.after_cull = compute("finalize", "after_cull")
        self.clip = compute("clip", "clip")
        self.after_clip = compute("finalize", "after_clip")
        self.after_crossings = compute("finalize", "after_crossings")
        self.edge_test = compute("edgetest", "edge_test")
        self.surface_test = compute("surfacetest", "surface_test")
        crossings = device.create_shader_module(label="crossings", code=shader_source("crossings"))
        state = FOCUSED_CROSSINGS
        self.crossings = device.create_render_pipeline(
            label=f"pass {state.number}: {state.purpose}", layout="auto",
            vertex={"module": crossings, "entry_point": "vs"},
            primitive={"topology": "triangle-list", "cull_mode": state.cull},
            fragment={"module": crossings, "entry_point": "fs",
                      "targets": [{"format": "r8unorm", "write_mask": state.write_mask}]})

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
        self.entry_prefix = grow("entry prefix")
        self.entry_cluster = grow("entry cluster")
        self.face_items = grow("face items", _U.STORAGE)
        self.edge_items = grow("edge items", _U.STORAGE)
        self.tris = grow("clipped triangles", _U.STORAGE)
        self.tri_face = grow("triangle faces", _U.STORAGE)
        self.active = grow("active pixels", _U.STORAGE)
        self.pixels = grow("pixel counts", _U.STORAGE | _U.COPY_DST)
        self.lists = grow("pixel crossings", _U.STORAGE)
        self.tile_counts = grow("tile counts", _U.STORAGE | _U.COPY_SRC | _U.COPY_DST)
        self.records = grow("records", _U.STORAGE | _U.COPY_SRC)
        self.counters = device.create_buffer(label="counters", size=4 * COUNTERS,
                                             usage=_U.STORAGE | _U.COPY_SRC | _U.COPY_DST)
        self.args = device.create_buffer(label="indirect args", size=64,
                                         usage=_U.STORAGE | _U.INDIRECT)
        self.round_params = grow("round parameters", _U.UNIFORM | _U.COPY_DST)
        self.frame_params = device.create_buffer(label="frame parameters", size=5 * PARAM_STRIDE,
                                                 usage=_U.UNIFORM | _U.COPY_DST)
        self.readback = Readback(device, "focused readback")
        self.readback_more = Readback(device, "focused records")
        self.target: wgpu.GPUTexture | None = None
        self.target_view: wgpu.GPUTextureView | None = None
        self.caps = {"tris": 1 << 16, "records": 1 << 16}
        self.layout: tuple | None = None
        self.uploaded: list | None = None
        self._groups: dict[str, tuple[tuple, wgpu.GPUBindGroup]] = {}

    # -- shapes -----------------------------------------------------------------------------

    def upload(self, pack: ShapePack, shapes: list) -> int:
        """Upload the shapes; returns the vertex bytes written.

        Index buffers are written when the layout (topologies, vertex counts) changed; vertices
        only for shapes that are new objects (shapes are cached by content, so a new object
        means new vertices). Cluster bounds are recomputed for those shapes on the GPU.
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
            self._update_bounds(which)
        return written

    def _bind(self, name: str, pipeline: wgpu.GPUComputePipeline | wgpu.GPURenderPipeline,
              resources: list) -> wgpu.GPUBindGroup:
        """A bind group of ``resources`` (buffers, or (buffer, offset, size)), rebuilt only when
        a buffer was replaced."""
        # The key holds the buffers themselves: an id alone can be reused by a new buffer once
        # a grown one is freed.
        key = tuple((r[0], r[1]) if isinstance(r, tuple) else (r, 0) for r in resources)
        cached = self._groups.get(name)
        if cached is not None and len(cached[0]) == len(key) and all(
                a[0] is b[0] and a[1] == b[1] for a, b in zip(cached[0], key)):
            return cached[1]
        entries = []
        for i, r in enumerate(resources):
            if isinstance(r, tuple):
                entries.append({"binding": i, "resource": {"buffer": r[0], "offset": r[1],
                                                            "size": r[2]}})
            else:
                entries.append({"binding": i, "resource": {"buffer": r}})
        group = self.gpu.device.create_bind_group(layout=pipeline.get_bind_group_layout(0),
                                                  entries=entries)
        self._groups[name] = (key, group)
        return group

    def _update_bounds(self, which: np.ndarray) -> None:
        device = self.gpu.device
        self.which.ensure(which.nbytes)
        self.which.write(which)
        params = np.array([len(which), 0, 0, 0], dtype=np.uint32)
        device.queue.write_buffer(self.frame_params, P_BOUNDS * PARAM_STRIDE, params)
        group = self._bind("bounds", self.bounds, [
            self.positions.buffer, self.faces.buffer, self.clusters.buffer, self.which.buffer,
            self.cluster_bounds.buffer, (self.frame_params, P_BOUNDS * PARAM_STRIDE, 16)])
        encoder = device.create_command_encoder()
        cpass = encoder.begin_compute_pass(label="F0 cluster bounds")
        cpass.set_pipeline(self.bounds)
        cpass.set_bind_group(0, group)
        cpass.dispatch_workgroups(*_groups(-(-len(which) // 64)))
        cpass.end()
        device.queue.submit([encoder.finish()])

    # -- one frame --------------------------------------------------------------------------

    def run(self, plan: TilePlan, matrices: np.ndarray, body_shape: np.ndarray,
            pack: ShapePack, n_pairs: int, *, records: bool = True, all_records: bool = False,
            list_capacity: int | None = None) -> FocusedOutput:
        """Run passes F1-F4 for every tile and read back what they found.

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
        records : bool
            Read back the records (False: only the per-tile counts).
        all_records : bool
            Test every edge of every tile (otherwise tiles of pairs already found are skipped).
        list_capacity : int, optional
            Crossings kept per pixel in this run (default: the one given at construction).
        """
        self.run_capacity = int(list_capacity or self.capacity)
        self.all_records = all_records
        t = len(plan)
        words = tile_words(plan, matrices)
        shapes = body_shape[plan.bodies].reshape(-1)                    # entry e = 2 * tile + side
        count = np.diff(pack.cluster_start)[shapes]
        prefix = np.concatenate([[0], np.cumsum(count)])
        if prefix[-1] >= 2**32:
            raise ValueError("too many cluster tests in one frame; raise the tolerance or split "
                             "the scene into several queries")
        bounds = np.searchsorted(plan.round, np.arange(len(plan.round_rows) + 1))
        round_threads = np.diff(prefix[2 * bounds])
        self.tiles.ensure(words.nbytes)
        self.tiles.write(words)
        self.entry_prefix.ensure(4 * len(prefix))
        self.entry_prefix.write(prefix.astype(np.uint32))
        first_cluster = pack.cluster_start[shapes].astype(np.uint32)
        self.entry_cluster.ensure(first_cluster.nbytes)
        self.entry_cluster.write(first_cluster)
        items = int(round_threads.max()) if len(round_threads) else 0
        self.face_items.ensure(8 * max(items, 1))
        self.edge_items.ensure(8 * max(items, 1))
        self.tile_counts.ensure(8 * t + 4 * n_pairs + 4)
        self.n_pairs = n_pairs
        width = plan.atlas_width
        rows = max(plan.round_rows) if plan.round_rows else 1
        self._ensure_target(width, rows)
        self.pixels.ensure(PIXEL_BYTES * width * rows)
        self.lists.ensure(ENTRY_BYTES * self.run_capacity * width * rows)
        self.active.ensure(4 * width * rows)
        reruns = 0
        while True:
            self.tris.ensure(48 * self.caps["tris"])
            self.tri_face.ensure(4 * self.caps["tris"])
            self.records.ensure(16 * self.caps["records"])
            out = self._frame(plan, bounds, round_threads, items, records)
            c = out.counters
            grown = False
            if c[C_MAX_TRIS] > self.caps["tris"]:
                self.caps["tris"] = int(c[C_MAX_TRIS] * 1.5) + 1024
                grown = True
            if c[C_RECORDS] > self.caps["records"] and records:
                self.caps["records"] = int(c[C_RECORDS] * 1.5) + 1024
                grown = True
            if not grown:
                out.reruns = reruns
                return out
            reruns += 1

    def _timestamps(self, r: int, k: int) -> dict:
        """Timestamp writes of pass ``k`` of round ``r`` (only while profiling)."""
        if not self.profile or r >= MAX_PROFILED_ROUNDS:
            return {}
        i = 2 * (r * len(PASS_NAMES) + k)
        return {"timestamp_writes": {"query_set": self.queries, "beginning_of_pass_write_index": i,
                                     "end_of_pass_write_index": i + 1}}

    def _ensure_target(self, width: int, rows: int) -> None:
        if self.target is not None and self.target.width >= width and self.target.height >= rows:
            return
        height = max(rows, self.target.height if self.target is not None else 0)
        self.target = self.gpu.device.create_texture(
            label="atlas", size=(width, height, 1), format="r8unorm",
            usage=wgpu.TextureUsage.RENDER_ATTACHMENT)
        self.target_view = self.target.create_view()

    def _frame(self, plan: TilePlan, bounds: np.ndarray, round_threads: np.ndarray, items: int,
               want_records: bool) -> FocusedOutput:
        device = self.gpu.device
        queue = device.queue
        n_rounds = len(plan.round_rows)
        width = plan.atlas_width
        caps = self.caps
        # Per-round parameters of the cull, one uniform block each.
        self.round_params.ensure(ROUND_STRIDE * max(n_rounds, 1))
        block = np.zeros((max(n_rounds, 1), ROUND_STRIDE // 4), dtype=np.uint32)
        surface = PARAM_STRIDE // 4
        for r in range(n_rounds):
            block[r, :6] = (round_threads[r], 2 * bounds[r], 2 * (bounds[r + 1] - bounds[r]),
                            items, items, 2 * len(plan))
            block[r, surface:surface + 5] = (width, plan.round_rows[r], self.run_capacity,
                                             caps["records"] if want_records else 0, 2 * len(plan))
        self.round_params.write(block)
        frame = np.zeros((4, PARAM_STRIDE // 4), dtype=np.uint32)
        frame[P_FINALIZE, :4] = (items, items, caps["tris"], 0)
        frame[P_CLIP, :4] = (caps["tris"], items, 0, 0)
        frame[P_ATLAS, :4] = (width, self.target.height, self.run_capacity, 0)
        frame[P_EDGES, :6] = (width, self.run_capacity, caps["records"] if want_records else 0,
                              items, 2 * len(plan), 0 if self.all_records else 1)
        queue.write_buffer(self.frame_params, 0, frame)

        b = self
        finalize = self._bind("finalize", self.after_cull, [
            b.counters, b.args, (b.frame_params, P_FINALIZE * PARAM_STRIDE, 16)])
        finalize2 = self._bind("finalize2", self.after_clip, [
            b.counters, b.args, (b.frame_params, P_FINALIZE * PARAM_STRIDE, 16)])
        clip = self._bind("clip", self.clip, [
            b.tiles.buffer, b.clusters.buffer, b.positions.buffer, b.faces.buffer,
            b.face_items.buffer, b.tris.buffer, b.counters, (b.frame_params, P_CLIP * PARAM_STRIDE, 16),
            b.tri_face.buffer])
        crossings = self._bind("crossings", self.crossings, [
            b.tris.buffer, b.tiles.buffer, b.pixels.buffer, b.lists.buffer,
            (b.frame_params, P_ATLAS * PARAM_STRIDE, 16), b.tri_face.buffer, b.active.buffer,
            b.counters])
        finalize3 = self._bind("finalize3", self.after_crossings, [
            b.counters, b.args, (b.frame_params, P_FINALIZE * PARAM_STRIDE, 16)])
        edges = self._bind("edges", self.edge_test, [
            b.tiles.buffer, b.clusters.buffer, b.positions.buffer, b.edges.buffer,
            b.edge_items.buffer, b.pixels.buffer, b.lists.buffer, b.tile_counts.buffer,
            b.records.buffer, b.counters, (b.frame_params, P_EDGES * PARAM_STRIDE, 32)])

        encoder = device.create_command_encoder()
        encoder.clear_buffer(self.counters)
        encoder.clear_buffer(self.tile_counts.buffer, 0, 8 * len(plan) + 4 * self.n_pairs)
        for r in range(n_rounds):
            if round_threads[r] == 0:
                continue
            cull = self._bind(f"cull{r}", self.cull, [
                b.tiles.buffer, b.clusters.buffer, b.cluster_bounds.buffer,
                b.entry_prefix.buffer, b.entry_cluster.buffer, b.face_items.buffer,
                b.edge_items.buffer, b.counters, (b.round_params.buffer, r * ROUND_STRIDE, 32),
                b.tile_counts.buffer])
            surface = self._bind(f"surface{r}", self.surface_test, [
                b.tiles.buffer, b.pixels.buffer, b.lists.buffer, b.tile_counts.buffer,
                b.records.buffer, b.counters,
                (b.round_params.buffer, r * ROUND_STRIDE + PARAM_STRIDE, 32), b.active.buffer])
            encoder.clear_buffer(self.counters, 0, 16)
            encoder.clear_buffer(self.pixels.buffer, 0, PIXEL_BYTES * width * plan.round_rows[r])
            stages = _Stages(encoder, self, r)
            cpass = stages.compute(0, "F1 cull")
            cpass.set_pipeline(self.cull)
            cpass.set_bind_group(0, cull)
            cpass.dispatch_workgroups(*_groups(-(-int(round_threads[r]) // 64)))
            cpass.set_pipeline(self.after_cull)
            cpass.set_bind_group(0, finalize)
            cpass.dispatch_workgroups(1)
            cpass = stages.compute(1, "F2 clip")
            cpass.set_pipeline(self.clip)
            cpass.set_bind_group(0, clip)
            cpass.dispatch_workgroups_indirect(self.args, 0)
            cpass.set_pipeline(self.after_clip)
            cpass.set_bind_group(0, finalize2)
            cpass.dispatch_workgroups(1)
            stages.end()
            rpass = encoder.begin_render_pass(
                label=f"F3 crossings, round {r}",
                color_attachments=[{"view": self.target_view, "load_op": "load",
                                    "store_op": "discard"}], **self._timestamps(r, 2))
            rpass.set_pipeline(self.crossings)
            rpass.set_bind_group(0, crossings)
            rpass.draw_indirect(self.args, 24)
            rpass.end()
            cpass = stages.compute(3, "F5 surface test")
            cpass.set_pipeline(self.after_crossings)
            cpass.set_bind_group(0, finalize3)
            cpass.dispatch_workgroups(1)
            cpass.set_pipeline(self.surface_test)
            cpass.set_bind_group(0, surface)
            cpass.dispatch_workgroups_indirect(self.args, 40)
            cpass = stages.compute(4, "F4 edge test")
            cpass.set_pipeline(self.edge_test)
            cpass.set_bind_group(0, edges)
            cpass.dispatch_workgroups_indirect(self.args, 12)
            stages.end()
        t = len(plan)
        speculative = min(SPECULATIVE_RECORDS, caps["records"]) if want_records else 0
        head = 4 * COUNTERS + 8 * t
        staging = self.readback.ensure(head + 16 * speculative)
        encoder.copy_buffer_to_buffer(self.counters, 0, staging, 0, 4 * COUNTERS)
        if t:
            encoder.copy_buffer_to_buffer(self.tile_counts.buffer, 0, staging, 4 * COUNTERS, 8 * t)
        if speculative:
            encoder.copy_buffer_to_buffer(self.records.buffer, 0, staging, head, 16 * speculative)
        profiled = min(n_rounds, MAX_PROFILED_ROUNDS) if self.profile else 0
        if profiled:
            nq = 2 * len(PASS_NAMES) * MAX_PROFILED_ROUNDS
            encoder.resolve_query_set(self.queries, 0, nq, self.query_buf, 0)
            encoder.copy_buffer_to_buffer(self.query_buf, 0, self.query_readback.ensure(8 * nq), 0,
                                          8 * nq)
        queue.submit([encoder.finish()])
        self.gpu_ms = {}
        if profiled:
            ts = self.query_readback.read(8 * 2 * len(PASS_NAMES) * MAX_PROFILED_ROUNDS, np.uint64)
            ts = ts.astype(np.float64).reshape(MAX_PROFILED_ROUNDS, len(PASS_NAMES), 2)
            for r in range(profiled):
                if round_threads[r] == 0:
                    continue
                for k, name in enumerate(PASS_NAMES):
                    self.gpu_ms[name] = self.gpu_ms.get(name, 0.0) + (ts[r, k, 1] - ts[r, k, 0]) * 1e-6
        n_records_guess = speculative
        data = self.readback.read(head + 16 * n_records_guess)
        counters = data[:COUNTERS].astype(np.int64)
        tile_counts = data[COUNTERS:COUNTERS + 2 * t].reshape(t, 2).astype(np.int64)
        n_records = int(min(counters[C_RECORDS], caps["records"])) if want_records else 0
        bytes_read = 4 * COUNTERS + 8 * t + 16 * speculative
        if n_records <= speculative:
            recs = data[head // 4: head // 4 + 4 * n_records].reshape(-1, 4)
        else:
            encoder = device.create_command_encoder()
            staging = self.readback_more.ensure(16 * n_records)
            encoder.copy_buffer_to_buffer(self.records.buffer, 0, staging, 0, 16 * n_records)
            queue.submit([encoder.finish()])
            recs = self.readback_more.read(16 * n_records).reshape(-1, 4)
            bytes_read += 16 * n_records
        if len(recs):
            recs = recs[np.lexsort((recs[:, 3], recs[:, 2], recs[:, 1], recs[:, 0]))]
        return FocusedOutput(tile_counts, recs, counters, bytes_read, 0)

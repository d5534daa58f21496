"""The Detector: owns pipelines and buffers, and runs the stages of one query.

    bodies + transforms -> scene (validate, pack) -> upload -> for each view:
        passes 1-4 -> [copy for prevent] -> passes 5-7 -> filter -> read back -> decode
    -> merge views -> CollisionResult
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
import wgpu

from .gpu.buffers import Readback, SceneBuffers, Targets
from .gpu.device import check_resolution, get_gpu
from .passes.raycast import RaycastPasses
from .passes.reduce import MipReduce
from .passes.selfint import COUNTERS_BYTES, RECORD_BYTES, FilterPass
from .result import RECORD_DTYPE, CollisionResult, Stats, decode_compact, decode_image, unique_pairs
from .scene import PackedScene, TopologyCache, prepare_bodies, repack
from .view import View, world_corners



class ClippedBodyWarning(UserWarning):
    """A user view's near or far plane cuts a body."""


SELF_INTERFERENCE_MODES = ("filter", "prevent", "offset")
READBACK_MODES = ("full", "compact", "mipmap", "adaptive")
FILTER_OUTPUT = {"full": "full", "compact": "compact", "mipmap": "packed", "adaptive": "packed"}
ENCODINGS = ("edge", "normal")


class Detector:
    """CInDeR collision detection with GPU resources kept between calls.

    Parameters
    ----------
    resolution : int
        Width and height of the render target in pixels. Detail smaller than one pixel of the view
        can be missed.
    self_interference : {"filter", "prevent", "offset"}
        How z-fighting between a body's edges and its own faces is handled (paper 4.3.1):
        ``"filter"`` blanks such pixels before readback; ``"prevent"`` (default) never registers
        them, so they cannot overwrite real collisions; ``"offset"`` moves edges outward.
    readback : {"full", "compact", "mipmap", "adaptive"}
        What is read back (paper 4.3.2). ``"full"``: the whole filtered image. ``"compact"``
        (default): only the surviving records, appended on the GPU through an atomic counter
        (lossless).
        ``"mipmap"``: the image reduced ``mipmap_levels`` times by keeping one record per 2x2
        block (lossy; ``stats.possibly_lost`` counts blocks where different pairs met).
        ``"adaptive"``: reduced for as long as no pair is lost. Every mode reads back only a
        16-byte counter when nothing collides.
    mipmap_levels : int
        Reductions for ``readback="mipmap"``.
    encode : {"edge", "normal"}
        What the payload channel of each record holds: the penetrating edge's index, or its
        world-space normal (paper 5.3).
    edge_offset : float, optional
        For ``self_interference="offset"``: how far edges move outward along their vertex normals,
        in body units. Default: half a pixel of the fitted view.
    strict : bool
        Raise instead of warning for open meshes and zero-area faces.
    profile : bool
        Measure each GPU stage with timestamp queries where the adapter supports them.
    """

    def __init__(self, resolution: int = 512, *, self_interference: str = "prevent",
                 readback: str = "compact", mipmap_levels: int = 2, encode: str = "edge",
                 edge_offset: float | None = None, strict: bool = False,
                 profile: bool = False) -> None:
        for value, allowed, name in ((self_interference, SELF_INTERFERENCE_MODES, "self_interference"),
                                     (readback, READBACK_MODES, "readback"),
                                     (encode, ENCODINGS, "encode")):
            if value not in allowed:
                raise ValueError(f"{name} must be one of {allowed}, got {value!r}")
        if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)):
            raise ValueError(f"resolution must be a positive integer, got {resolution!r}")
        self.gpu = get_gpu()
        check_resolution(self.gpu, int(resolution), int(resolution))
        self.resolution = int(resolution)
        self.self_interference = self_interference
        self.readback = readback
        self.encode = encode
        self.edge_offset = edge_offset
        self.strict = strict
        device = self.gpu.device
        self.targets = Targets(device, self.resolution, self.resolution, self.gpu.depth_format)
        self.raycast = RaycastPasses(self.gpu, prevent=self_interference == "prevent")
        self.filter = FilterPass(self.gpu, FILTER_OUTPUT[readback])
        self.reduce: MipReduce | None = None
        if readback in ("mipmap", "adaptive"):
            levels = mipmap_levels if readback == "mipmap" else \
                max(1, int(np.log2(self.resolution)) - 1)
            if not isinstance(levels, (int, np.integer)) or not 1 <= levels <= 14:
                raise ValueError(f"mipmap_levels must be an integer from 1 to 14, got {levels!r}")
            self.reduce = MipReduce(self.gpu, self.resolution, self.resolution, int(levels))
        self.mipmap_levels = mipmap_levels
        self.buffers = SceneBuffers(device)
        self._topologies = TopologyCache()
        self._counters_readback = Readback(device, "counters readback")
        self._records_readback = Readback(device, "records readback")
        self._profile = profile and self.gpu.timestamps
        if self._profile:
            self._stage_names = [" + ".join(f"pass {n}" for n in step.passes)
                                 for step in self.raycast.plan] + ["filter"]
            self._n_queries = 2 * len(self._stage_names)
            self._queries = device.create_query_set(type="timestamp", count=self._n_queries)
            self._query_buf = device.create_buffer(
                size=8 * self._n_queries,
                usage=wgpu.BufferUsage.QUERY_RESOLVE | wgpu.BufferUsage.COPY_SRC)
            self._query_readback = Readback(device, "timestamps readback")

    # -- public API ---------------------------------------------------------------------------

    def find_collisions(self, bodies: Sequence[Any], transforms: Any = None, *,
                        view: View | Sequence[View] | None = None,
                        names: Sequence[str | None] | None = None) -> CollisionResult:
        """Find every pair of interfering bodies.

        bodies : sequence of trimesh.Trimesh or (vertices (V, 3), faces (F, 3)) pairs
        transforms : None, or (N, 4, 4) float world-from-body matrices
        view : a :class:`View`, several (their results are merged), or None to fit one
        names : optional body names for error messages
        """
        t0 = time.perf_counter()
        stats = Stats(readback=self.readback, self_interference=self.self_interference,
                      resolution=(self.resolution, self.resolution), adapter=self.gpu.description)
        prepared = self.prepare(bodies, transforms, view=view, names=names)
        if prepared is None:
            return CollisionResult(np.zeros((0, 2), dtype=np.int64), np.zeros(0, RECORD_DTYPE),
                                   [], stats.resolution, stats)
        scene, transforms_arr, views = prepared
        stats.uploaded_vertex_bytes = self.buffers.uploaded_vertex_bytes
        stats.views = len(views)
        stats.wall_ms["prepare"] = (time.perf_counter() - t0) * 1e3
        parts = []
        for k, v in enumerate(views):
            rec, view_stats = self._run_view(k, v, transforms_arr, scene)
            parts.append(rec)
            stats.merge(view_stats)
        records = np.concatenate(parts) if len(parts) > 1 else parts[0]
        t3 = time.perf_counter()
        pairs = unique_pairs(records)
        stats.records = len(records)
        stats.wall_ms["total"] = (time.perf_counter() - t0) * 1e3
        stats.wall_ms["decode"] = stats.wall_ms.get("decode", 0.0) + (time.perf_counter() - t3) * 1e3
        return CollisionResult(pairs, records, views, stats.resolution, stats,
                               (scene.edges, scene.edge_start, scene.vertex_start))

    def prepare(self, bodies: Sequence[Any], transforms: Any = None, *,
                view: View | Sequence[View] | None = None,
                names: Sequence[str | None] | None = None
                ) -> tuple[PackedScene, np.ndarray, list[View]] | None:
        """Validate and upload a scene; None when there are no bodies.

        Returns the packed scene, the (N, 4, 4) transforms and the views to render.
        """
        body_list, normals = prepare_bodies(bodies, transforms, names=names, strict=self.strict,
                                            cache=self._topologies)
        if not body_list:
            return None
        scene = repack(self.buffers.scene, body_list, normals)
        self.buffers.upload(scene)
        transforms_arr = np.stack([b.transform for b in body_list])
        return scene, transforms_arr, self._views(view, body_list, transforms_arr)

    def set_view(self, view: View, transforms: np.ndarray) -> None:
        """Upload the per-body matrices and frame constants for rendering through ``view``."""
        clip = np.einsum("ij,njk->nik", view.clip_from_world, transforms)
        self.buffers.upload_transforms(clip, transforms)
        self.buffers.write_frame(self._edge_offset(view), 1 if self.encode == "normal" else 0)

    # -- stages -------------------------------------------------------------------------------

    def _views(self, view: View | Sequence[View] | None, bodies: list,
               transforms: np.ndarray) -> list[View]:
        lo = np.stack([b.vertices.min(axis=0) for b in bodies]).astype(np.float64)
        hi = np.stack([b.vertices.max(axis=0) for b in bodies]).astype(np.float64)
        if view is None:
            return [View.fit(world_corners(lo, hi, transforms), resolution=self.resolution)]
        views = [view] if isinstance(view, View) else list(view)
        if not views or not all(isinstance(v, View) for v in views):
            raise TypeError("view must be a View, a non-empty sequence of Views, or None")
        for k, v in enumerate(views):
            self._check_depth_range(k, v, bodies, lo, hi, transforms)
        return views

    def _check_depth_range(self, k: int, view: View, bodies: list, lo: np.ndarray,
                           hi: np.ndarray, transforms: np.ndarray) -> None:
        """Warn (raise when strict) when the near or far plane cuts a body: the ray count through
        a cut solid is wrong. Bounding boxes first; exact vertices only for suspects."""
        zmin, zmax = view.depth_range(lo, hi, transforms)
        for i in np.flatnonzero((zmin < 0) | (zmax > 1)):
            b = bodies[i]
            z = view.project(b.vertices @ b.transform[:3, :3].T + b.transform[:3, 3], 1, 1)[:, 2]
            if z.min() >= 0 and z.max() <= 1:
                continue
            plane = "near" if z.min() < 0 else "far"
            message = (f"{b.label} is cut by the {plane} plane of view {k}; the ray count through "
                       "a cut solid is wrong, so its collisions may be missed or invented. Use "
                       "View.fit_bodies or move the planes.")
            if self.strict:
                raise ValueError(message)
            warnings.warn(message, ClippedBodyWarning, stacklevel=4)

    def _edge_offset(self, view: View) -> float:
        if self.self_interference != "offset":
            return 0.0
        if self.edge_offset is not None:
            return float(self.edge_offset)
        return 0.5 * view.pixel_size if view.pixel_size else 0.0

    def _timestamps(self, i: int) -> dict | None:
        if not self._profile:
            return None
        return {"query_set": self._queries, "beginning_of_pass_write_index": 2 * i,
                "end_of_pass_write_index": 2 * i + 1}

    def _readback_source(self, counters: np.ndarray, survivors: int, stats: Stats
                         ) -> tuple[wgpu.GPUBuffer, int, bool]:
        """The buffer to read records from, its byte count, and whether it is a packed image."""
        if self.readback == "compact":
            return self.filter.out.buffer, survivors * RECORD_BYTES, False
        if self.readback == "full":
            return self.filter.out.buffer, self.targets.pixels * RECORD_BYTES, False
        lost = counters[COUNTERS_BYTES // 4:COUNTERS_BYTES // 4 + self.reduce.levels + 1]
        cumulative = np.cumsum(lost.astype(np.int64))
        if self.readback == "mipmap":
            level = self.reduce.levels
            stats.possibly_lost = int(cumulative[level])
        else:
            # Adaptive: the deepest level at which no block has merged two pairs.
            level = int(np.flatnonzero(cumulative == 0).max())
        stats.mip_level = level
        if level == 0:
            return self.filter.out.buffer, self.targets.pixels * RECORD_BYTES, True
        return self.reduce.level_buffer(level), self.reduce.level_bytes(level), True

    def _run_view(self, k: int, view: View, transforms: np.ndarray, scene: PackedScene
                  ) -> tuple[np.ndarray, Stats]:
        stats = Stats()
        t0 = time.perf_counter()
        self.set_view(view, transforms)
        device = self.gpu.device
        encoder = device.create_command_encoder()
        steps = len(self.raycast.plan)
        self.raycast.encode(encoder, self.buffers, self.targets,
                            [self._timestamps(i) for i in range(steps)] if self._profile else None)
        self.filter.encode(encoder, self.targets, timestamp_writes=self._timestamps(steps))
        header = COUNTERS_BYTES
        staging = self._counters_readback.ensure(COUNTERS_BYTES + 64)
        encoder.copy_buffer_to_buffer(self.filter.counters, 0, staging, 0, COUNTERS_BYTES)
        if self.reduce is not None:
            self.reduce.encode(encoder, self.filter.out.buffer)
            lost_bytes = 4 * (self.reduce.levels + 1)
            encoder.copy_buffer_to_buffer(self.reduce.lost, 0, staging, COUNTERS_BYTES, lost_bytes)
            header += -(-lost_bytes // 8) * 8
        if self._profile:
            nq = self._n_queries
            encoder.resolve_query_set(self._queries, 0, nq, self._query_buf, 0)
            encoder.copy_buffer_to_buffer(self._query_buf, 0, self._query_readback.ensure(8 * nq),
                                          0, 8 * nq)
        device.queue.submit([encoder.finish()])
        counters = self._counters_readback.read(header)
        t1 = time.perf_counter()
        stats.bytes_read = header
        survivors, stats.self_interference_pixels, stats.unidentified_pixels = map(int, counters[:3])
        if self._profile:
            ts = self._query_readback.read(8 * self._n_queries, np.uint64).astype(np.float64)
            for i, name in enumerate(self._stage_names):
                stats.gpu_ms[name] = (ts[2 * i + 1] - ts[2 * i]) * 1e-6  # nanoseconds to ms
        width = self.targets.width
        if survivors == 0:
            # The early-out of paper 4.3.2.3: nothing survived, so nothing else is read back.
            records = np.zeros(0, RECORD_DTYPE)
        else:
            source, nbytes, packed = self._readback_source(counters, survivors, stats)
            encoder = device.create_command_encoder()
            encoder.copy_buffer_to_buffer(source, 0, self._records_readback.ensure(nbytes), 0,
                                          nbytes)
            device.queue.submit([encoder.finish()])
            data = self._records_readback.read(nbytes)
            stats.bytes_read += nbytes
            t_dec = time.perf_counter()
            if self.readback == "full":
                records = decode_image(data, width, k, self.encode, scene.edge_start)
            else:
                if packed:
                    rows = data.reshape(-1, 4)
                    data = rows[rows[:, 1] != 0]
                records = decode_compact(data, width, k, self.encode, scene.edge_start)
            stats.wall_ms["decode"] = (time.perf_counter() - t_dec) * 1e3
        t2 = time.perf_counter()
        stats.wall_ms["gpu"] = (t1 - t0) * 1e3
        stats.wall_ms["readback"] = (t2 - t1) * 1e3 - stats.wall_ms.get("decode", 0.0)
        return records, stats


def find_collisions(bodies: Sequence[Any], transforms: Any = None, *, resolution: int = 512,
                    view: View | Sequence[View] | None = None, **options: Any) -> CollisionResult:
    """Find every pair of interfering closed meshes with CInDeR.

    bodies : sequence of trimesh.Trimesh or (vertices (V, 3), faces (F, 3)) pairs
    transforms : None, or one (4, 4) world-from-body matrix per body
    resolution : width and height of the image the test runs in
    view : a :class:`View`, several, or None to fit an orthographic view around all bodies
    options : passed to :class:`Detector` (self_interference, readback, encode, strict, ...)

    Returns a :class:`CollisionResult`; ``result.pairs`` is (K, 2) int64 with i < j.
    For animation loops, keep a :class:`Detector` instead: it reuses pipelines and buffers.
    """
    return _shared_detector(resolution, tuple(sorted(options.items()))).find_collisions(
        bodies, transforms, view=view)


_DETECTORS: dict[tuple, Detector] = {}


def _shared_detector(resolution: int, options: tuple) -> Detector:
    key = (resolution, options)
    if key not in _DETECTORS:
        if len(_DETECTORS) >= 4:
            _DETECTORS.pop(next(iter(_DETECTORS)))
        _DETECTORS[key] = Detector(resolution, **dict(options))
    return _DETECTORS[key]

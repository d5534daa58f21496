"""The whole-scene strategy (``strategy="scene"``): the paper's CInDeR over one image of the
whole scene.

    scene -> pack body by body -> upload -> views (fitted, or the user's)
          -> per view: frame (passes 1-7, filter, readback mode's passes) -> records
          -> merge views -> pairs

Its pixel is the scene's extent divided by the resolution, and at most one edge is seen per pixel
(paper 4.3): kept for the paper's figures, ``debug-buffers`` and comparison. The focused strategy
is the default.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from ..errors import ClippedBodyWarning, warn_at_caller
from ..gpu.buffers import SceneBuffers, Targets
from ..gpu.device import Gpu, check_resolution
from ..records import empty_records, unique_pairs
from ..request import CollisionRequest
from ..result import CollisionResult, Stats
from ..scene import Scene
from ..scene.pack import PackedScene, repack
from ..strategy import Done, Query
from ..view import View, world_corners
from .filter import FilterPass
from .scene_frame import Hook, WholeSceneFrame
from .raycast import RaycastPasses
from .readback import READBACK_MODES
from .selfint import SELF_INTERFERENCE


class WholeSceneStrategy:
    """Runs queries through one image of the whole scene (or several views, merged).

    Parameters
    ----------
    gpu : Gpu
    request : CollisionRequest
    """

    REFUSED: ClassVar[dict[str, str]] = {
        "pairs": "pairs applies to strategy='focused': the scene strategy draws every body in "
                 "one image",
        "batch": "find_collisions_batch needs strategy='focused': the scene strategy draws one "
                 "image of everything",
        "scenes": "many scenes in one query need strategy='focused': the scene strategy draws "
                  "one image of everything",
    }
    """What the scene strategy cannot do (:attr:`pycinder.strategy.Strategy.REFUSED`)."""

    def __init__(self, gpu: Gpu, request: CollisionRequest) -> None:
        self.gpu = gpu
        self.request = request
        res = int(request.resolution)
        check_resolution(gpu, res, res)
        self.resolution = res
        self.selfint = SELF_INTERFERENCE[request.self_interference](request)
        self.readback = READBACK_MODES[request.readback](gpu, res, res, request)
        device = gpu.device
        self.targets = Targets(device, res, res, gpu.depth_format)
        self.raycast = RaycastPasses(gpu, self.selfint.table, self.selfint.plan)
        self.filter = FilterPass(gpu, self.readback.filter_output)
        self.buffers = SceneBuffers(device)
        self.frame = WholeSceneFrame(gpu, self.raycast, self.filter, self.readback, self.targets,
                                  self.buffers, profile=request.profile)

    def prepare(self, scene: Scene, view: View | Sequence[View] | None, stats: Stats
                ) -> tuple[PackedScene, list[View]]:
        """Pack and upload a scene; returns it and the views to render."""
        needs_normals = self.selfint.needs_normals or self.request.encode == "normal"
        packed = repack(self.buffers.scene, scene, needs_normals)
        self.buffers.upload(packed)
        stats.uploaded_vertex_bytes = self.buffers.uploaded_vertex_bytes
        return packed, self._views(view, scene)

    def set_view(self, view: View, scene: Scene) -> None:
        """Upload the per-body matrices and frame constants for rendering through ``view``."""
        transforms = scene.transforms
        clip = np.einsum("ij,njk->nik", view.clip_from_world, transforms)
        self.buffers.upload_transforms(clip, transforms)
        lo, hi = scene.world_boxes()
        centre = 0.5 * (lo.min(axis=0) + hi.max(axis=0))
        offset = self.selfint.edge_offset(view, self.resolution, centre)
        self.raycast.write_frame(offset, payload_normal=self.request.encode == "normal")

    def submit(self, scene: Scene, stats: Stats, query: Query) -> Done:
        """Runs the query whole (the query's ``view`` and ``groups`` apply; its records are
        this strategy's own, and a query that stops at its first pair runs whole too)."""
        result = self.run(scene, stats, query.view)
        return Done(result.across(query.groups) if query.groups is not None else result)

    def run(self, scene: Scene, stats: Stats, view: View | Sequence[View] | None = None,
            hook: Hook | None = None) -> CollisionResult:
        """The colliding pairs of a validated scene, seen through ``view`` (default: one fitted
        view); ``hook`` is called after each pass (the debug buffers')."""
        t0 = time.perf_counter()
        stats.resolution = (self.resolution, self.resolution)
        stats.readback = self.readback.name
        stats.self_interference = self.selfint.name
        if len(scene) == 0:
            return CollisionResult.empty(stats)
        packed, views = self.prepare(scene, view, stats)
        stats.views = len(views)
        stats.add_ms("prepare", (time.perf_counter() - t0) * 1e3)
        parts = []
        for k, v in enumerate(views):
            t1 = time.perf_counter()
            self.set_view(v, scene)
            header = self.frame.run(stats, hook)
            t2 = time.perf_counter()
            rec = self.frame.read_records(header, stats, k, self.request.encode, packed.edge_start)
            if rec is not None:
                rec["point"] = v.unproject(rec["pixel_x"], rec["pixel_y"], rec["pixel_z"],
                                           self.resolution, self.resolution)
                parts.append(rec)
            stats.add_ms("gpu", (t2 - t1) * 1e3)
            stats.add_ms("readback", (time.perf_counter() - t2) * 1e3)
        records = np.concatenate(parts) if parts else empty_records()
        stats.records = len(records)
        pairs = unique_pairs(records["penetrating"], records["penetrated"])
        return CollisionResult(pairs, records, stats, views=views, scene=scene)

    # -- views --------------------------------------------------------------------------------

    def _views(self, view: View | Sequence[View] | None, scene: Scene) -> list[View]:
        lo, hi = scene.local_lo, scene.local_hi
        if view is None:
            return [View.fit(world_corners(lo, hi, scene.transforms), resolution=self.resolution)]
        views = [view] if isinstance(view, View) else list(view)
        if not views or not all(isinstance(v, View) for v in views):
            raise TypeError("view must be a View, a non-empty sequence of Views, or None")
        for k, v in enumerate(views):
            self._check_depth_range(k, v, scene, lo, hi)
        return views

    def _check_depth_range(self, k: int, view: View, scene: Scene, lo: np.ndarray,
                           hi: np.ndarray) -> None:
        """Warn (raise when strict) when the near or far plane cuts a body: the ray count through
        a cut solid is wrong. Bounding boxes first; exact vertices only for suspects."""
        zmin, zmax = view.depth_range(lo, hi, scene.transforms)
        for i in np.flatnonzero((zmin < 0) | (zmax > 1)):
            shape, t = scene.shape_of(i), scene.transforms[i]
            z = view.project(shape.vertices @ t[:3, :3].T + t[:3, 3], 1, 1)[:, 2]
            if z.min() >= 0 and z.max() <= 1:
                continue
            plane = "near" if z.min() < 0 else "far"
            message = (f"{scene.label(i)} is cut by the {plane} plane of view {k}; the ray count "
                       "through a cut solid is wrong, so its collisions may be missed or "
                       "invented. Use View.fit_bodies or move the planes.")
            if self.request.strict:
                raise ValueError(message)
            warn_at_caller(message, ClippedBodyWarning)

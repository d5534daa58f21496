"""NVIDIA Warp as a benchmark peer: per-body ``wp.Mesh`` BVHs, refitted when bodies deform."""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np

from ..optional import require
from .peers import System, aabb_candidates, as_pairs, world_aabbs
from .scenes import Scene


@cache
def _collide_kernel() -> Any:
    """The Warp kernel, built on first use so that importing this module needs no Warp.

    One thread per (candidate pair p, triangle f of body A): the triangle is taken into B's
    body space by ``rel[p]`` (float64), its box is queried against B's BVH, and every candidate
    triangle of B goes through Warp's Möller triangle-triangle test in double precision.
    ``hit[p]`` is set on the first intersection; the pair's later threads return at once.
    """
    import warp as wp

    @wp.func
    def tri_tri(v0: wp.vec3d, v1: wp.vec3d, v2: wp.vec3d,
                u0: wp.vec3d, u1: wp.vec3d, u2: wp.vec3d) -> int:
        # Warp's Möller test zeroes plane distances below an absolute 1e-6, and those distances
        # scale with size cubed: small triangles then pass as touching. Rescale both to unit
        # size first (the answer is scale- and translation-invariant).
        lo = wp.min(wp.min(wp.min(v0, v1), wp.min(v2, u0)), wp.min(u1, u2))
        hi = wp.max(wp.max(wp.max(v0, v1), wp.max(v2, u0)), wp.max(u1, u2))
        d = hi - lo
        s = wp.float64(1.0) / wp.max(wp.max(wp.max(d[0], d[1]), d[2]), wp.float64(1e-300))
        return wp.intersect_tri_tri((v0 - lo) * s, (v1 - lo) * s, (v2 - lo) * s,
                                    (u0 - lo) * s, (u1 - lo) * s, (u2 - lo) * s)

    @wp.kernel
    def collide(meshes: wp.array(dtype=wp.uint64), body_a: wp.array(dtype=wp.int32),
                body_b: wp.array(dtype=wp.int32), rel: wp.array(dtype=wp.mat44d),
                start: wp.array(dtype=wp.int32), hit: wp.array(dtype=wp.int32)):
        item = wp.tid()
        p = wp.lower_bound(start, item + 1) - 1  # start[p] <= item < start[p + 1]
        if hit[p] != 0:
            return
        a = meshes[body_a[p]]
        b = meshes[body_b[p]]
        f = 3 * (item - start[p])
        m = rel[p]
        v0 = wp.transform_point(m, wp.vec3d(wp.mesh_get_point(a, f)))
        v1 = wp.transform_point(m, wp.vec3d(wp.mesh_get_point(a, f + 1)))
        v2 = wp.transform_point(m, wp.vec3d(wp.mesh_get_point(a, f + 2)))
        lo = wp.vec3(wp.min(wp.min(v0, v1), v2))
        hi = wp.vec3(wp.max(wp.max(v0, v1), v2))
        query = wp.mesh_query_aabb(b, lo, hi)
        g = int(0)
        while wp.mesh_query_aabb_next(query, g):
            u0 = wp.vec3d(wp.mesh_get_point(b, 3 * g))
            u1 = wp.vec3d(wp.mesh_get_point(b, 3 * g + 1))
            u2 = wp.vec3d(wp.mesh_get_point(b, 3 * g + 2))
            if tri_tri(v0, v1, v2, u0, u1, u2) != 0:
                hit[p] = 1
                return

    return collide


class Warp(System):
    """Triangle-versus-BVH tests in one Warp kernel launch per frame.

    Every body has a ``wp.Mesh`` in body space, built in :meth:`prepare`. Deforming scenes
    copy each frame's vertices into the mesh points in place and call ``Mesh.refit()``; rigid
    scenes never touch the meshes and only pass transforms, which is cheaper than moving the
    points and refitting. Candidate body pairs come from a NumPy sweep over world AABBs; all
    candidates of a frame go to one launch over (pair, triangle of A) items, A being the body of
    the pair with fewer triangles and its triangles mapped into B's body space by
    ``inv(T_B) @ T_A`` in float64.

    Like python-fcl this tests surfaces only: a body wholly inside another, with no surfaces
    crossing, is not reported.

    Parameters
    ----------
    device : str, optional
        Warp device; ``"cuda"`` when Warp sees a CUDA device, else ``"cpu"``.
    """

    name = "warp"

    def __init__(self, device: str | None = None) -> None:
        wp = require("warp", "the Warp peer", "bench", "warp-lang")
        wp.config.quiet = True  # older Warp; newer Warp reads log_level
        wp.config.log_level = getattr(wp, "LOG_WARNING", 30)
        wp.init()
        self.wp = wp
        self.device = device or ("cuda" if wp.get_cuda_device_count() > 0 else "cpu")
        self.kernel = _collide_kernel()

    def prepare(self, scene: Scene) -> None:
        """Build one body-space ``wp.Mesh`` per body from frame 0 and compile the kernel.

        Parameters
        ----------
        scene : Scene
            The scene whose frames :meth:`step` will be given.
        """
        wp = self.wp
        verts, _ = scene.frame(0)
        self.meshes = [
            wp.Mesh(points=wp.array(np.asarray(v, np.float32), dtype=wp.vec3, device=self.device),
                    indices=wp.array(np.asarray(f, np.int32).ravel(), dtype=wp.int32,
                                     device=self.device))
            for v, f in zip(verts, scene.faces)]
        self.ids = wp.array(np.array([m.id for m in self.meshes], np.uint64), dtype=wp.uint64,
                            device=self.device)
        self.counts = np.array([len(f) for f in scene.faces], np.int64)
        wp.load_module(self.kernel.module, device=self.device)  # compile here, not in step

    def step(self, scene: Scene, k: int) -> np.ndarray:
        """Colliding pairs (K, 2) int64 of frame k, refitting first if the scene deforms.

        Parameters
        ----------
        scene : Scene
            The scene given to :meth:`prepare`.
        k : int
            Frame index.

        Returns
        -------
        numpy.ndarray
            (K, 2) int64 pairs ``i < j``, sorted.
        """
        wp = self.wp
        verts, transforms = scene.frame(k)
        if scene.deforming:
            for mesh, v in zip(self.meshes, verts):
                mesh.points.assign(np.asarray(v, np.float32))
                mesh.refit()
        pairs = aabb_candidates(*world_aabbs(verts, transforms))
        if len(pairs) == 0:
            return as_pairs(set())
        # A: the side with fewer triangles (ties: the lower index), one thread per triangle.
        swap = self.counts[pairs[:, 0]] > self.counts[pairs[:, 1]]
        a = np.where(swap, pairs[:, 1], pairs[:, 0])
        b = np.where(swap, pairs[:, 0], pairs[:, 1])
        t = np.asarray(transforms, np.float64)
        rel = np.linalg.inv(t[b]) @ t[a]
        start = np.concatenate([[0], np.cumsum(self.counts[a])]).astype(np.int32)
        hit = wp.zeros(len(pairs), dtype=wp.int32, device=self.device)
        wp.launch(self.kernel, dim=int(start[-1]), device=self.device, inputs=[
            self.ids,
            wp.array(a.astype(np.int32), dtype=wp.int32, device=self.device),
            wp.array(b.astype(np.int32), dtype=wp.int32, device=self.device),
            wp.array(rel, dtype=wp.mat44d, device=self.device),
            wp.array(start, dtype=wp.int32, device=self.device),
            hit])
        return as_pairs({(i, j) for i, j in pairs[hit.numpy() != 0].tolist()})

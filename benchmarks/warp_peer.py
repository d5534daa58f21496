"""NVIDIA Warp as a benchmark peer, at its best: every frame runs on the Warp device.

Per frame, the host uploads one (N, 4, 4) float64 array of transforms (and, for deforming
scenes, one array of all vertices, followed by a ``Mesh.refit()`` per body); then a fixed
sequence of kernels, captured once as a graph and replayed, does the rest on the device:

1. world boxes: each body's body-space box, mapped by its transform (``|R| @ half-extent``),
   intersected with the box of its transformed bounding sphere (tight for round bodies);
   deforming scenes first recompute the body-space boxes from the vertices;
2. candidate pairs: a sort-and-sweep (radix sort of the boxes' minima along the axis where the
   centres spread most, then one thread per box walking forward while the boxes overlap on that
   axis), appended to a fixed-capacity pair list through an atomic counter;
3. narrow phase: one work item per (candidate pair, triangle of its body with fewer triangles),
   the triangle mapped into the other body's space by ``inv(T_B) @ T_A`` in float64 and tested
   against that body's BVH (no refit for rigid motion) with a rescaled double-precision Möller
   test;
4. compaction of the colliding pairs through a second atomic counter.

The host then waits once and reads back the counters and the colliding pairs. Nothing runs per
body or per pair in Python, and no array is allocated per frame (the pair list grows, and the
graph is captured again, only when a frame has more candidates than it holds).

Sort-and-sweep is the default broad phase, chosen by measurement on Warp's CPU device: on the
benchmark's scenes it is faster than the all-pairs kernel, whose N^2 / 2 checks grow fastest
(kept as ``Warp(broadphase="all-pairs")`` to compare).
"""

# No "from __future__ import annotations": Warp reads the kernels' annotations, which name
# the ``wp`` local to _kernels().
from functools import cache
from types import SimpleNamespace
from typing import Any

import numpy as np

from pycinder.testing.scenes import Scene
from pycinder.util.optional import require

from .system import System

BROADPHASES = ("sweep", "all-pairs")
MIN_CAPACITY = 1024
"""Fewest candidate pairs the pair list holds; it is sized at twice the first frame's count."""
RADIUS_PAD = 1.0 + 1e-6
"""Bounding-sphere radii, computed in float32, are padded by this factor to stay conservative."""


@cache
def _kernels() -> SimpleNamespace:
    """The Warp kernels, built on first use so that importing this module needs no Warp."""
    import warp as wp

    wp.set_module_options({"enable_backward": False})

    @wp.kernel
    def body_boxes(points: wp.array(dtype=wp.vec3), owner: wp.array(dtype=wp.int32),
                   lo: wp.array(dtype=wp.vec3), hi: wp.array(dtype=wp.vec3)):
        """Body-space boxes from the vertices (lo, hi start at +inf, -inf)."""
        v = wp.tid()
        wp.atomic_min(lo, owner[v], points[v])
        wp.atomic_max(hi, owner[v], points[v])

    @wp.kernel
    def body_radii(points: wp.array(dtype=wp.vec3), owner: wp.array(dtype=wp.int32),
                   lo: wp.array(dtype=wp.vec3), hi: wp.array(dtype=wp.vec3),
                   radius: wp.array(dtype=wp.float32)):
        """Bounding-sphere radius about each box's centre (radius starts at 0)."""
        v = wp.tid()
        b = owner[v]
        wp.atomic_max(radius, b, wp.length(points[v] - 0.5 * (lo[b] + hi[b])))

    @wp.kernel
    def world_boxes(transforms: wp.array(dtype=wp.mat44d), lo: wp.array(dtype=wp.vec3),
                    hi: wp.array(dtype=wp.vec3), radius: wp.array(dtype=wp.float32),
                    world_lo: wp.array(dtype=wp.vec3d), world_hi: wp.array(dtype=wp.vec3d),
                    spread: wp.array(dtype=wp.vec3d)):
        """World box of body i, and the sums of its centre and squared centre (for the axis)."""
        i = wp.tid()
        m = transforms[i]
        l = wp.vec3d(lo[i])
        h = wp.vec3d(hi[i])
        e = wp.float64(0.5) * (h - l)
        c = wp.transform_point(m, wp.float64(0.5) * (l + h))
        r = wp.float64(radius[i]) * wp.float64(RADIUS_PAD)
        half = wp.vec3d()
        for k in range(3):
            box = wp.abs(m[k, 0]) * e[0] + wp.abs(m[k, 1]) * e[1] + wp.abs(m[k, 2]) * e[2]
            ball = r * wp.sqrt(m[k, 0] * m[k, 0] + m[k, 1] * m[k, 1] + m[k, 2] * m[k, 2])
            half[k] = wp.min(box, ball)
        world_lo[i] = c - half
        world_hi[i] = c + half
        wp.atomic_add(spread, 0, c)
        wp.atomic_add(spread, 1, wp.cw_mul(c, c))

    @wp.func
    def sweep_axis(spread: wp.array(dtype=wp.vec3d), n: int) -> int:
        """The axis along which the box centres spread most (n times their variance)."""
        s = spread[0]
        var = spread[1] - wp.cw_div(wp.cw_mul(s, s), wp.vec3d(wp.float64(n)))
        axis = int(0)
        if var[1] > var[axis]:
            axis = 1
        if var[2] > var[axis]:
            axis = 2
        return axis

    @wp.func
    def overlap(lo_i: wp.vec3d, hi_i: wp.vec3d, lo_j: wp.vec3d, hi_j: wp.vec3d) -> bool:
        """Whether two boxes overlap (touching counts)."""
        return (lo_i[0] <= hi_j[0] and lo_j[0] <= hi_i[0] and lo_i[1] <= hi_j[1]
                and lo_j[1] <= hi_i[1] and lo_i[2] <= hi_j[2] and lo_j[2] <= hi_i[2])

    @wp.func
    def emit(i: int, j: int, counts: wp.array(dtype=wp.int32),
             pairs: wp.array(dtype=wp.vec2i)):
        """Append (min, max) to the pair list; past its capacity only the count grows."""
        k = wp.atomic_add(counts, 0, 1)
        if k < pairs.shape[0]:
            pairs[k] = wp.vec2i(wp.min(i, j), wp.max(i, j))

    @wp.kernel
    def sweep_keys(world_lo: wp.array(dtype=wp.vec3d), spread: wp.array(dtype=wp.vec3d),
                   n: int, keys: wp.array(dtype=wp.float64), order: wp.array(dtype=wp.int32)):
        i = wp.tid()
        keys[i] = world_lo[i][sweep_axis(spread, n)]
        order[i] = i

    @wp.kernel
    def sweep(keys: wp.array(dtype=wp.float64), order: wp.array(dtype=wp.int32),
              world_lo: wp.array(dtype=wp.vec3d), world_hi: wp.array(dtype=wp.vec3d),
              spread: wp.array(dtype=wp.vec3d), n: int, counts: wp.array(dtype=wp.int32),
              pairs: wp.array(dtype=wp.vec2i)):
        """Box at sorted position s against the boxes after it that start before it ends."""
        s = wp.tid()
        i = order[s]
        lo_i = world_lo[i]
        hi_i = world_hi[i]
        end = hi_i[sweep_axis(spread, n)]
        t = s + 1
        while t < n:
            if keys[t] > end:
                break
            j = order[t]
            if overlap(lo_i, hi_i, world_lo[j], world_hi[j]):
                emit(i, j, counts, pairs)
            t += 1

    @wp.kernel
    def all_pairs(world_lo: wp.array(dtype=wp.vec3d), world_hi: wp.array(dtype=wp.vec3d),
                  counts: wp.array(dtype=wp.int32), pairs: wp.array(dtype=wp.vec2i)):
        i, j = wp.tid()
        if i < j and overlap(world_lo[i], world_hi[i], world_lo[j], world_hi[j]):
            emit(i, j, counts, pairs)

    @wp.kernel
    def orient(pairs: wp.array(dtype=wp.vec2i), counts: wp.array(dtype=wp.int32),
               triangles: wp.array(dtype=wp.int32), transforms: wp.array(dtype=wp.mat44d),
               body_a: wp.array(dtype=wp.int32), body_b: wp.array(dtype=wp.int32),
               rel: wp.array(dtype=wp.mat44d), items: wp.array(dtype=wp.int32)):
        """A: the side with fewer triangles (ties: the lower index); rel maps A into B's space."""
        p = wp.tid()
        if p >= wp.min(counts[0], pairs.shape[0]):
            items[p] = 0
            return
        a = pairs[p][0]
        b = pairs[p][1]
        if triangles[a] > triangles[b]:
            a = pairs[p][1]
            b = pairs[p][0]
        body_a[p] = a
        body_b[p] = b
        rel[p] = wp.inverse(transforms[b]) @ transforms[a]
        items[p] = triangles[a]

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

    @wp.func
    def triangle_hits(a: wp.uint64, f: int, m: wp.mat44d, b: wp.uint64) -> int:
        """Whether triangle f of mesh a, mapped by m, crosses a triangle of mesh b."""
        v0 = wp.transform_point(m, wp.vec3d(wp.mesh_get_point(a, 3 * f)))
        v1 = wp.transform_point(m, wp.vec3d(wp.mesh_get_point(a, 3 * f + 1)))
        v2 = wp.transform_point(m, wp.vec3d(wp.mesh_get_point(a, 3 * f + 2)))
        query = wp.mesh_query_aabb(b, wp.vec3(wp.min(wp.min(v0, v1), v2)),
                                   wp.vec3(wp.max(wp.max(v0, v1), v2)))
        g = int(0)
        while wp.mesh_query_aabb_next(query, g):
            if tri_tri(v0, v1, v2, wp.vec3d(wp.mesh_get_point(b, 3 * g)),
                       wp.vec3d(wp.mesh_get_point(b, 3 * g + 1)),
                       wp.vec3d(wp.mesh_get_point(b, 3 * g + 2))) != 0:
                return 1
        return 0

    @wp.kernel
    def collide(meshes: wp.array(dtype=wp.uint64), body_a: wp.array(dtype=wp.int32),
                body_b: wp.array(dtype=wp.int32), rel: wp.array(dtype=wp.mat44d),
                ends: wp.array(dtype=wp.int32), counts: wp.array(dtype=wp.int32),
                stride: int, hit: wp.array(dtype=wp.int32)):
        """Work items (pair p, triangle of A), ``ends`` the inclusive scan of their counts per
        pair; a fixed number of threads stride over them. A pair's items stop once it hits."""
        n = wp.min(counts[0], ends.shape[0])
        if n == 0:
            return
        total = ends[n - 1]
        item = wp.tid()
        while item < total:
            p = wp.lower_bound(ends, 0, n, item + 1)  # ends[p - 1] <= item < ends[p]
            if hit[p] == 0:
                first = int(0)
                if p > 0:
                    first = ends[p - 1]
                if triangle_hits(meshes[body_a[p]], item - first, rel[p],
                                 meshes[body_b[p]]) != 0:
                    hit[p] = 1
            item += stride

    @wp.kernel
    def compact(pairs: wp.array(dtype=wp.vec2i), hit: wp.array(dtype=wp.int32),
                counts: wp.array(dtype=wp.int32), found: wp.array(dtype=wp.vec2i)):
        p = wp.tid()
        if p < wp.min(counts[0], pairs.shape[0]) and hit[p] != 0:
            found[wp.atomic_add(counts, 1, 1)] = pairs[p]

    return SimpleNamespace(**{k: v for k, v in locals().items() if isinstance(v, wp.Kernel)})


class Warp(System):
    """Broad and narrow phase in Warp kernels, replayed as one captured graph per frame.

    Every body has a ``wp.Mesh`` in body space, built in :meth:`prepare` on a slice of one
    array of all vertices. Rigid scenes never touch the meshes: B's BVH is queried in B's body
    space. Deforming scenes upload all vertices as one array each frame and refit every mesh.

    Like python-fcl this tests surfaces only: a body wholly inside another, with no surfaces
    crossing, is not reported.

    Parameters
    ----------
    device : str, optional
        Warp device; ``"cuda"`` when Warp sees a CUDA device, else ``"cpu"``.
    broadphase : {"sweep", "all-pairs"}
        Sort-and-sweep (default), or one thread per pair of bodies.
    graph : bool
        Capture each frame's kernels once and replay them (default); else launch them one by
        one every frame.
    """

    name = "warp"

    def __init__(self, device: str | None = None, broadphase: str = "sweep",
                 graph: bool = True) -> None:
        if broadphase not in BROADPHASES:
            raise ValueError(f"broadphase must be one of {BROADPHASES}, not {broadphase!r}")
        wp = require("warp", "the Warp peer", "bench", "warp-lang")
        wp.config.quiet = True  # older Warp; newer Warp reads log_level
        wp.config.log_level = getattr(wp, "LOG_WARNING", 30)
        wp.init()
        self.wp = wp
        self.device = wp.get_device(device or ("cuda" if wp.get_cuda_device_count() > 0
                                               else "cpu"))
        self.broadphase = broadphase
        self.graph_mode = graph
        self.k = _kernels()

    # ----------------------------------------------------------------------------------------
    # set-up

    def _empty(self, shape: Any, dtype: Any) -> Any:
        return self.wp.empty(shape, dtype=dtype, device=self.device)

    def _host(self, array: Any) -> Any:
        """Where the host reads or writes ``array``: the array itself on the CPU device, else
        pinned host memory of its shape, copied to or from it."""
        if self.device.is_cpu:
            return array
        return self.wp.empty(array.shape, dtype=array.dtype, device="cpu", pinned=True)

    def prepare(self, scene: Scene) -> None:
        """Build the meshes, body boxes and every per-frame array, compile the kernels, and size
        the pair list on frame 0.

        Parameters
        ----------
        scene : Scene
            The scene whose frames :meth:`step` will be given.
        """
        wp = self.wp
        n = self.n = len(scene.faces)
        if n < 2:
            return  # no pairs: step answers at once
        verts, _ = scene.frame(0)
        sizes = np.array([len(v) for v in verts], np.int64)
        self.deforming = scene.deforming
        self.points = wp.array(np.concatenate(verts).astype(np.float32), dtype=wp.vec3,
                               device=self.device)
        self.points_host = self._host(self.points)
        offsets = np.concatenate([[0], np.cumsum(sizes)])
        self.meshes = [
            wp.Mesh(points=self.points[offsets[b]:offsets[b + 1]],
                    indices=wp.array(np.asarray(f, np.int32).ravel(), dtype=wp.int32,
                                     device=self.device))
            for b, f in enumerate(scene.faces)]
        self.ids = wp.array(np.array([m.id for m in self.meshes], np.uint64), dtype=wp.uint64,
                            device=self.device)
        self.triangles = wp.array(np.array([len(f) for f in scene.faces], np.int32),
                                  dtype=wp.int32, device=self.device)
        self.owner = wp.array(np.repeat(np.arange(n, dtype=np.int32), sizes), dtype=wp.int32,
                              device=self.device)
        self.box_lo = self._empty(n, wp.vec3)
        self.box_hi = self._empty(n, wp.vec3)
        self.radius = self._empty(n, wp.float32)
        self.transforms = self._empty(n, wp.mat44d)
        self.transforms_host = self._host(self.transforms)
        self.world_lo = self._empty(n, wp.vec3d)
        self.world_hi = self._empty(n, wp.vec3d)
        self.spread = self._empty(2, wp.vec3d)
        self.keys = self._empty(2 * n, wp.float64)
        self.order = self._empty(2 * n, wp.int32)
        self.counts = self._empty(2, wp.int32)  # candidate pairs, colliding pairs
        self.counts_host = self._host(self.counts)
        # Threads of the narrow phase: the CPU device runs threads one after another, so one
        # thread walks the items in order; on a GPU, enough to fill every multiprocessor.
        self.stride = 1 if self.device.is_cpu else 2048 * self.device.sm_count
        for kernel in vars(self.k).values():
            wp.load_module(kernel.module, device=self.device)  # compile here, not in step
        self._body_boxes()  # rigid bodies: once
        self._allocate(MIN_CAPACITY)
        wanted = self._frame(scene, 0)[0]
        if wanted > self.capacity // 2:
            self._allocate(2 * wanted)

    def _allocate(self, capacity: int) -> None:
        """(Re)make the per-candidate arrays for ``capacity`` pairs; drop the captured graph."""
        self.capacity = capacity
        e = self._empty
        wp = self.wp
        self.pairs = e(capacity, wp.vec2i)
        self.body_a = e(capacity, wp.int32)
        self.body_b = e(capacity, wp.int32)
        self.rel = e(capacity, wp.mat44d)
        self.items = e(capacity, wp.int32)
        self.ends = e(capacity, wp.int32)
        self.hit = e(capacity, wp.int32)
        self.found = e(capacity, wp.vec2i)
        self.found_host = self._host(self.found)
        self.graph = None

    def _body_boxes(self) -> None:
        """Body-space boxes and bounding-sphere radii from the current vertices."""
        wp, k = self.wp, self.k
        self.box_lo.fill_(wp.vec3(np.inf))
        self.box_hi.fill_(wp.vec3(-np.inf))
        self.radius.zero_()
        args = dict(dim=len(self.points), device=self.device)
        wp.launch(k.body_boxes, inputs=[self.points, self.owner, self.box_lo, self.box_hi],
                  **args)
        wp.launch(k.body_radii, inputs=[self.points, self.owner, self.box_lo, self.box_hi,
                                        self.radius], **args)

    # ----------------------------------------------------------------------------------------
    # per frame

    def _upload(self, scene: Scene, k: int) -> None:
        """One copy of the transforms (and of all vertices, refitting, when deforming)."""
        wp = self.wp
        verts, transforms = scene.frame(k)
        self.transforms_host.numpy()[:] = transforms
        if self.transforms_host is not self.transforms:
            wp.copy(self.transforms, self.transforms_host)
        if self.deforming:
            np.concatenate(verts, out=self.points_host.numpy(), casting="same_kind")
            if self.points_host is not self.points:
                wp.copy(self.points, self.points_host)
            for mesh in self.meshes:
                mesh.refit()

    def _launches(self) -> None:
        """Every kernel of a frame after the upload, in order."""
        if self.deforming:
            self._body_boxes()
        self._broad_phase()
        self._narrow_phase()

    def _broad_phase(self) -> None:
        """World boxes, then candidate pairs into ``pairs`` and their count into counts[0]."""
        wp, k, n, dev = self.wp, self.k, self.n, self.device
        self.spread.zero_()
        self.counts.zero_()
        wp.launch(k.world_boxes, dim=n, device=dev, inputs=[
            self.transforms, self.box_lo, self.box_hi, self.radius, self.world_lo, self.world_hi,
            self.spread])
        if self.broadphase == "sweep":
            wp.launch(k.sweep_keys, dim=n, device=dev,
                      inputs=[self.world_lo, self.spread, n, self.keys, self.order])
            wp.utils.radix_sort_pairs(self.keys, self.order, n)
            wp.launch(k.sweep, dim=n, device=dev, inputs=[
                self.keys, self.order, self.world_lo, self.world_hi, self.spread, n, self.counts,
                self.pairs])
        else:
            wp.launch(k.all_pairs, dim=(n, n), device=dev,
                      inputs=[self.world_lo, self.world_hi, self.counts, self.pairs])

    def _narrow_phase(self) -> None:
        """Candidates tested triangle by triangle, colliding ones compacted into ``found``
        and counted in counts[1]; both copied for the host to read."""
        wp, k, dev = self.wp, self.k, self.device
        self.hit.zero_()
        wp.launch(k.orient, dim=self.capacity, device=dev, inputs=[
            self.pairs, self.counts, self.triangles, self.transforms, self.body_a, self.body_b,
            self.rel, self.items])
        wp.utils.array_scan(self.items, self.ends, inclusive=True)
        wp.launch(k.collide, dim=self.stride, device=dev, inputs=[
            self.ids, self.body_a, self.body_b, self.rel, self.ends, self.counts, self.stride,
            self.hit])
        wp.launch(k.compact, dim=self.capacity, device=dev,
                  inputs=[self.pairs, self.hit, self.counts, self.found])
        if self.counts_host is not self.counts:
            wp.copy(self.counts_host, self.counts)
            wp.copy(self.found_host, self.found)

    def _run(self) -> None:
        """This frame's kernels: the captured graph, captured on first use."""
        wp = self.wp
        if not self.graph_mode:
            self._launches()
            return
        if self.graph is None:
            wp.capture_begin(device=self.device, force_module_load=False)
            try:
                self._launches()
            finally:
                self.graph = wp.capture_end(device=self.device)
        wp.capture_launch(self.graph)

    def _frame(self, scene: Scene, k: int) -> tuple[int, int]:
        """Run frame k; the counts of candidate and colliding pairs, after the frame's one
        wait for the device."""
        self._upload(scene, k)
        self._run()
        if not self.device.is_cpu:
            self.wp.synchronize_device(self.device)
        candidates, colliding = self.counts_host.numpy().tolist()
        return candidates, colliding

    def step(self, scene: Scene, k: int) -> np.ndarray:
        """Colliding pairs (K, 2) int64 of frame k.

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
        if self.n < 2:
            return np.zeros((0, 2), np.int64)
        candidates, colliding = self._frame(scene, k)
        if candidates > self.capacity:  # rare: grow the pair list and run the frame again
            self._allocate(2 * candidates)
            return self.step(scene, k)
        found = self.found_host.numpy()[:colliding].astype(np.int64)
        return found[np.lexsort((found[:, 1], found[:, 0]))]

    def candidates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The last frame's world boxes (lo, hi: (N, 3) float64) and candidate pairs (K, 2)
        int64 ``i < j``, sorted, read back from the device (for checks, not timed)."""
        count = min(int(self.counts.numpy()[0]), self.capacity)
        pairs = self.pairs.numpy()[:count].astype(np.int64)
        return (self.world_lo.numpy().astype(np.float64), self.world_hi.numpy().astype(np.float64),
                pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))])

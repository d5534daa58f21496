"""Scenes and exact ground truth, shared by the tests, the demos and the benchmarks.

Truth is computed from the meshes themselves, never from pycinder's output, in the terms of the
tolerance contract (see :mod:`pycinder.request`), for a tolerance ``t`` per pair:

* a pair is **separate** when its meshes do not overlap (manifold3d intersection volume) and their
  exact distance is at least ``t`` (manifold3d ``min_gap``): it must never be reported;
* a pair **must be reported** when some point of one body's surface lies inside the other at a
  distance of at least ``2 t`` from its surface (trimesh signed distances at the vertices and at
  evenly sampled surface points). Then moving either body by ``2 t`` in any direction keeps that
  point inside, so the pair's penetration is at least ``2 t``: a sufficient test, so the few
  pairs whose depth it cannot prove are left unscored rather than guessed;
* every other pair is **ambiguous**: closer than ``t``, or overlapping by less than ``2 t``
  somewhere the samples can show, and not scored.

Needs the ``test`` extra (``pip install pycinder[test]``) for manifold3d and rtree.

The modules of the package hold larger scenes, each with its truth:

* :mod:`pycinder.testing.scenes`: the benchmarks' scenes, sequences of frames of the same bodies
  (:class:`~pycinder.testing.scenes.ManyBodies`, :class:`~pycinder.testing.scenes.Stairs`, ...);
* :mod:`pycinder.testing.robots`: pybullet_data's robots in their environments, python-fcl's
  answers for them and exact scoring;
* :mod:`pycinder.testing.buildings`: a generated IFC building with the exact distance and depth
  of every close pair, and :mod:`pycinder.testing.buildingscore`, answers scored against it;
* :mod:`pycinder.testing.realtruth`: exact truth on the pairs of real IFC models.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from ..tolerance import body_sizes, default_pair_tolerances
from ..util.optional import require

SURFACE_SAMPLES = 1500
"""Evenly spaced surface points per body (besides its vertices) for the depth test."""


def _manifold3d() -> Any:
    return require("manifold3d", "exact ground truth", "test")


def world_mesh(mesh: Any, transform: np.ndarray | None) -> trimesh.Trimesh:
    """A trimesh copy of ``mesh`` (a Trimesh or a (vertices, faces) pair) in world coordinates."""
    if isinstance(mesh, trimesh.Trimesh):
        m = mesh.copy()
    else:
        m = trimesh.Trimesh(np.asarray(mesh[0], np.float64), np.asarray(mesh[1]), process=False)
    if transform is not None:
        m.apply_transform(np.asarray(transform, dtype=np.float64))
    return m


def _manifold(mesh: trimesh.Trimesh) -> Any:
    m3d = _manifold3d()
    return m3d.Manifold(m3d.Mesh(vert_properties=np.asarray(mesh.vertices, np.float32),
                                 tri_verts=np.asarray(mesh.faces, np.uint32)))


def mesh_pair_tolerances(meshes: list, transforms: list | np.ndarray | None,
                         pairs: np.ndarray, tolerance: float | None) -> np.ndarray:
    """(K,) tolerance of each pair ((K, 2) body indices): ``tolerance``, or the documented
    default (:func:`pycinder.tolerance.default_pair_tolerances`: 1% of the smaller body's
    bounding-box diagonal in world units), from the meshes' own vertices and ``transforms`` (what
    :func:`pycinder.tolerance.pair_tolerances` gives for a prepared scene, from meshes as
    they are)."""
    vertices = [np.asarray(m.vertices if hasattr(m, "vertices") else m[0], np.float64)
                for m in meshes]
    lo = np.array([v.min(axis=0) for v in vertices]).reshape(-1, 3)
    hi = np.array([v.max(axis=0) for v in vertices]).reshape(-1, 3)
    world = np.broadcast_to(np.eye(4), (len(meshes), 4, 4)) if transforms is None \
        else np.asarray(transforms, np.float64).reshape(-1, 4, 4)
    sizes = body_sizes(lo, hi, world)
    return default_pair_tolerances(sizes[pairs[:, 0]], sizes[pairs[:, 1]], tolerance)


@dataclass
class Truth:
    """Ground truth of a scene.

    overlap : (K, 2) int64 pairs that must be reported (penetration of at least 2 tolerances)
    separate : (M, 2) int64 pairs at least one tolerance apart: never to be reported
    ambiguous : (L, 2) int64 pairs in between, not scored
    """

    overlap: np.ndarray
    separate: np.ndarray
    ambiguous: np.ndarray

    def score(self, found: np.ndarray) -> dict[str, Any]:
        """Recall on pairs that must be reported, and separate pairs reported, for ``found``."""
        found_set = {tuple(p) for p in np.asarray(found).reshape(-1, 2).tolist()}
        overlap = {tuple(p) for p in self.overlap.tolist()}
        separate = {tuple(p) for p in self.separate.tolist()}
        missed = sorted(overlap - found_set)
        false = sorted(found_set & separate)
        return {
            "overlaps": len(overlap),
            "found": len(overlap) - len(missed),
            "recall": 1.0 if not overlap else (len(overlap) - len(missed)) / len(overlap),
            "missed": missed,
            "false": false,
        }


class _Body:
    """A world mesh with its manifold and surface samples, built when first needed."""

    def __init__(self, mesh: trimesh.Trimesh, seed: int) -> None:
        self.mesh = mesh
        self.seed = seed
        self._solid = None
        self._points = None

    @property
    def solid(self) -> Any:
        if self._solid is None:
            self._solid = _manifold(self.mesh)
        return self._solid

    @property
    def points(self) -> np.ndarray:
        if self._points is None:
            samples = trimesh.sample.sample_surface_even(self.mesh, SURFACE_SAMPLES,
                                                         seed=self.seed)[0]
            self._points = np.vstack([self.mesh.vertices, samples])
        return self._points


def _deep(a: _Body, b: _Body, depth: float, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether some surface sample of ``b`` lies inside ``a`` at least ``depth`` from its surface.

    ``lo, hi``: the box of the bodies' intersection, where any such point lies."""
    a_lo, a_hi = a.mesh.bounds
    pts = b.points
    pts = pts[((pts >= np.maximum(lo, a_lo + depth)) & (pts <= np.minimum(hi, a_hi - depth)))
              .all(axis=1)]
    if len(pts) == 0:
        return False
    # Deep points tend to lie near the middle of the intersection: test those first, in batches,
    # and stop at the first one found.
    middle = 0.5 * (np.maximum(lo, a_lo) + np.minimum(hi, a_hi))
    pts = pts[np.argsort(np.linalg.norm(pts - middle, axis=1))]
    for start in range(0, len(pts), 256):
        if (trimesh.proximity.signed_distance(a.mesh, pts[start:start + 256]) >= depth).any():
            return True
    return False


def ground_truth(meshes: list, transforms: list | np.ndarray | None = None,
                 tolerance: float | None = None) -> Truth:
    """Classify every pair of a scene (see the module's doc).

    Parameters
    ----------
    meshes : list of trimesh.Trimesh or (vertices, faces) pairs
    transforms : list of (4, 4) float, optional
    tolerance : float, optional
        World units; default: the per-pair relative tolerance pycinder documents.
    """
    bodies = [_Body(world_mesh(m, None if transforms is None else transforms[i]), i)
              for i, m in enumerate(meshes)]
    n = len(bodies)
    iu, ju = np.triu_indices(n, 1)
    pairs = np.stack([iu, ju], axis=1).astype(np.int64)
    tol = mesh_pair_tolerances(meshes, transforms, pairs, tolerance)
    lo = np.array([b.mesh.bounds[0] for b in bodies]).reshape(-1, 3)
    hi = np.array([b.mesh.bounds[1] for b in bodies]).reshape(-1, 3)
    near = ((lo[iu] <= hi[ju] + tol[:, None]) & (lo[ju] <= hi[iu] + tol[:, None])).all(axis=1)
    classes = np.zeros(len(pairs), dtype=np.int8)  # 0 separate, 1 must, 2 ambiguous
    for k in np.flatnonzero(near):
        a, b, t = bodies[pairs[k, 0]], bodies[pairs[k, 1]], tol[k]
        both = a.solid ^ b.solid
        if both.volume() > 0.0:
            box = np.asarray(both.bounding_box(), dtype=np.float64)
            lo_i, hi_i = box[:3], box[3:]
            classes[k] = 1 if (_deep(a, b, 2 * t, lo_i, hi_i) or _deep(b, a, 2 * t, lo_i, hi_i)) \
                else 2
        elif a.solid.min_gap(b.solid, 2 * t) < t:
            classes[k] = 2
    return Truth(pairs[classes == 1], pairs[classes == 0], pairs[classes == 2])


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return trimesh.transformations.quaternion_matrix(q / np.linalg.norm(q))


SHAPES = ("box", "icosphere", "cylinder", "torus", "capsule", "cone")


def make_shape(kind: str, size: float, rng: np.random.Generator) -> trimesh.Trimesh:
    """A closed primitive of roughly ``size`` across."""
    s = size
    if kind == "box":
        return trimesh.creation.box(rng.uniform(0.4, 1.0, 3) * s)
    if kind == "icosphere":
        return trimesh.creation.icosphere(subdivisions=2, radius=0.5 * s)
    if kind == "cylinder":
        return trimesh.creation.cylinder(radius=0.3 * s, height=s, sections=24)
    if kind == "torus":
        return trimesh.creation.torus(major_radius=0.35 * s, minor_radius=0.12 * s,
                                      major_sections=24, minor_sections=12)
    if kind == "capsule":
        return trimesh.creation.capsule(height=0.6 * s, radius=0.22 * s, count=[12, 12])
    if kind == "cone":
        return trimesh.creation.cone(radius=0.4 * s, height=s, sections=24)
    raise ValueError(kind)


def random_scene(n: int, seed: int, *, density: float = 0.35, size: float = 1.0,
                 shapes: tuple[str, ...] = SHAPES) -> tuple[list[trimesh.Trimesh], list[np.ndarray]]:
    """``n`` random primitives with random rotations in a cube sized so that about ``density`` of
    its volume is filled. Returns meshes (body space) and (4, 4) world-from-body transforms."""
    rng = np.random.default_rng(seed)
    side = size * (n / density) ** (1 / 3) * 0.6
    meshes, transforms = [], []
    for i in range(n):
        kind = shapes[i % len(shapes)]
        meshes.append(make_shape(kind, size * rng.uniform(0.7, 1.3), rng))
        t = random_rotation(rng)
        t[:3, 3] = rng.uniform(-side / 2, side / 2, 3)
        transforms.append(t)
    return meshes, transforms


def random_box_bodies(rng: np.random.Generator, n: int, *, scale: float = 1.0,
                      spread: float = 1.0, mirror: bool = True, shear: bool = True
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` random body-space boxes about ``scale`` across, flat boxes and boxes of equal
    extents among them, under random transforms (rotated, non-uniformly scaled, sheared and
    mirrored) placed within ``spread * scale`` of the world's origin.

    Returns
    -------
    local_lo, local_hi : (n, 3) float64
    transforms : (n, 4, 4) float64
    """
    lo = rng.uniform(-1.0, 0.0, (n, 3)) * scale
    hi = lo + rng.uniform(0.05, 1.0, (n, 3)) * scale
    flat = rng.random(n) < 0.1
    hi[flat, 2] = lo[flat, 2] + 1e-3 * scale                     # flat boxes
    same = rng.random(n) < 0.1
    hi[same] = lo[same] + 0.5 * scale                           # equal extents
    transforms = np.zeros((n, 4, 4))
    for i in range(n):
        m = random_rotation(rng)[:3, :3] if rng.random() < 0.8 else np.eye(3)
        if rng.random() < 0.4:
            m = m @ np.diag(rng.uniform(0.3, 2.0, 3))
        if shear and rng.random() < 0.2:
            s = np.eye(3)
            s[0, 1] = rng.uniform(-0.5, 0.5)
            m = m @ s
        if mirror and rng.random() < 0.2:
            m = m @ np.diag([1.0, 1.0, -1.0])
        transforms[i, :3, :3] = m
        transforms[i, :3, 3] = rng.uniform(-spread, spread, 3) * scale
        transforms[i, 3, 3] = 1.0
    return lo, hi, transforms


def box_world_bounds(local_lo: np.ndarray, local_hi: np.ndarray, transforms: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """World boxes (n, 3) lo and hi of body-space boxes (n, 3) under transforms (n, 4, 4): the
    extremes of their transformed corners."""
    corners = np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), -1).reshape(8, 3)
    local = local_lo[:, None] + corners[None] * (local_hi - local_lo)[:, None]     # (n, 8, 3)
    world = np.einsum("nij,nkj->nki", transforms[:, :3, :3], local) + transforms[:, None, :3, 3]
    return world.min(axis=1), world.max(axis=1)


def random_boxes(n: int, seed: int, *, scale: float = 1.0, offset: float = 0.0,
                 spread: float | None = None, mirror: bool = True, shear: bool = True
                 ) -> dict[str, np.ndarray]:
    """The tile planners' inputs (:func:`pycinder.focused.plan.plan_numpy.plan_tiles`') for
    ``n`` random boxes of :func:`random_box_bodies`, placed ``offset`` from the world's origin
    (default spread: about one candidate pair a box), with every pair of overlapping world boxes
    a candidate.

    Returns
    -------
    dict
        ``pairs`` (K, 2), ``tolerance`` (K,), ``local_lo``, ``local_hi``, ``world_lo``,
        ``world_hi`` (n, 3), ``transforms`` (n, 4, 4), ``faces`` (n,) and ``open_bodies`` (n,).
    """
    rng = np.random.default_rng(seed)
    spread = 0.35 * n ** (1 / 3) if spread is None else spread
    lo, hi, transforms = random_box_bodies(rng, n, scale=scale, spread=spread, mirror=mirror,
                                           shear=shear)
    transforms[:, :3, 3] += offset
    world_lo, world_hi = box_world_bounds(lo, hi, transforms)
    i, j = np.triu_indices(n, 1)
    meet = ((world_lo[i] <= world_hi[j]) & (world_lo[j] <= world_hi[i])).all(axis=1)
    pairs = np.stack([i[meet], j[meet]], axis=1).astype(np.int64)
    tol = 0.02 * scale * rng.uniform(0.5, 2.0, len(pairs))
    faces = rng.integers(12, 6000, n)
    open_bodies = rng.random(n) < 0.1
    return dict(pairs=pairs, pair_tolerances=tol, local_lo=lo, local_hi=hi, world_lo=world_lo,
                world_hi=world_hi, transforms=transforms, faces=faces, open_bodies=open_bodies)


def nested_scene() -> tuple[list[trimesh.Trimesh], list[np.ndarray]]:
    """A small sphere entirely inside a large box, with no surface crossing, plus a far sphere."""
    big = trimesh.creation.box((4, 3, 2))
    small = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    far = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    t = [np.eye(4), trimesh.transformations.translation_matrix((0.5, 0.2, -0.1)),
         trimesh.transformations.translation_matrix((4, 0, 0))]
    return [big, small, far], t


BUNNY_FILE = Path(__file__).parents[1] / "data" / "bunny.npz"
"""The sample bunny the package ships: the closed Stanford bunny, decimated to 3,512 triangles
(see ``scripts/make_bunny.py``)."""


@lru_cache(maxsize=4)
def _bunny(subdivisions: int) -> trimesh.Trimesh:
    with np.load(BUNNY_FILE) as data:
        vertices = data["vertices"].astype(np.float64)
        faces = data["faces"].astype(np.int64)
    if subdivisions:
        vertices, faces = trimesh.remesh.subdivide_loop(vertices, faces, iterations=subdivisions)
    return trimesh.Trimesh(vertices, faces, process=True)


def bunny(subdivisions: int = 2) -> trimesh.Trimesh:
    """The Stanford bunny shipped with pycinder: closed, outward-wound, about 0.62 across.

    Parameters
    ----------
    subdivisions : int
        Loop subdivisions of the shipped 3,512 triangles: each multiplies the triangle count by
        4 and smooths the surface. The default, 2, gives 56,192 triangles (about the closed
        original's 56,172); 0 gives the 3,512 shipped.

    Returns
    -------
    trimesh.Trimesh
        A new copy each call (the loaded mesh is cached).
    """
    if not isinstance(subdivisions, int) or isinstance(subdivisions, bool) \
            or not 0 <= subdivisions <= 4:
        raise ValueError(f"subdivisions must be a whole number from 0 to 4, got {subdivisions!r}")
    return _bunny(subdivisions).copy()


def sample_mesh_path(name: str) -> Path:
    """A mesh from pymeshlab's bundled samples (``bunny10k_textured.obj``: the scanned bunny,
    open at the bottom, which the snow demo's ``--scan`` shows). Needs pymeshlab."""
    require("pymeshlab", f"the sample mesh {name}", "scan")
    import pymeshlab

    path = Path(pymeshlab.__file__).parent / "tests" / "sample_meshes" / name
    if not path.exists():  # pragma: no cover
        raise FileNotFoundError(f"pymeshlab has no sample mesh {name}")
    return path


def fcl_object(mesh: Any) -> Any:
    """A mesh (trimesh, or anything with ``vertices`` (V, 3) and ``faces`` (F, 3)) as
    python-fcl's collision object of its triangles, in float64, at the identity."""
    fcl = require("fcl", "exact distances", "test", "python-fcl")
    model = fcl.BVHModel()
    model.beginModel(len(mesh.vertices), len(mesh.faces))
    model.addSubModel(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int32))
    model.endModel()
    return fcl.CollisionObject(model, fcl.Transform())


def coal_convex(mesh: Any) -> Any:
    """A convex mesh (trimesh, or anything with ``vertices`` (V, 3) and ``faces`` (F, 3)) as
    coal's ``Convex``."""
    coal = require("coal", "exact penetration depths", "test")
    points = coal.StdVec_Vec3s()
    for p in np.asarray(mesh.vertices, np.float64):
        points.append(p)
    triangles = coal.StdVec_Triangle()
    for f in np.asarray(mesh.faces):
        triangles.append(coal.Triangle(int(f[0]), int(f[1]), int(f[2])))
    return coal.Convex(points, triangles)


def coal_pose(transform: np.ndarray) -> Any:
    """A (4, 4) rigid transform as coal's ``Transform3s``."""
    coal = require("coal", "exact penetration depths", "test")
    t = np.asarray(transform, np.float64)
    return coal.Transform3s(np.ascontiguousarray(t[:3, :3]), np.ascontiguousarray(t[:3, 3]))


def coal_depth(a: Any, ta: np.ndarray, b: Any, tb: np.ndarray) -> float:
    """coal's penetration depth (GJK/EPA signed distance) of two convex meshes placed by
    (4, 4) transforms; 0 where they are apart."""
    coal = require("coal", "exact penetration depths", "test")
    distance = coal.distance(coal_convex(a), coal_pose(ta), coal_convex(b), coal_pose(tb),
                             coal.DistanceRequest(), coal.DistanceResult())
    return max(-float(distance), 0.0)


def surface_distance(a: Any, b: Any, transforms: Any = None) -> float:
    """Exact distance between two meshes' surfaces (python-fcl), 0 or less where they meet.

    Parameters
    ----------
    a, b : trimesh.Trimesh or (vertices, faces)
    transforms : pair of (4, 4) float, optional
        World from body of ``a`` and ``b`` (default: the meshes are in world coordinates).
    """
    import fcl

    ta, tb = (None, None) if transforms is None else transforms
    oa, ob = fcl_object(world_mesh(a, ta)), fcl_object(world_mesh(b, tb))
    return float(fcl.distance(oa, ob, fcl.DistanceRequest(), fcl.DistanceResult()))


def crosses_deeply(a: trimesh.Trimesh, b: trimesh.Trimesh, depth: float) -> bool:
    """Whether some edge of one mesh passes through a face of the other with both of its ends at
    least ``depth`` from that face's plane (a crossing no rounding can hide)."""
    for p, q in ((a, b), (b, a)):
        edges = p.vertices[p.edges_unique]
        origins, ends = edges[:, 0], edges[:, 1]
        direction = ends - origins
        length = np.linalg.norm(direction, axis=1)
        hits, rays, _ = q.ray.intersects_location(origins, direction / length[:, None])
        if not len(hits):
            continue
        along = np.einsum("ij,ij->i", hits - origins[rays], direction[rays] / length[rays, None])
        inside = (along > 0) & (along < length[rays])
        for h, r in zip(hits[inside], rays[inside]):
            tri = q.nearest.on_surface([h])[2][0]
            n = q.face_normals[tri]
            if min(abs(np.dot(origins[r] - h, n)), abs(np.dot(ends[r] - h, n))) >= depth:
                return True
    return False


def first_contact(a: trimesh.Trimesh, b: trimesh.Trimesh, direction: np.ndarray,
                  gap: float = 0.0, iterations: int = 60) -> float:
    """How far to move ``b`` along ``direction`` (from where it is) so that, coming in from far
    away, it is first exactly ``gap`` from ``a`` (``gap = 0``: first contact).

    Scans inwards in steps of a quarter of the smaller body's size (so that ``b`` can neither
    jump into ``a`` nor over a concave part of it unseen), then bisects on the exact mesh
    distance (python-fcl), so non-convex bodies stop at their first contact, not a later one.

    Parameters
    ----------
    a, b : trimesh.Trimesh
        World meshes.
    direction : (3,) float
        ``b`` comes in towards ``a`` along ``-direction``.
    gap : float
        Wanted distance.

    Returns
    -------
    float
        ``s`` such that ``b`` translated by ``s * direction`` is ``gap`` from ``a``.
    """
    import fcl

    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    oa, ob = fcl_object(a), fcl_object(b)
    far = float(np.linalg.norm(a.extents) + np.linalg.norm(b.extents)) + 2 * gap + float(
        np.linalg.norm(a.centroid - b.centroid))
    step = 0.25 * min(float(a.extents.min()), float(b.extents.min()))

    def distance(s: float) -> float:
        ob.setTransform(fcl.Transform(np.eye(3), s * d))
        return float(fcl.distance(oa, ob, fcl.DistanceRequest(), fcl.DistanceResult()))

    prev = far
    for s in np.arange(far - step, -far, -step):
        if distance(s) <= gap:
            hi, lo = prev, float(s)  # distance(hi) > gap >= distance(lo)
            for _ in range(iterations):
                mid = 0.5 * (hi + lo)
                if distance(mid) > gap:
                    hi = mid
                else:
                    lo = mid
            return float(hi) if gap > 0 else float(lo)
        prev = float(s)
    raise ValueError("the bodies never come within the gap along this direction")


def l_shape(size: float = 1.0, thickness: float = 0.3, depth: float = 0.5) -> trimesh.Trimesh:
    """A closed L-shaped solid (two boxes joined with manifold3d): non-convex, with an inner
    corner."""
    m3d = _manifold3d()
    arm = m3d.Manifold.cube((size, thickness, depth))
    leg = m3d.Manifold.cube((thickness, size, depth))
    mesh = (arm + leg).to_mesh()
    out = trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts))
    out.apply_translation(-out.bounds.mean(axis=0))
    return out


# -- Open surfaces and holed solids (the contract's open-body and holed-body cases) -------------

def open_cup(size: float = 1.0) -> trimesh.Trimesh:
    """A box without its top: an open surface."""
    box = trimesh.creation.box((size, size, size))
    keep = box.face_normals[:, 2] < 0.9
    return trimesh.Trimesh(box.vertices, box.faces[keep], process=False)


def open_tube(radius: float, height: float, sections: int = 32) -> trimesh.Trimesh:
    """A cylinder without its caps: an open surface."""
    c = trimesh.creation.cylinder(radius=radius, height=height, sections=sections)
    keep = np.abs(c.face_normals[:, 2]) < 0.5
    return trimesh.Trimesh(c.vertices, c.faces[keep], process=False)


def grid_plate(size: float = 1.0, n: int = 8) -> trimesh.Trimesh:
    """A flat square grid of triangles in the plane z = 0: an open surface."""
    xs = np.linspace(-size / 2, size / 2, n + 1)
    x, y = np.meshgrid(xs, xs)
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    a = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    f = np.concatenate([np.stack([a, a + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + n + 1], 1)])
    return trimesh.Trimesh(v, f, process=False)


def disc(radius: float, sections: int = 32) -> trimesh.Trimesh:
    """A flat disc in the plane z = 0, a fan of triangles: an open surface."""
    angle = np.linspace(0, 2 * np.pi, sections, endpoint=False)
    v = np.concatenate([[[0, 0, 0]], np.stack([radius * np.cos(angle), radius * np.sin(angle),
                                               np.zeros(sections)], 1)])
    k = np.arange(sections)
    f = np.stack([np.zeros(sections, int), 1 + k, 1 + (k + 1) % sections], 1)
    return trimesh.Trimesh(v, f, process=False)


def holed_plate(size: float = 1.0, holes: int = 3) -> trimesh.Trimesh:
    """A plate with ``holes`` round holes through it (manifold3d): watertight, genus ``holes``."""
    m3d = _manifold3d()
    plate = m3d.Manifold.cube((size, size, 0.1 * size), center=True)
    for k in range(holes):
        x = (k + 0.5) / holes * size - size / 2
        hole = m3d.Manifold.cylinder(0.4 * size, 0.12 * size / holes, 0.12 * size / holes, 32,
                                     center=True).translate((x, 0.0, 0.0))
        plate = plate - hole
    mesh = plate.to_mesh()
    return trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts))


def holed_scene(count: int, seed: int) -> tuple[list[trimesh.Trimesh], list[np.ndarray]]:
    """``count`` holed and thin-walled solids (plates with holes, a thin and a thick torus, a
    ring), about 1 across, turned and placed at random in a cube 1.2 wide: meshes and (4, 4)
    world-from-body transforms."""
    rng = np.random.default_rng(seed)
    shapes = [holed_plate(1.0, 3), holed_plate(0.8, 1),
              trimesh.creation.torus(major_radius=0.35, minor_radius=0.05, major_sections=48,
                                     minor_sections=12),
              trimesh.creation.torus(major_radius=0.3, minor_radius=0.12, major_sections=32,
                                     minor_sections=16),
              trimesh.creation.annulus(r_min=0.25, r_max=0.3, height=0.4, sections=40)]
    meshes, transforms = [], []
    for k in range(count):
        meshes.append(shapes[k % len(shapes)])
        pose = random_rotation(rng)
        pose[:3, 3] = rng.uniform(-0.6, 0.6, 3)
        transforms.append(pose)
    return meshes, transforms


def _placed(x: float = 0.0, y: float = 0.0, z: float = 0.0,
            rotation: np.ndarray | None = None) -> np.ndarray:
    m = np.eye(4) if rotation is None else rotation.copy()
    m[:3, 3] = (x, y, z)
    return m


def open_body_cases(t: float) -> list[tuple[str, list[trimesh.Trimesh], list[np.ndarray], bool]]:
    """Open bodies against open and closed ones at tolerance ``t`` (bodies about 1 across):
    ``(name, meshes, transforms, must be reported)``. Each answer is fixed by the construction:
    the reported ones cross by far more than ``2 t``, the others are at least ``t`` apart by
    their surfaces (python-fcl checks it in the tests)."""
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.2)
    turn = trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0))
    return [
        ("ball in a cup, 20 t from every wall", [open_cup(), ball],
         [_placed(), _placed(0, 0, 0.05)], False),
        ("ball through a cup's wall", [open_cup(), ball], [_placed(), _placed(0.45, 0, 0)], True),
        ("ball 2 t inside a cup's wall", [open_cup(), ball],
         [_placed(), _placed(0.3 - 2 * t, 0, 0)], False),
        ("rod along a tube's axis", [open_tube(0.3, 1.0), open_tube(0.05, 1.5)],
         [_placed(), _placed()], False),
        ("rod through a tube's wall", [open_tube(0.3, 1.0), open_tube(0.05, 1.5)],
         [_placed(), _placed(rotation=turn)], True),
        ("plate through an open box's walls", [open_cup(), grid_plate(1.6)],
         [_placed(), _placed(0, 0, 0.1)], True),
        ("plate 1.5 t inside an open box's wall", [open_cup(), grid_plate(0.5)],
         [_placed(), _placed(0.5 - 1.5 * t, 0, 0, turn)], False),
        ("disc through a ball", [ball, disc(0.4)], [_placed(), _placed(0, 0, 0.05)], True),
        ("disc 2 t above a ball", [ball, disc(0.4)], [_placed(), _placed(0, 0, 0.2 + 2 * t)],
         False),
        ("disc inside a ball", [ball, disc(0.1)], [_placed(), _placed(0, 0, 0.02)], True),
        ("ball inside a closed box (solids still count)", [trimesh.creation.box((1, 1, 1)), ball],
         [_placed(), _placed(0, 0, 0.05)], True),
    ]

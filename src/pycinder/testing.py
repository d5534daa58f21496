"""Scenes and exact ground truth, shared by the tests and the benchmarks.

Ground truth is the intersection volume computed by manifold3d, scored with a tolerance band:

* a pair **overlaps** when it still overlaps with both solids shrunk 5% about their centroids;
* a pair is **separate** when it is still apart with both solids grown 5%;
* pairs in between are **ambiguous** and not scored.

Needs the ``test`` extra (``pip install pycinder[test]``) for manifold3d.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

BAND = 0.05


def _manifold3d() -> Any:
    try:
        import manifold3d
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("exact ground truth needs manifold3d: pip install 'pycinder[test]'") from exc
    return manifold3d


def world_mesh(mesh: trimesh.Trimesh, transform: np.ndarray | None) -> trimesh.Trimesh:
    m = mesh.copy()
    if transform is not None:
        m.apply_transform(transform)
    return m


def scaled_about_centroid(mesh: trimesh.Trimesh, factor: float) -> np.ndarray:
    """Vertices (V, 3) of ``mesh`` scaled by ``factor`` about its volume centroid."""
    c = mesh.center_mass if mesh.is_volume else mesh.centroid
    return c + (mesh.vertices - c) * factor


def _manifold(vertices: np.ndarray, faces: np.ndarray) -> Any:
    m3d = _manifold3d()
    return m3d.Manifold(m3d.Mesh(vert_properties=np.asarray(vertices, np.float32),
                                 tri_verts=np.asarray(faces, np.uint32)))


@dataclass
class Truth:
    """Ground truth of a scene.

    overlap : (K, 2) int64 pairs that clearly overlap
    separate : (M, 2) int64 pairs that are clearly apart
    ambiguous : (L, 2) int64 pairs inside the tolerance band
    """

    overlap: np.ndarray
    separate: np.ndarray
    ambiguous: np.ndarray

    def score(self, found: np.ndarray) -> dict[str, Any]:
        """Recall on clear overlaps and the clear separations reported, for ``found`` (K, 2)."""
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


def ground_truth(meshes: list[trimesh.Trimesh], transforms: list[np.ndarray] | None = None,
                 band: float = BAND) -> Truth:
    """Exact overlap classes of every pair, with the tolerance band."""
    world = [world_mesh(m, None if transforms is None else transforms[i]) for i, m in enumerate(meshes)]
    n = len(world)
    small = [scaled_about_centroid(m, 1.0 - band) for m in world]
    large = [scaled_about_centroid(m, 1.0 + band) for m in world]
    lo = np.array([v.min(axis=0) for v in large])
    hi = np.array([v.max(axis=0) for v in large])
    cache_small: dict[int, Any] = {}
    cache_large: dict[int, Any] = {}

    def solid(cache: dict[int, Any], verts: list[np.ndarray], i: int) -> Any:
        if i not in cache:
            cache[i] = _manifold(verts[i], world[i].faces)
        return cache[i]

    overlap, separate, ambiguous = [], [], []
    for i in range(n):
        # Pairs whose grown bounding boxes do not touch are clearly separate.
        near = np.flatnonzero((lo[i + 1:] <= hi[i]).all(axis=1) & (hi[i + 1:] >= lo[i]).all(axis=1))
        near_set = set((near + i + 1).tolist())
        for j in range(i + 1, n):
            if j not in near_set:
                separate.append((i, j))
                continue
            vs = (solid(cache_small, small, i) ^ solid(cache_small, small, j)).volume()
            if vs > 1e-12:
                overlap.append((i, j))
                continue
            vl = (solid(cache_large, large, i) ^ solid(cache_large, large, j)).volume()
            (ambiguous if vl > 1e-12 else separate).append((i, j))

    def arr(x: list) -> np.ndarray:
        return np.array(x, dtype=np.int64).reshape(-1, 2)

    return Truth(arr(overlap), arr(separate), arr(ambiguous))


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


def nested_scene() -> tuple[list[trimesh.Trimesh], list[np.ndarray]]:
    """A small sphere entirely inside a large box, with no surface crossing, plus a far sphere."""
    big = trimesh.creation.box((4, 3, 2))
    small = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    far = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    t = [np.eye(4), trimesh.transformations.translation_matrix((0.5, 0.2, -0.1)),
         trimesh.transformations.translation_matrix((4, 0, 0))]
    return [big, small, far], t


@lru_cache(maxsize=2)
def bunny(decimate_to: int | None = None) -> trimesh.Trimesh:
    """The Stanford bunny from pymeshlab's sample meshes (about 56k triangles, closed).

    decimate_to : target vertex count for a quadric edge collapse (pymeshlab), or None
    """
    path = sample_mesh_path("bunny.obj")
    if decimate_to is None:
        return trimesh.load(path, force="mesh", process=True)
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(path))
    ms.meshing_decimation_quadric_edge_collapse(targetfacenum=2 * decimate_to, preservetopology=True,
                                                preservenormal=True)
    m = ms.current_mesh()
    return trimesh.Trimesh(m.vertex_matrix(), m.face_matrix(), process=True)


def sample_mesh_path(name: str) -> Path:
    """A mesh from pymeshlab's bundled samples (``bunny.obj``, ``bunny10k_textured.obj``)."""
    try:
        import pymeshlab
    except ImportError as exc:  # pragma: no cover
        raise ImportError("the sample bunny comes with pymeshlab: pip install pymeshlab") from exc
    path = Path(pymeshlab.__file__).parent / "tests" / "sample_meshes" / name
    if not path.exists():  # pragma: no cover
        raise FileNotFoundError(f"pymeshlab has no sample mesh {name}")
    return path

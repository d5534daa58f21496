"""Bodies: validation, unique edges, normals, id limits, and packing into flat arrays.

A body is a closed triangle mesh plus a world-from-body transform. Everything the GPU needs about
the topology (faces, unique edges, normals) is computed once per distinct ``faces`` array and
cached; what changes every frame (vertices, transforms) is checked cheaply every call.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

MAX_BODIES = 65535
"""Ids are 16 bits per role, and 0 means "nothing": at most 65535 bodies per query."""


class OpenMeshWarning(UserWarning):
    """A body is not a closed, consistently oriented surface: ray counts through it can be wrong."""


class DegenerateFaceWarning(UserWarning):
    """A body has faces of zero area."""


@dataclass(frozen=True)
class Topology:
    """What is computed once per distinct face array.

    faces : (F, 3) uint32, vertex indices, counter-clockwise seen from outside
    edges : (E, 2) uint32, unique undirected edges
    edge_faces : (3F,) int64, the unique edge of each directed face edge (face-major order)
    boundary_edges : int, edges used by one face only
    nonmanifold_edges : int, edges used by three faces or more
    misoriented_edges : int, edges both of whose faces run the same direction along them
    """

    faces: np.ndarray
    edges: np.ndarray
    edge_faces: np.ndarray
    n_vertices: int
    boundary_edges: int
    nonmanifold_edges: int
    misoriented_edges: int

    @property
    def closed(self) -> bool:
        return self.boundary_edges == 0 and self.nonmanifold_edges == 0 and self.misoriented_edges == 0

    def problem(self) -> str:
        parts = []
        if self.boundary_edges:
            parts.append(f"{self.boundary_edges} boundary edges (holes)")
        if self.nonmanifold_edges:
            parts.append(f"{self.nonmanifold_edges} edges shared by more than two faces")
        if self.misoriented_edges:
            parts.append(f"{self.misoriented_edges} edges between inconsistently wound faces")
        return ", ".join(parts)


def body_label(index: int, name: str | None) -> str:
    return f"body {index}" + (f" ({name!r})" if name else "")


def build_topology(faces: np.ndarray, n_vertices: int, label: str) -> Topology:
    """Check a face array and derive its unique edges.

    faces : (F, 3) int, indices into a vertex array of length ``n_vertices``
    """
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"{label}: faces must have shape (F, 3), got {faces.shape}")
    if len(faces) == 0 or n_vertices == 0:
        raise ValueError(f"{label}: the mesh is empty ({n_vertices} vertices, {len(faces)} faces)")
    if not np.issubdtype(faces.dtype, np.integer):
        if not np.all(np.equal(np.mod(faces, 1), 0)):
            raise ValueError(f"{label}: face indices must be integers")
    lo, hi = int(faces.min()), int(faces.max())
    if lo < 0 or hi >= n_vertices:
        bad = int(np.count_nonzero((faces < 0).any(1) | (faces >= n_vertices).any(1)))
        raise ValueError(
            f"{label}: {bad} faces index vertices out of range (indices span {lo}..{hi}, "
            f"the mesh has {n_vertices} vertices)"
        )
    faces = faces.astype(np.uint32)
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    if repeated.any():
        first = int(np.flatnonzero(repeated)[0])
        raise ValueError(
            f"{label}: {int(repeated.sum())} degenerate faces repeat a vertex index "
            f"(first: face {first} = {faces[first].tolist()}); remove them, for example with "
            "trimesh's mesh.update_faces(mesh.nondegenerate_faces())"
        )
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2).astype(np.int64)
    lo_hi = np.sort(directed, axis=1)
    key = lo_hi[:, 0] * np.int64(n_vertices) + lo_hi[:, 1]
    unique_keys, first_index, inverse, counts = np.unique(
        key, return_index=True, return_inverse=True, return_counts=True
    )
    edges = lo_hi[first_index].astype(np.uint32)
    # Orientation: in a closed, consistently wound mesh each undirected edge is walked once in
    # each direction. Count the walks from low to high vertex per edge.
    forward = (directed[:, 0] < directed[:, 1]).astype(np.int64)
    forward_per_edge = np.bincount(inverse, weights=forward, minlength=len(unique_keys))
    misoriented = int(np.count_nonzero((counts == 2) & (forward_per_edge != 1)))
    return Topology(
        faces=faces,
        edges=edges,
        edge_faces=inverse.astype(np.int64),
        n_vertices=int(n_vertices),
        boundary_edges=int(np.count_nonzero(counts == 1)),
        nonmanifold_edges=int(np.count_nonzero(counts > 2)),
        misoriented_edges=misoriented,
    )


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals and face areas.

    vertices : (V, 3) float
    faces : (F, 3) int
    Returns normals (F, 3) float32 (zero for zero-area faces) and areas (F,) float64.
    """
    tri = vertices[faces].astype(np.float64)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(cross, axis=1)
    normals = np.divide(cross, length[:, None], out=np.zeros_like(cross), where=length[:, None] > 0)
    return normals.astype(np.float32), 0.5 * length


def _accumulate(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    out = np.stack([np.bincount(index, weights=values[:, k], minlength=n) for k in range(3)], axis=1)
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return np.divide(out, length, out=np.zeros_like(out), where=length > 0).astype(np.float32)


def vertex_and_edge_normals(
    vertices: np.ndarray, topo: Topology
) -> tuple[np.ndarray, np.ndarray, int]:
    """Area-weighted vertex normals (V, 3), edge normals (E, 3) and the count of zero-area faces."""
    normals, areas = face_normals(vertices, topo.faces)
    weighted = normals * areas[:, None].astype(np.float32)
    vn = _accumulate(topo.faces.reshape(-1).astype(np.int64), np.repeat(weighted, 3, axis=0),
                     topo.n_vertices)
    en = _accumulate(topo.edge_faces, np.repeat(normals, 3, axis=0), len(topo.edges))
    return vn, en, int(np.count_nonzero(areas <= 0))


@dataclass
class Body:
    """One validated body.

    vertices : (V, 3) float32, body space
    topology : the face and edge data shared by bodies with the same face array
    transform : (4, 4) float64, world from body
    """

    index: int
    name: str | None
    vertices: np.ndarray
    topology: Topology
    transform: np.ndarray

    @property
    def label(self) -> str:
        return body_label(self.index, self.name)


def mesh_arrays(body: Any, label: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of a trimesh.Trimesh or a (vertices, faces) pair."""
    if hasattr(body, "vertices") and hasattr(body, "faces"):
        # Keep trimesh's own faces object: its identity is the topology cache's key.
        return np.asarray(body.vertices), body.faces
    if isinstance(body, (tuple, list)) and len(body) == 2:
        return np.asarray(body[0]), np.asarray(body[1])
    raise TypeError(
        f"{label}: expected a trimesh.Trimesh or a (vertices, faces) pair, got {type(body).__name__}"
    )


def check_vertices(vertices: np.ndarray, label: str) -> np.ndarray:
    """vertices : (V, 3) float; returns a float32 copy, raising on NaN/inf and bad shapes."""
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"{label}: vertices must have shape (V, 3), got {vertices.shape}")
    if not np.issubdtype(vertices.dtype, np.number):
        raise ValueError(f"{label}: vertices must be numbers, got dtype {vertices.dtype}")
    finite = np.isfinite(vertices)
    if not finite.all():
        bad = np.flatnonzero(~finite.all(axis=1))
        raise ValueError(
            f"{label}: {len(bad)} vertices are NaN or infinite (first: vertex {int(bad[0])})"
        )
    return np.ascontiguousarray(vertices, dtype=np.float32)


def check_transforms(transforms: Any, n: int, names: Sequence[str | None]) -> np.ndarray:
    """transforms : None or (N, 4, 4) float. Returns (N, 4, 4) float64."""
    if transforms is None:
        return np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    t = np.asarray(transforms, dtype=np.float64)
    if t.shape != (n, 4, 4):
        raise ValueError(f"transforms must have shape ({n}, 4, 4), one per body; got {t.shape}")
    finite = np.isfinite(t).reshape(n, -1).all(axis=1)
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise ValueError(f"{body_label(i, names[i])}: transform contains NaN or infinite values")
    bottom = np.abs(t[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    if (bottom > 1e-9).any():
        i = int(np.flatnonzero(bottom > 1e-9)[0])
        raise ValueError(
            f"{body_label(i, names[i])}: transform is not affine (last row must be [0, 0, 0, 1])"
        )
    return t


class TopologyCache:
    """Topology per distinct face array, so that animation loops validate faces only once.

    Face arrays are looked up by identity and treated as immutable once passed in; vertices may
    change freely between calls.
    """

    def __init__(self, maxsize: int = 4096) -> None:
        self._entries: dict[int, tuple[np.ndarray, Topology, tuple[np.ndarray, np.ndarray, int]]] = {}
        self._maxsize = maxsize

    def get(self, faces: np.ndarray, vertices: np.ndarray, label: str, strict: bool
            ) -> tuple[Topology, np.ndarray, np.ndarray]:
        """Topology, vertex normals (V, 3) and edge normals (E, 3) for this face array."""
        entry = self._entries.get(id(faces))
        if entry is None or entry[0] is not faces or entry[1].n_vertices != len(vertices):
            topo = build_topology(faces, len(vertices), label)
            normals = vertex_and_edge_normals(vertices, topo)
            if len(self._entries) >= self._maxsize:
                self._entries.clear()
            entry = (faces, topo, normals)
            self._entries[id(faces)] = entry
            report_problems(topo, normals[2], label, strict)
        topo, (vn, en, _) = entry[1], entry[2]
        return topo, vn, en


def report_problems(topo: Topology, zero_area: int, label: str, strict: bool) -> None:
    """Warn (or raise when ``strict``) about open meshes and zero-area faces."""
    if not topo.closed:
        message = (
            f"{label} is not a closed, consistently oriented surface: {topo.problem()}. CInDeR "
            "counts faces along rays, which is only meaningful for closed solids, so collisions "
            "with this body may be missed or invented. Repair it (trimesh.repair.fill_holes, "
            "pymeshlab's close holes) or pass strict=True to make this an error."
        )
        if strict:
            raise ValueError(message)
        warnings.warn(message, OpenMeshWarning, stacklevel=4)
    if zero_area:
        message = f"{label} has {zero_area} faces of zero area"
        if strict:
            raise ValueError(message)
        warnings.warn(message, DegenerateFaceWarning, stacklevel=4)


def prepare_bodies(
    bodies: Sequence[Any],
    transforms: Any = None,
    *,
    names: Sequence[str | None] | None = None,
    strict: bool = False,
    cache: TopologyCache | None = None,
) -> tuple[list[Body], list[tuple[np.ndarray, np.ndarray]]]:
    """Validate bodies and transforms.

    Returns the bodies and, per body, its (vertex normals, edge normals).
    """
    if isinstance(bodies, (str, bytes)) or not isinstance(bodies, Sequence):
        bodies = list(bodies)
    n = len(bodies)
    if n > MAX_BODIES:
        raise ValueError(
            f"{n} bodies is more than the {MAX_BODIES} that 16-bit ids can name; split the scene "
            "into several queries"
        )
    names = list(names) if names is not None else [None] * n
    cache = cache if cache is not None else TopologyCache()
    t = check_transforms(transforms, n, names)
    out: list[Body] = []
    normals: list[tuple[np.ndarray, np.ndarray]] = []
    for i, body in enumerate(bodies):
        label = body_label(i, names[i])
        vertices, faces = mesh_arrays(body, label)
        v32 = check_vertices(vertices, label)
        if len(v32) == 0:
            raise ValueError(f"{label}: the mesh is empty (0 vertices)")
        topo, vn, en = cache.get(faces, v32, label, strict)
        out.append(Body(i, names[i], v32, topo, t[i]))
        normals.append((vn, en))
    return out, normals


@dataclass
class PackedScene:
    """All bodies in flat arrays, as the GPU buffers hold them.

    positions : (V, 3) float32, body space
    vertex_body : (V,) uint32
    indices : (3F,) uint32, global vertex indices of all faces
    edges : (E, 2) uint32, global vertex indices of all unique edges
    vertex_normals : (V, 3) float32
    edge_normals : (E, 3) float32
    vertex_start, face_start, edge_start : (N + 1,) int64 prefix sums per body
    """

    positions: np.ndarray
    vertex_body: np.ndarray
    indices: np.ndarray
    edges: np.ndarray
    vertex_normals: np.ndarray
    edge_normals: np.ndarray
    vertex_start: np.ndarray
    face_start: np.ndarray
    edge_start: np.ndarray
    topology_ids: tuple[int, ...]


def _prefix(counts: Sequence[int]) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(np.asarray(counts, dtype=np.int64))]).astype(np.int64)


def pack(bodies: Sequence[Body], normals: Sequence[tuple[np.ndarray, np.ndarray]]) -> PackedScene:
    """Pack validated bodies into one set of arrays."""
    vs = _prefix([len(b.vertices) for b in bodies])
    fs = _prefix([len(b.topology.faces) for b in bodies])
    es = _prefix([len(b.topology.edges) for b in bodies])
    offsets = vs[:-1].astype(np.uint32)
    return PackedScene(
        positions=np.concatenate([b.vertices for b in bodies]),
        vertex_body=np.repeat(np.arange(len(bodies), dtype=np.uint32), np.diff(vs)),
        indices=np.concatenate([b.topology.faces + o for b, o in zip(bodies, offsets)]).reshape(-1),
        edges=np.concatenate([b.topology.edges + o for b, o in zip(bodies, offsets)]),
        vertex_normals=np.concatenate([n[0] for n in normals]),
        edge_normals=np.concatenate([n[1] for n in normals]),
        vertex_start=vs,
        face_start=fs,
        edge_start=es,
        topology_ids=tuple(id(b.topology) for b in bodies),
    )


def repack(last: PackedScene | None, bodies: Sequence[Body],
           normals: Sequence[tuple[np.ndarray, np.ndarray]]) -> PackedScene:
    """:func:`pack`, reusing ``last``'s topology arrays when the bodies' topology is unchanged
    (an animation frame): only the positions are concatenated anew."""
    ids = tuple(id(b.topology) for b in bodies)
    if last is not None and last.topology_ids == ids:
        positions = np.concatenate([b.vertices for b in bodies])
        if len(positions) == len(last.positions):
            return PackedScene(positions, last.vertex_body, last.indices, last.edges,
                               last.vertex_normals, last.edge_normals, last.vertex_start,
                               last.face_start, last.edge_start, ids)
    return pack(bodies, normals)

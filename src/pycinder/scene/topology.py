"""Topology: what depends on a face array alone (unique edges, closedness, clusters), computed once
per distinct face content and kept in a cache bounded by bytes.

Animation loops pass the same faces every frame, often as a new array each time (``(mesh.vertices,
mesh.faces)``, or faces rebuilt by user code). The cache is therefore keyed on content: trimesh's
tracked arrays carry their own cached content hash; other arrays are fingerprinted from a sample
of their rows and then compared in full with the cached copy, which costs a memory comparison
rather than a rebuild.
"""

from __future__ import annotations

import zlib
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from ..errors import DegenerateFaceWarning, OpenMeshWarning, warn_at_caller
from .clusters import Clusters, build_clusters

DEFAULT_CACHE_BYTES = 512 * 2**20


@dataclass(eq=False)
class Topology:
    """What is computed once per distinct face array.

    Attributes
    ----------
    faces : (F, 3) uint32
        Vertex indices, counter-clockwise seen from outside.
    edges : (E, 2) uint32
        Unique undirected edges.
    edge_faces : (3F,) int64
        The unique edge of each directed face edge (face-major order).
    n_vertices : int
    boundary_edges, nonmanifold_edges, misoriented_edges : int
        Edges used by one face; by three or more; whose two faces run the same way along them.
    unbalanced_edges : int
        Edges walked more often in one direction than in the other by the faces that use them.
    dropped_faces : int
        Faces dropped because they repeat a vertex index (they bound nothing).
    kept : (F,) int64 or None
        Where faces were dropped: the index of each face of ``faces`` in the face array as given
        (records and contacts name faces by that index).
    dropped : (D, 3) int or None
        Where faces were dropped: those faces, as given (so that the cache can tell the face
        array given from one that differs only there).
    """

    faces: np.ndarray
    edges: np.ndarray
    edge_faces: np.ndarray
    n_vertices: int
    boundary_edges: int
    nonmanifold_edges: int
    misoriented_edges: int
    unbalanced_edges: int = 0
    dropped_faces: int = 0
    kept: np.ndarray | None = field(default=None, repr=False)
    dropped: np.ndarray | None = field(default=None, repr=False)
    _clusters: Clusters | None = field(default=None, repr=False)

    @property
    def closed(self) -> bool:
        """A closed, consistently oriented two-manifold surface."""
        return self.boundary_edges == 0 and self.nonmanifold_edges == 0 and self.misoriented_edges == 0

    @property
    def solid(self) -> bool:
        """Whether the surface bounds a solid: every edge is walked as often in one direction as
        in the other, so the winding number of every point off the surface is well defined (a
        closed mesh, also where closed parts share an edge). Solids are tested by ray counts;
        other bodies as surfaces."""
        return self.unbalanced_edges == 0

    @property
    def nbytes(self) -> int:
        extra = self._clusters.nbytes if self._clusters is not None else 0
        return self.faces.nbytes + self.edges.nbytes + self.edge_faces.nbytes + extra

    def given_faces(self, values: np.ndarray) -> np.ndarray:
        """Per-face ``values`` (F, ...) laid out as the face array was given: rows of dropped
        faces are zero."""
        if self.kept is None:
            return values
        out = np.zeros((len(self.kept) + self.dropped_faces,) + values.shape[1:], values.dtype)
        out[self.kept] = values
        return out

    def problem(self) -> str:
        parts = []
        if self.boundary_edges:
            parts.append(f"{self.boundary_edges} boundary edges (holes)")
        if self.nonmanifold_edges:
            parts.append(f"{self.nonmanifold_edges} edges shared by more than two faces")
        if self.misoriented_edges:
            parts.append(f"{self.misoriented_edges} edges between inconsistently wound faces")
        return ", ".join(parts)

    def clusters(self, vertices: np.ndarray) -> Clusters:
        """Spatially coherent clusters of faces and edges (built from the first vertices seen)."""
        if self._clusters is None:
            self._clusters = build_clusters(self.faces, self.edge_faces, len(self.edges),
                                            vertices)
        return self._clusters


def build_topology(faces: np.ndarray, n_vertices: int, label: str) -> Topology:
    """Check a face array and derive its unique edges.

    Parameters
    ----------
    faces : (F, 3) int
        Indices into a vertex array of length ``n_vertices``.
    n_vertices : int
    label : str
        How errors name the body.

    Returns
    -------
    Topology
    """
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"{label}: faces must have shape (F, 3), got {faces.shape}")
    if len(faces) == 0 or n_vertices == 0:
        raise ValueError(f"{label}: the mesh is empty ({n_vertices} vertices, {len(faces)} faces)")
    if not np.issubdtype(faces.dtype, np.integer):
        if not np.issubdtype(faces.dtype, np.number) or not np.all(np.equal(np.mod(faces, 1), 0)):
            raise ValueError(f"{label}: face indices must be integers")
    lo, hi = int(faces.min()), int(faces.max())
    if lo < 0 or hi >= n_vertices:
        bad = int(np.count_nonzero((faces < 0).any(1) | (faces >= n_vertices).any(1)))
        raise ValueError(
            f"{label}: {bad} faces index vertices out of range (indices span {lo}..{hi}, "
            f"the mesh has {n_vertices} vertices)"
        )
    faces = faces.astype(np.uint32)
    # A face that repeats a vertex index bounds nothing and walks its one real edge both ways:
    # dropping it changes neither the surface nor its balance.
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    dropped = int(np.count_nonzero(repeated))
    kept = dropped_rows = None
    if dropped:
        kept = np.flatnonzero(~repeated)
        dropped_rows = faces[repeated].copy()
        faces = faces[kept]
        if len(faces) == 0:
            raise ValueError(f"{label}: every face repeats a vertex index: the mesh has no area")
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
        unbalanced_edges=int(np.count_nonzero(2 * forward_per_edge != counts)),
        dropped_faces=dropped,
        kept=kept,
        dropped=dropped_rows,
    )


def report_problems(topo: Topology, zero_area: int, label: str, strict: bool,
                    inverted: bool = False) -> None:
    """Warn about open, inside-out and degenerate meshes, saying what rule is applied to each;
    with ``strict``, raise instead (and the message says only what is wrong)."""

    def complain(problem: str, rule: str, repair: str, category: type[Warning]) -> None:
        if strict:
            raise ValueError(f"{problem}. {repair}.")
        warn_at_caller(f"{problem}; {rule}. {repair}, or ask for strict checking to make this an "
                       "error.", category)

    if not topo.closed:
        complain(f"{label} is not a closed, consistently oriented surface: {topo.problem()}",
                 "it is tested as a solid all the same: every edge is walked equally often both "
                 "ways, so its inside is well defined" if topo.solid else
                 "it is tested as a surface: a pair is reported where its surface crosses the "
                 "other body's surface, or lies inside another body that is a closed solid; "
                 "nothing is ever found inside it",
                 "Repair it (trimesh.repair.fill_holes, pymeshlab's close holes) to test it as a "
                 "solid", OpenMeshWarning)
    elif inverted:
        complain(f"{label} is closed but wound inside out (its volume is negative)",
                 "collisions are still found (the ray count of its inside is -1, not 0), but its "
                 "normals, and so contact normals, point inwards",
                 "Flip it (trimesh's mesh.invert())", OpenMeshWarning)
    degenerate = []
    if topo.dropped_faces:
        degenerate.append(f"{topo.dropped_faces} faces repeat a vertex index")
    if zero_area:
        degenerate.append(f"{zero_area} faces have zero area")
    if degenerate:
        complain(f"{label} has degenerate faces: {' and '.join(degenerate)}",
                 "faces that repeat a vertex index are dropped and faces of zero area ignored "
                 "(they bound nothing and cross no ray)",
                 "Remove them with trimesh's mesh.update_faces(mesh.nondegenerate_faces())",
                 DegenerateFaceWarning)


def _fingerprint(faces: np.ndarray) -> int:
    """A cheap content key: shape, dtype and a CRC of up to 512 evenly spaced rows."""
    n = len(faces)
    rows = faces if n <= 512 else faces[:: max(1, n // 512)]
    return zlib.crc32(np.ascontiguousarray(rows).tobytes()) ^ hash((faces.shape, faces.dtype.str))


class TopologyCache:
    """Topology per distinct face content, least recently used first out, bounded by bytes.

    Parameters
    ----------
    max_bytes : int
        Memory the cached topologies may hold together.
    """

    def __init__(self, max_bytes: int = DEFAULT_CACHE_BYTES) -> None:
        self.max_bytes = int(max_bytes)
        self._entries: OrderedDict[tuple, Topology] = OrderedDict()
        self.nbytes = 0
        self.builds = 0
        """How many topologies were built (a cache miss each)."""
        self.query = 0
        """The current query (see :meth:`ShapeCache.begin_query`): topologies used by it or the
        one before are never evicted, whatever their size."""
        self._used: dict[tuple, int] = {}
        self._tracked: dict[tuple, tuple[tuple, Topology]] = {}
        """trimesh's content hash of a TrackedArray's faces -> the key of their topology and the
        topology (so that a trimesh mesh and plain arrays of the same faces share one)."""

    def __len__(self) -> int:
        return len(self._entries)

    @staticmethod
    def _key(faces: np.ndarray, n_vertices: int) -> tuple:
        """The cache key (a sampled fingerprint: a hit is confirmed by comparing the faces)."""
        return ("array", _fingerprint(faces), faces.shape, n_vertices)

    def get(self, faces: np.ndarray, n_vertices: int, label: str) -> tuple[Topology, bool]:
        """The topology of ``faces``; the flag says whether it was built just now.

        Parameters
        ----------
        faces : (F, 3) int
        n_vertices : int
            Length of the vertex array the faces index.
        label : str
            How errors name the body.
        """
        faces_arr = faces if isinstance(faces, np.ndarray) else np.asarray(faces)
        if faces_arr.ndim != 2:
            return build_topology(faces_arr, n_vertices, label), True
        tracked = ("tracked", hash(faces_arr), faces_arr.shape, n_vertices) \
            if type(faces_arr).__name__ == "TrackedArray" else None
        alias = self._tracked.get(tracked) if tracked is not None else None
        # trimesh's hash of the content names its topology, while that is still cached
        exact = alias is not None and self._entries.get(alias[0]) is alias[1]
        key = alias[0] if exact else self._key(faces_arr, n_vertices)
        topo = self._entries.get(key)
        if topo is not None and (exact or self._same(topo, faces_arr)):
            self._entries.move_to_end(key)
            self._used[key] = self.query
            if tracked is not None:
                self._tracked[tracked] = (key, topo)
            return topo, False
        topo = build_topology(faces_arr, n_vertices, label)
        if tracked is not None:
            self._tracked[tracked] = (key, topo)
        self.builds += 1
        if key in self._entries:
            self.nbytes -= self._entries.pop(key).nbytes
        self._entries[key] = topo
        self._used[key] = self.query
        self.nbytes += topo.nbytes
        self.evict()
        return topo, True

    @staticmethod
    def _same(topo: Topology, faces: np.ndarray) -> bool:
        """Whether ``faces`` (as given) are the faces ``topo`` was built from."""
        if topo.kept is None:
            return np.array_equal(topo.faces, faces)
        if len(faces) != len(topo.kept) + topo.dropped_faces:
            return False
        given = np.ones(len(faces), dtype=bool)
        given[topo.kept] = False
        return np.array_equal(topo.faces, faces[topo.kept]) \
            and np.array_equal(topo.dropped, faces[given])

    def evict(self) -> None:
        """Drop the least recently used topologies until the cache fits its byte bound, never
        one of the current or the previous query."""
        for key in list(self._entries):
            if self.nbytes <= self.max_bytes:
                break
            if self.query and self._used.get(key, 0) >= self.query - 1:
                continue  # needed by the current or the previous query
            self.nbytes -= self._entries.pop(key).nbytes
            self._used.pop(key, None)
        if len(self._tracked) > 2 * len(self._entries):
            self._tracked = {t: (k, topo) for t, (k, topo) in self._tracked.items()
                             if self._entries.get(k) is topo}

    def account(self, topo: Topology, added: int) -> None:
        """Count bytes a topology grew by after it was cached (its clusters)."""
        self.nbytes += added
        self.evict()

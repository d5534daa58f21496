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

from ..errors import (DegenerateFaceWarning, MeshWarning, OpenMeshWarning, RewoundMeshWarning,
                      warn_at_caller)
from .clusters import Clusters, build_clusters
from .winding import consistent_flips, flip_faces, outward_flips

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
    rewound : int
        Edges that were walked the same way by their two faces before the mesh was wound again
        (0: the faces are as given). A closed two-manifold mesh wound inconsistently is wound
        again (:mod:`~pycinder.scene.winding`), each part outward, and is then a solid.
    as_given : (F, 3) uint32 or None
        Where the mesh was wound again: its faces (those kept) as given, for the cache.
    parts : (F,) int64 or None
        Where the mesh was wound consistently but not yet outward (that needs its vertices:
        :meth:`orient`): each face's connected part.
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
    rewound: int = 0
    as_given: np.ndarray | None = field(default=None, repr=False)
    parts: np.ndarray | None = field(default=None, repr=False)
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
        return (self.faces.nbytes + self.edges.nbytes + self.edge_faces.nbytes + extra
                + self.nbytes_given)

    def orient(self, vertices: np.ndarray) -> None:
        """Turn each part of a mesh wound again outward (see :attr:`parts`), with the first
        vertices it is given (a body that deforms keeps which way its parts face)."""
        if self.parts is None:
            return
        flip_faces(self.faces, self.edge_faces, outward_flips(vertices, self.faces, self.parts))
        self.parts = None

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

    @property
    def nbytes_given(self) -> int:
        return 0 if self.as_given is None else self.as_given.nbytes

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
    boundary = int(np.count_nonzero(counts == 1))
    nonmanifold = int(np.count_nonzero(counts > 2))
    unbalanced = int(np.count_nonzero(2 * forward_per_edge != counts))
    edge_faces = inverse.astype(np.int64)
    rewound, as_given, parts = 0, None, None
    if misoriented and not boundary and not nonmanifold:
        # Closed, but wound inconsistently: wound again (outward once its vertices are known).
        found = consistent_flips(faces, edge_faces)
        if found is not None:
            flip, parts = found
            as_given = faces
            faces = faces.copy()
            flip_faces(faces, edge_faces, flip)
            rewound, misoriented, unbalanced = misoriented, 0, 0
    return Topology(
        faces=faces,
        edges=edges,
        edge_faces=edge_faces,
        n_vertices=int(n_vertices),
        boundary_edges=boundary,
        nonmanifold_edges=nonmanifold,
        misoriented_edges=misoriented,
        unbalanced_edges=unbalanced,
        dropped_faces=dropped,
        kept=kept,
        dropped=dropped_rows,
        rewound=rewound,
        as_given=as_given,
        parts=parts,
    )


@dataclass(frozen=True)
class MeshProblem:
    """One body's problem of one kind (see :func:`mesh_problems`)."""

    kind: str
    """A key of :data:`PROBLEMS`."""
    label: str
    """The body, as errors name it."""
    detail: str
    """What it has (``"2 boundary edges (holes)"``)."""


@dataclass(frozen=True)
class ProblemKind:
    """How a kind of problem is told: what one body (``one``) or several (``many``) are, the
    rule applied to them, the repair, and the warning's category."""

    one: str
    many: str
    rule: str
    repair: str
    category: type[MeshWarning]
    short: str
    """The rule in a few words, for the summary line."""


PROBLEMS: dict[str, ProblemKind] = {
    "surface": ProblemKind(
        "is not a closed, consistently oriented surface",
        "are not closed, consistently oriented surfaces",
        "each is tested as a surface: a pair is reported where its surface crosses the other "
        "body's surface, or lies inside another body that is a closed solid; nothing is ever "
        "found inside it",
        "Repair them (trimesh.repair.fill_holes, pymeshlab's close holes) to test them as "
        "solids", OpenMeshWarning, "tested as surfaces"),
    "balanced": ProblemKind(
        "is not a closed, consistently oriented surface",
        "are not closed, consistently oriented surfaces",
        "each is tested as a solid all the same: every edge is walked equally often both ways, "
        "so its inside is well defined",
        "Repair them (trimesh.repair.fill_holes, pymeshlab's close holes) to make them closed",
        OpenMeshWarning, "tested as solids all the same (their edges balance)"),
    "rewound": ProblemKind(
        "is closed but was wound inconsistently",
        "are closed but were wound inconsistently",
        "each was wound again, every part outward, and is tested as a solid",
        "Wind them consistently where they are made (trimesh.repair.fix_winding and "
        "fix_inversion) to pass them as they are tested", RewoundMeshWarning,
        "wound again, outward, and tested as solids"),
    "inverted": ProblemKind(
        "is closed but wound inside out (its volume is negative)",
        "are closed but wound inside out (their volumes are negative)",
        "collisions are still found (the ray count of its inside is -1, not 0), but its "
        "normals, and so contact normals, point inwards",
        "Flip them (trimesh's mesh.invert())", OpenMeshWarning,
        "tested as solids, their normals inwards"),
    "degenerate": ProblemKind(
        "has degenerate faces", "have degenerate faces",
        "faces that repeat a vertex index are dropped and faces of zero area ignored (they "
        "bound nothing and cross no ray)",
        "Remove them with trimesh's mesh.update_faces(mesh.nondegenerate_faces())",
        DegenerateFaceWarning, "those faces dropped or ignored"),
}
"""Every kind of mesh problem, and how it is told."""

SHOWN = 5
"""Most bodies a summary names (its warning's ``bodies`` lists them all)."""


def mesh_problems(topo: Topology, zero_area: int, label: str, strict: bool,
                  inverted: bool = False) -> list[MeshProblem]:
    """What is wrong with a body's mesh, each with the rule applied to it
    (:data:`PROBLEMS`); with ``strict``, a ValueError for the first instead (its message says
    only what is wrong and how to repair it)."""
    found = []
    if not topo.closed:
        found.append(MeshProblem("balanced" if topo.solid else "surface", label, topo.problem()))
    elif topo.rewound:
        found.append(MeshProblem("rewound", label, f"{topo.rewound} edges walked the same way "
                                 "by their two faces"))
    elif inverted:
        found.append(MeshProblem("inverted", label, "its volume is negative"))
    degenerate = []
    if topo.dropped_faces:
        degenerate.append(f"{topo.dropped_faces} faces repeat a vertex index")
    if zero_area:
        degenerate.append(f"{zero_area} faces have zero area")
    if degenerate:
        found.append(MeshProblem("degenerate", label, " and ".join(degenerate)))
    if strict and found:
        first = found[0]
        kind = PROBLEMS[first.kind]
        raise ValueError(f"{first.label} {kind.one}: {first.detail}. {kind.repair}.")
    return found


def warn_problems(problems: list[MeshProblem]) -> None:
    """One warning per kind of problem, however many bodies have it: the first
    :data:`SHOWN` bodies by name and what each has, the rule applied and the repair; the
    warning's ``bodies`` and ``details`` list every one."""
    by_kind: dict[str, list[MeshProblem]] = {}
    for problem in problems:
        by_kind.setdefault(problem.kind, []).append(problem)
    for name, found in by_kind.items():
        kind = PROBLEMS[name]
        if len(found) == 1:
            what = f"{found[0].label} {kind.one}: {found[0].detail}"
        else:
            named = ", ".join(f"{p.label} ({p.detail})" for p in found[:SHOWN])
            more = (f", and {len(found) - SHOWN} more (the warning's bodies list them all)"
                    if len(found) > SHOWN else "")
            what = f"{len(found)} bodies {kind.many}: {named}{more}"
        message = (f"{what}; {kind.rule}. {kind.repair}, or ask for strict checking to make "
                   "this an error.")
        many = (f"{len(found)} bodies {kind.many}" if len(found) > 1
                else f"1 body {kind.one}")
        warn_at_caller(kind.category(message, [p.label for p in found],
                                     [p.detail for p in found], f"{many}: {kind.short}"))


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
        kept_faces = topo.faces if topo.as_given is None else topo.as_given
        if topo.kept is None:
            return np.array_equal(kept_faces, faces)
        if len(faces) != len(topo.kept) + topo.dropped_faces:
            return False
        given = np.ones(len(faces), dtype=bool)
        given[topo.kept] = False
        return np.array_equal(kept_faces, faces[topo.kept]) \
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

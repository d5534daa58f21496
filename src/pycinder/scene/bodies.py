"""Bodies in, a validated :class:`Scene` out.

A body is a triangle mesh (a ``trimesh.Trimesh`` or a ``(vertices, faces)`` pair) plus a
world-from-body transform. Bodies that share one vertex array and one face array (250 copies of
one sphere) share one :class:`Shape`, so each mesh is checked, measured and uploaded once.

Shapes are cached across calls by content, like topologies: a rigid body passed again costs a
lookup (trimesh meshes carry their own content hash) or one hash of its vertex bytes and one
comparison with a copy of them (plain arrays, of any dtype, so arrays edited in place are seen;
see :func:`_vertex_key`), never a new check. The cache keeps the
shapes of the current and the previous query, whatever their size, and others only within its
byte bound: a body that deforms every frame replaces its shape instead of piling them up. Such a
body is not hashed once it has changed (see :meth:`ShapeCache.get_many`): it is checked and
measured (:mod:`.vertices`) into memory that no shape uses any more, and compared with its last
shape.

Precision: a shape's vertices are stored in single precision relative to the centre of their
box (computed in double precision), and that centre is folded into the body's transform, so a
mesh stored far from its own origin keeps its detail. Extents up to :data:`MAX_EXTENT` are
supported; every computation on the host that squares a length runs in double precision.
"""

from __future__ import annotations

import secrets
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import xxhash

from ..util import threads
from ..util.arrays import det3, sum3
from .normals import face_normals, signed_volume, vertex_and_edge_normals
from .topology import (DEFAULT_CACHE_BYTES, MeshProblem, Topology, TopologyCache, mesh_problems,
                       warn_problems)
from .vertices import MAX_EXTENT, VertexMemory, bounding_radius, check_vertices
from .vertices import measure as _measure

PARALLEL_BYTES = 1 << 20
"""Vertex bytes of a query's large bodies (see :data:`PARALLEL_ITEM_BYTES`) from which they are
hashed and measured on several threads (NumPy and xxhash release the GIL on arrays this
large)."""
PARALLEL_ITEM_BYTES = 1 << 16
"""Vertex bytes from which a body is large enough to be hashed and measured on another thread:
a small body's cost is Python's own, which threads do not share (1,000 bodies of 642 vertices
validated in 21.7 ms on a pool of two threads, 12.0 ms on one)."""


def _map(fn: Any, items: list, sizes: list[int]) -> list:
    """``[fn(*item) for item in items]``. Items of at least :data:`PARALLEL_ITEM_BYTES` (their
    ``sizes``, in vertex bytes) holding :data:`PARALLEL_BYTES` or more together run on a thread
    pool, in one contiguous chunk of about equal bytes per thread, while this thread runs the
    small ones (whose cost is Python's, under the GIL: a task each would cost more than their
    work). The first exception, in item order, is raised."""
    workers = threads.pool()
    big = [i for i, size in enumerate(sizes) if size >= PARALLEL_ITEM_BYTES]
    big_bytes = sum(sizes[i] for i in big)
    if len(big) < 2 or big_bytes < PARALLEL_BYTES or workers is None:
        return [fn(*item) for item in items]
    # Cut the large items where their running byte count passes each worker's share.
    share = big_bytes * np.arange(1, threads.WORKERS) / threads.WORKERS
    ends = np.searchsorted(np.cumsum([sizes[i] for i in big]), share, "right")
    bounds = [0, *sorted({int(e) for e in ends if 0 < e < len(big)}), len(big)]

    def run(which: list[int]) -> list[tuple[bool, Any]]:
        out = []
        for i in which:
            try:
                out.append((True, fn(*items[i])))
            except Exception as exc:  # raised below, in item order
                out.append((False, exc))
        return out

    futures = [workers.submit(run, big[lo:hi]) for lo, hi in zip(bounds[:-1], bounds[1:])]
    small = sorted(set(range(len(items))) - set(big))
    done = dict(zip(small, run(small)))
    for f, lo, hi in zip(futures, bounds[:-1], bounds[1:]):
        done.update(zip(big[lo:hi], f.result()))
    for i in range(len(items)):
        ok, value = done[i]
        if not ok:
            raise value
    return [done[i][1] for i in range(len(items))]


def _array(values: Any, label: str) -> np.ndarray:
    """``np.asarray(values)``, its failure (ragged rows) worded with the body's label."""
    try:
        return np.asarray(values)
    except ValueError as exc:
        raise ValueError(f"{label}: vertices must be a (V, 3) array of numbers ({exc})") from None


def body_label(index: int, name: str | None) -> str:
    return f"body {index}" + (f" ({name!r})" if name else "")


@dataclass(eq=False)
class Shape:
    """One distinct mesh: its vertices in body space and what is derived from them.

    Attributes
    ----------
    vertices : (V, 3) float32
        Vertices relative to ``offset``.
    topology : Topology
    offset : (3,) float64
        The body-space point the stored vertices are relative to (the centre of their box).
    lo, hi : (3,) float64
        Bounding box of ``vertices`` (relative to ``offset``).
    radius : float
        Radius of the bounding sphere about the box's centre (measured when first asked for,
        when it was not given).
    """

    vertices: np.ndarray
    topology: Topology
    offset: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    _radius: float | None = field(default=None, repr=False)
    _normals: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    _face_normals: np.ndarray | None = field(default=None, repr=False)

    @property
    def centre(self) -> np.ndarray:
        return 0.5 * (self.lo + self.hi)

    @property
    def radius(self) -> float:
        if self._radius is None:
            self._radius = bounding_radius(self.vertices, self.lo, self.hi)
        return self._radius

    @property
    def nbytes(self) -> int:
        extra = sum(a.nbytes for a in self._normals) if self._normals is not None else 0
        if self._face_normals is not None:
            extra += self._face_normals.nbytes
        return self.vertices.nbytes + extra

    def face_normals(self) -> np.ndarray:
        """Unit face normals (F, 3) float32 of this pose, one per face as given (zero for faces
        dropped as degenerate)."""
        if self._face_normals is None:
            normals = face_normals(self.vertices, self.topology.faces)[0]
            self._face_normals = self.topology.given_faces(normals)
        return self._face_normals

    def normals(self) -> tuple[np.ndarray, np.ndarray]:
        """Vertex normals (V, 3) and edge normals (E, 3) of this pose, float32."""
        if self._normals is None:
            self._normals = vertex_and_edge_normals(self.vertices, self.topology)
        return self._normals


def mesh_arrays(body: Any, label: str) -> tuple[Any, Any]:
    """(vertices, faces) of a trimesh.Trimesh or a (vertices, faces) pair, as given."""
    if hasattr(body, "vertices") and hasattr(body, "faces"):
        return body.vertices, body.faces
    if isinstance(body, (tuple, list)) and len(body) == 2:
        return body[0], body[1]
    raise TypeError(
        f"{label}: expected a trimesh.Trimesh or a (vertices, faces) pair, got {type(body).__name__}"
    )


def check_transforms(transforms: Any, n: int, names: Sequence[str | None]) -> np.ndarray:
    """World-from-body matrices, checked.

    Parameters
    ----------
    transforms : None or (N, 4, 4) float
    n : int
        Number of bodies.
    names : sequence of str or None
        Body names for messages.

    Returns
    -------
    (N, 4, 4) float64
    """
    if transforms is None:
        return np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    try:
        t = np.array(transforms, dtype=np.float64)  # a copy: the scene folds offsets into it
    except (TypeError, ValueError) as exc:
        raise ValueError(f"transforms must be (N, 4, 4) numbers: {exc}") from exc
    if t.shape != (n, 4, 4):
        raise ValueError(f"transforms must have shape ({n}, 4, 4), one per body; got {t.shape}")
    # Each test runs over the whole array at once (a reduction along a row of 16 numbers per
    # body is several times slower); the first body that fails is found only when one does.
    if not np.isfinite(t).all():
        i = int(np.flatnonzero(~np.isfinite(t).reshape(n, 16).all(axis=1))[0])
        raise ValueError(f"{body_label(i, names[i])}: transform contains NaN or infinite values")
    bottom = np.abs(t[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])) > 1e-9
    if bottom.any():
        i = int(np.flatnonzero(bottom.any(axis=1))[0])
        raise ValueError(
            f"{body_label(i, names[i])}: transform is not affine (last row must be [0, 0, 0, 1])"
        )
    det = det3(t[:, :3, :3])
    odd = ~np.isfinite(det)  # a product overflowed (extreme scales): LU's determinant there
    if odd.any():
        det[odd] = np.linalg.det(t[odd, :3, :3])
    if (np.abs(det) < 1e-300).any() or not np.isfinite(det).all():
        i = int(np.flatnonzero((np.abs(det) < 1e-300) | ~np.isfinite(det))[0])
        raise ValueError(f"{body_label(i, names[i])}: transform is singular (it flattens the body)")
    far = np.abs(t[:, :3, :]) > MAX_EXTENT
    if far.any():
        i = int(np.flatnonzero(far.reshape(n, 12).any(axis=1))[0])
        raise ValueError(f"{body_label(i, names[i])}: transform moves or scales the body beyond "
                         f"{MAX_EXTENT:g} units; rescale the scene")
    return t


_SEED = secrets.randbits(64)
"""The seed of this process's vertex hashes: unknown outside it, so content cannot be made to
collide on purpose without reading the process's memory."""


def _digest(data: Any) -> bytes:
    """128-bit XXH3 hash of a buffer's bytes (seeded with :data:`_SEED`)."""
    return xxhash.xxh3_128_digest(data, _SEED)


def _vertex_key(vertices: Any) -> tuple[tuple, np.ndarray | None]:
    """A content key for a vertex array, and the array whose bytes a cached shape's copy is
    compared with.

    A TrackedArray (trimesh's) is keyed by trimesh's own hash of it (nothing to compare: trimesh
    tracks its edits). Other arrays are keyed by the 128-bit XXH3 hash of their bytes with their
    shape and dtype, so an array edited in place, of any dtype, gets a new key, and an equal
    array (a new object of the same content) gets the same key. XXH3 reads memory about as fast
    as a copy (0.02 ms for a bunny's 674 kB, where the BLAKE2b used before took 1.3 ms). It is
    not a cryptographic hash, so a key is not taken on its word: :class:`ShapeCache` keeps a
    copy of the bytes each shape was made from and compares it on a hit (a copy and a
    ``memcmp``: 0.04 ms for a bunny, 1 µs for a small body), so a collision (2**-128 for two
    given arrays, and seeded per process, so not one that can be made on purpose) costs a new
    shape, never a wrong one."""
    if type(vertices).__name__ == "TrackedArray":
        return ("tracked", hash(vertices), vertices.shape), None
    v = np.ascontiguousarray(vertices)
    return ("array", _digest(v), v.shape, v.dtype.str), v


def _same_bytes(kept: bytes | np.ndarray | None, v: np.ndarray | None) -> bool:
    """Whether ``v`` (from :func:`_vertex_key`) holds exactly the bytes ``kept`` (a cached
    shape's copy: ``bytes``, or a flat uint8 array for large arrays, see :func:`_kept_copy`;
    None for tracked arrays, whose keys are trimesh's). With equal keys, equal bytes are equal
    content: the key holds the shape and the dtype."""
    if kept is None or v is None:
        return kept is None and v is None
    if isinstance(kept, np.ndarray):
        if kept.nbytes != v.nbytes:
            return False
        mine, theirs = kept, _flat_bytes(v)
        if kept.nbytes % 8 == 0:  # compared as 64-bit words: a bitwise comparison all the same
            mine, theirs = mine.view(np.uint64), theirs.view(np.uint64)
        return bool(np.array_equal(mine, theirs))
    return v.tobytes() == kept


def _flat_bytes(v: np.ndarray) -> np.ndarray:
    """The bytes of a C-contiguous array, as a flat uint8 view."""
    return v.reshape(-1).view(np.uint8)


KEPT_ARRAY_BYTES = PARALLEL_ITEM_BYTES
"""Vertex bytes from which a shape's kept copy (see :class:`ShapeCache`) is a NumPy array,
copied on the thread that measures the shape, into the memory of a copy dropped at the end of
the last query when one of that size was (a body that deforms every frame reuses its copies
instead of mapping fresh memory for each: the page faults cost more than the copy), rather than
a ``bytes`` object."""


def _measure_kept(vertices: Any, label: str, bits: np.ndarray | None,
                  into: np.ndarray | None, out: np.ndarray | None = None
                  ) -> tuple[tuple, bytes | np.ndarray | None]:
    """:func:`_measure` (its vertices written into ``out`` when given), and the copy of
    ``bits`` (from :func:`_vertex_key`) a new cached shape keeps (see :func:`_kept_copy`), made
    in ``into`` when given (a spare of the right size)."""
    return _measure(vertices, label, out), _kept_copy(bits, into)


def _same_geometry(shape: Shape, measure: tuple) -> bool:
    """Whether measured vertices (from :func:`_measure`) are ``shape``'s, bit for bit: the same
    single-precision vertices, offset and box (the rest follows from them)."""
    v32, offset, lo, hi, _ = measure
    return (v32.shape == shape.vertices.shape and offset.tobytes() == shape.offset.tobytes()
            and lo.tobytes() == shape.lo.tobytes() and hi.tobytes() == shape.hi.tobytes()
            and np.array_equal(v32.view(np.uint32), shape.vertices.view(np.uint32)))


@dataclass
class _Slot:
    """A mesh of the last :meth:`ShapeCache.get_many` call: its topology, the key and shape it
    got, and whether that shape was another than the one before it at the same place (its
    vertices changed)."""

    topology: Topology
    key: tuple
    shape: Shape
    changed: bool


def _kept_copy(bits: np.ndarray | None, into: np.ndarray | None = None
               ) -> bytes | np.ndarray | None:
    """The copy of the bytes a cached shape was made from: None for tracked arrays, ``bytes``
    below :data:`KEPT_ARRAY_BYTES`, else a flat uint8 array (``into``, when given)."""
    if bits is None:
        return None
    if bits.nbytes < KEPT_ARRAY_BYTES:
        return bits.tobytes()
    if into is None:
        into = np.empty(bits.nbytes, dtype=np.uint8)
    np.copyto(into, _flat_bytes(bits))
    return into


class ShapeCache:
    """Shapes by content: those of the current and the previous query (what rigid reuse needs),
    and topologies by face content within a byte bound.

    Parameters
    ----------
    max_bytes : int
        Memory the cached topologies may hold beyond those of the last two queries (half of it;
        the other half is left to the shapes, for compatibility).
    """

    def __init__(self, max_bytes: int = DEFAULT_CACHE_BYTES) -> None:
        self.topologies = TopologyCache(max_bytes // 2)
        self.max_bytes = int(max_bytes) - self.topologies.max_bytes
        self._entries: OrderedDict[tuple, Shape] = OrderedDict()
        self._kept: dict[tuple, bytes | np.ndarray | None] = {}  # what each shape was made from
        self._spare: dict[int, list[np.ndarray]] = {}  # large copies dropped by the last query
        self._used: dict[tuple, int] = {}
        self._slots: list[_Slot] = []  # the last call's meshes, in its order
        self._serial = 0
        self.memory = VertexMemory()
        """Where new shapes' vertices are written (see :class:`~.vertices.VertexMemory`)."""
        self.query = 0
        self.nbytes = 0

    def __len__(self) -> int:
        return len(self._entries)

    def begin_query(self) -> None:
        """Start a query: shapes used from now on are kept until the next query ends."""
        self.query += 1
        self.topologies.query = self.query

    def end_query(self) -> None:
        """Drop the shapes of neither this query nor the previous one (a body that deforms
        leaves one shape behind per frame: they go at once), then topologies while over the byte
        bound."""
        keep_from = self.query - 1
        self._spare = {}  # the last query's spares that this one did not reuse go
        for key in [k for k, q in self._used.items() if q < keep_from]:
            self._drop(key)
        self.topologies.evict()

    def _drop(self, key: tuple) -> None:
        kept = self._kept.pop(key)
        self.nbytes -= self._entries.pop(key).nbytes + (len(kept) if kept is not None else 0)
        del self._used[key]
        if isinstance(kept, np.ndarray):
            self._spare.setdefault(kept.nbytes, []).append(kept)

    def _spare_copy(self, bits: np.ndarray | None) -> np.ndarray | None:
        """A dropped copy of the size of ``bits``, to copy ``bits`` into (None: none, or a copy
        that is not an array)."""
        if bits is None or bits.nbytes < KEPT_ARRAY_BYTES:
            return None
        spares = self._spare.get(bits.nbytes)
        return spares.pop() if spares else None

    def get(self, vertices: Any, faces: Any, label: str, strict: bool) -> Shape:
        """The shape of a mesh, checked and measured once per distinct content."""
        return self.get_many([(vertices, faces, label)], strict)[0]

    def get_many(self, meshes: list[tuple[Any, Any, str]], strict: bool, keep: bool = True,
                 topologies: Sequence[Topology | None] | None = None) -> list[Shape]:
        """The shapes of meshes ``(vertices, faces, label)``, in order (see :meth:`get`). Their
        vertices are hashed, checked and measured on several threads when they are large; a
        cached shape is reused when the key matches and the vertices' bytes equal the copy kept
        with it (see :func:`_vertex_key`). Faces given for several meshes (one array object)
        are looked up once.

        A mesh at the same place in the list as in the last call, with the same faces, whose
        vertices changed then (a body that deforms) is taken to change again: it is measured
        without a hash or a kept copy, and compared with the last call's shape, which it keeps
        when they are equal (then it is hashed again from the next call on).

        ``keep=False``: new vertices, by the caller's word (:meth:`PreparedBodies.update`): they
        are not hashed or looked up (an array given twice makes one shape), and the shapes made
        are not cached (their caller holds them), so a loop that makes them outside of queries
        leaves nothing behind.

        ``topologies``: per mesh, the topology its faces are known to have (None: look it up),
        used where it indexes as many vertices as the mesh has; its faces are then neither
        looked up nor compared (:meth:`PreparedBodies.update`: a body whose face array is the one
        its topology was found from)."""
        given, topos = [], []
        looked: dict[tuple[int, int], Topology] = {}
        for m, (vertices, faces, label) in enumerate(meshes):
            v = vertices if type(vertices).__name__ == "TrackedArray" else _array(vertices, label)
            if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0 or v.dtype.kind not in "iuf":
                check_vertices(v, label)  # raises with the message for the shape or dtype
            given.append(v)
            known = topologies[m] if topologies is not None else None
            if known is not None and known.n_vertices == len(v):
                topos.append((known, False))
                continue
            seen = looked.get((id(faces), len(v)))
            if seen is None:
                topos.append(self.topologies.get(faces, len(v), label))
                looked[(id(faces), len(v))] = topos[-1][0]
            else:
                topos.append((seen, False))
        sizes = [v.nbytes for v in given]
        slots = self._slots if keep else []
        changing = [i < len(slots) and slots[i].topology is topo and slots[i].changed
                    for i, (topo, _) in enumerate(topos)]
        keyed: list[tuple[tuple, np.ndarray | None]]
        if keep:
            hashed = [i for i in range(len(given)) if not changing[i]]
            found = iter(_map(_vertex_key, [(given[i],) for i in hashed],
                              [sizes[i] for i in hashed]))
            keyed = [(("changing", self._next_serial()), None) if changing[i] else next(found)
                     for i in range(len(given))]
        else:
            keyed = [(("given", id(v)), None) for v in given]
        out: list[Shape | None] = [None] * len(meshes)
        keys: list[tuple] = [()] * len(meshes)
        missing: dict[tuple, list[int]] = {}  # new content: the meshes that have it
        for i, ((topo, _), (key, bits)) in enumerate(zip(topos, keyed)):
            key = (id(topo), key)
            shape = self._entries.get(key)
            if shape is not None and shape.topology is topo \
                    and _same_bytes(self._kept[key], bits):
                self._entries.move_to_end(key)
                self._used[key] = self.query
                out[i], keys[i] = shape, key
                continue
            where = missing.get(key)
            first = keyed[where[0]][1] if keep and where is not None else None
            if first is not None and not _same_bytes(first.tobytes(), bits):
                key = (*key, ("collision", i))  # equal keys, other bytes: a shape of its own
            missing.setdefault(key, []).append(i)
        problems: list[MeshProblem] = []
        first = [where[0] for where in missing.values()]
        # New shapes' vertices go into memory that dropped shapes no longer use.
        into = [self.memory.take(len(given[i])) for i in first]
        if keep:
            # The copies new shapes keep are made with their measuring, on its threads.
            measured = _map(_measure_kept, [(given[i], meshes[i][2], keyed[i][1],
                                             self._spare_copy(keyed[i][1]), o)
                                            for i, o in zip(first, into)],
                            [sizes[i] for i in first])
        else:
            measured = [(m, None) for m in _map(_measure, [(given[i], meshes[i][2], o)
                                                           for i, o in zip(first, into)],
                                                [sizes[i] for i in first])]
        del into
        changed = [False] * len(meshes)
        for (key, where), (measure, kept) in zip(missing.items(), measured):
            i = where[0]
            topo, built = topos[i]
            last = slots[i].shape if i < len(slots) and slots[i].topology is topo else None
            if last is not None and _same_geometry(last, measure):
                # The same shape as the last call's here (taken to deform, or given another
                # key: a trimesh mesh after arrays): kept, not uploaded again.
                if changing[i]:
                    key = self._rekeyed(slots[i].key, last, given[i])
                    shape = last
                else:
                    shape = self._made(key, topo, built, measure, meshes[i][2], strict,
                                       problems, keep, kept)
            else:
                shape = self._made(key, topo, built, measure, meshes[i][2], strict, problems,
                                   keep, kept)
                changed[i] = last is not None
            for i in where:
                out[i], keys[i] = shape, key
        if keep:
            self._slots = [_Slot(topo, key, shape, moved) for (topo, _), key, shape, moved
                           in zip(topos, keys, out, changed)]
        warn_problems(problems)
        return out  # type: ignore[return-value]

    def _next_serial(self) -> int:
        self._serial += 1
        return self._serial

    def _rekeyed(self, old: tuple, shape: Shape, vertices: np.ndarray) -> tuple:
        """Cache ``shape`` (under ``old`` when it still is) under the key of ``vertices``' content
        instead, with a copy of them: a body taken to deform that did not (see
        :meth:`get_many`), hashed again from the next call on. Returns the new key."""
        if self._entries.get(old) is shape:
            self._drop(old)
        content, bits = _vertex_key(vertices)
        key = (id(shape.topology), content)
        if key in self._entries:
            self._drop(key)
        kept = _kept_copy(bits, self._spare_copy(bits))
        self._entries[key] = shape
        self._kept[key] = kept
        self._used[key] = self.query
        self.nbytes += shape.nbytes + (len(kept) if kept is not None else 0)
        return key

    def _made(self, key: tuple, topo: Topology, built: bool, measure: tuple, label: str,
              strict: bool, problems: list[MeshProblem], keep: bool = True,
              kept: bytes | np.ndarray | None = None) -> Shape:
        """A new shape of ``topo`` from its measured vertices, its problems added to
        ``problems`` (when its topology is new) and cached under ``key`` (when ``keep``) with
        ``kept``, the copy of the bytes it was made from (see :func:`_vertex_key` and
        :func:`_kept_copy`). A topology wound again is turned outward with these vertices."""
        v32, offset, lo, hi, radius = measure
        topo.orient(v32)
        if built:
            _, areas = face_normals(v32, topo.faces)
            inverted = topo.closed and signed_volume(v32, topo.faces) < 0
            problems += mesh_problems(topo, int(np.count_nonzero(areas <= 0)), label, strict,
                                      inverted)
            before = topo.nbytes
            topo.clusters(v32)
            self.topologies.account(topo, topo.nbytes - before)
        shape = Shape(v32, topo, offset, lo, hi, radius)
        if not keep:
            return shape
        if key in self._entries:
            self._drop(key)
        self._entries[key] = shape
        self._kept[key] = kept
        self._used[key] = self.query
        self.nbytes += shape.nbytes + (len(kept) if kept is not None else 0)
        return shape


@dataclass(eq=False)
class Scene:
    """Validated bodies of one query.

    Attributes
    ----------
    shapes : list of Shape
        The distinct meshes.
    body_shape : (N,) int64
        Each body's shape.
    transforms : (N, 4, 4) float64
        World from body, where body coordinates are those of the shapes' stored vertices (the
        transforms given, with each shape's offset folded in).
    names : list of str or None
    boxes : ((N, 3), (N, 3)) float64 or None
        World boxes given with the bodies (see below); None: measured.
    """

    shapes: list[Shape]
    body_shape: np.ndarray
    transforms: np.ndarray
    names: list[str | None]
    _radii: np.ndarray | None = field(default=None, repr=False)
    _centres: np.ndarray | None = field(default=None, repr=False)
    per_body: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    """Per-body arrays taken from the shapes (:attr:`local_lo`, :attr:`face_counts`, ...), made
    on first use; prepared bodies share one dict across the scenes of their queries (the shapes
    and ``body_shape`` of a scene never change)."""
    boxes: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    """World boxes (N, 3) minimum and maximum known to hold every body, made by whoever placed
    the bodies (a robot check's pass K1, :mod:`pycinder.robot.k1_kinematics`): :meth:`world_boxes`
    gives them instead of measuring its own; None: measured."""

    def __len__(self) -> int:
        return len(self.body_shape)

    def label(self, i: int) -> str:
        return body_label(i, self.names[i])

    def shape_of(self, i: int) -> Shape:
        return self.shapes[int(self.body_shape[i])]

    def _per_shape(self, name: str, value: Callable[[Shape], Any]) -> np.ndarray:
        """``value`` of every body's shape (N, ...), kept in :attr:`per_body` under ``name``.
        Read-only: the arrays are shared."""
        out = self.per_body.get(name)
        if out is None:
            out = np.asarray([value(s) for s in self.shapes])[self.body_shape]
            out.flags.writeable = False
            self.per_body[name] = out
        return out

    @property
    def local_lo(self) -> np.ndarray:
        """(N, 3) body-space box minimum of every body."""
        return self._per_shape("local_lo", lambda s: s.lo)

    @property
    def local_hi(self) -> np.ndarray:
        """(N, 3) body-space box maximum of every body."""
        return self._per_shape("local_hi", lambda s: s.hi)

    @property
    def face_counts(self) -> np.ndarray:
        """(N,) faces of every body (as tested: faces repeating a vertex left out)."""
        return self._per_shape("face_counts", lambda s: len(s.topology.faces))

    @property
    def open(self) -> np.ndarray:
        """(N,) whether each body is not a solid (tested as a surface, see
        :attr:`~pycinder.scene.Topology.solid`)."""
        return self._per_shape("open", lambda s: not s.topology.solid)

    @property
    def radius(self) -> np.ndarray:
        """(N,) radius of every body's body-space bounding sphere about its box's centre."""
        return self._per_shape("radius", lambda s: s.radius)

    def box_centres(self) -> np.ndarray:
        """(N, 3) the world centre of every body's body-space box, made once a scene (its
        world box and its tolerance's floor both start from it)."""
        if self._centres is None:
            centres = np.einsum("nij,nj->ni", self.transforms[:, :3, :3],
                                0.5 * (self.local_lo + self.local_hi)) + self.transforms[:, :3, 3]
            centres.flags.writeable = False  # shared by every reader
            self._centres = centres
        return self._centres

    def bounding_radii(self) -> np.ndarray:
        """(N,) a radius about every body's box centre that holds the body, as its measured
        world box uses it (see :meth:`world_boxes`)."""
        if self._radii is None:
            self._measured_boxes()
        return self._radii  # type: ignore[return-value]

    def world_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) world box minimum and maximum of every body: :attr:`boxes` where given, else
        measured (:meth:`_measured_boxes`)."""
        if self.boxes is not None:
            return self.boxes
        return self._measured_boxes()

    def _measured_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) world box minimum and maximum of every body: :func:`world_boxes` of its box
        and a radius that holds it (:meth:`bounding_radii`), its bounding sphere's
        (:attr:`Shape.radius`) where a sphere could tighten the world box, else the half
        diagonal of its box, which holds the body too and needs no measuring.

        A sphere whose radius is at least the largest half extent of the box is no tighter than
        the box along any world axis unless the transform turns the body off its axes (not one
        that only moves, mirrors or scales it along them); the bounding sphere's radius and the
        half diagonal are at least that, so either gives the box's own world box, bit for bit.
        """
        lo, hi = self.local_lo, self.local_hi
        t3 = self.transforms[:, :3, :3]
        centre = self.box_centres()
        extent = 0.5 * (hi - lo)
        box = np.einsum("nij,nj->ni", np.abs(t3), extent)
        # Sums and maxima over an axis of 3 as NumPy reduces it ((x0 + x1) + x2), written out:
        # a reduction along so short an axis is several times slower, and the bits are the same.
        squares = t3 * t3
        rows = np.sqrt(sum3(squares))
        largest = np.maximum(np.maximum(extent[:, 0], extent[:, 1]), extent[:, 2])
        shorter = largest[:, None] * rows < box
        tighter = np.flatnonzero(shorter[:, 0] | shorter[:, 1] | shorter[:, 2])
        radius = np.sqrt(sum3(extent * extent))
        if len(tighter):
            which = np.zeros(len(self.shapes), dtype=bool)
            which[self.body_shape[tighter]] = True
            sphere = np.array([s.radius if w else 0.0 for s, w in zip(self.shapes, which)])
            radius[tighter] = sphere[self.body_shape[tighter]]
        self._radii = radius
        half = np.minimum(box, radius[:, None] * rows)
        return centre - half, centre + half


def _shapes_of(bodies: Sequence[Any], names: list[str | None], cache: ShapeCache, strict: bool
               ) -> tuple[list[Shape], np.ndarray]:
    """The distinct shapes of ``bodies`` and each body's index among them."""
    meshes: list[tuple[Any, Any, str]] = []  # distinct arrays (kept here, so ids stay valid)
    seen: dict[tuple[int, int], int] = {}
    which: list[int] = []
    for i, body in enumerate(bodies):
        # mesh_arrays, with the label made only for a distinct mesh (or the error).
        if hasattr(body, "vertices") and hasattr(body, "faces"):
            vertices, faces = body.vertices, body.faces
        elif (type(body) is tuple or type(body) is list) and len(body) == 2:
            vertices, faces = body
        else:
            vertices, faces = mesh_arrays(body, body_label(i, names[i]))
        key = (id(vertices), id(faces))
        m = seen.get(key)
        if m is None:
            m = seen[key] = len(meshes)
            meshes.append((vertices, faces, body_label(i, names[i])))
        which.append(m)
    shapes: list[Shape] = []
    index: dict[int, int] = {}
    mesh_shape = np.empty(len(meshes), dtype=np.int64)
    for m, shape in enumerate(cache.get_many(meshes, strict)):
        k = index.get(id(shape))
        if k is None:
            k = index[id(shape)] = len(shapes)
            shapes.append(shape)
        mesh_shape[m] = k
    return shapes, mesh_shape[np.array(which, dtype=np.int64)]


def world_edge_normals(scene: Scene, body: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """World-space unit normals of edges given by body and edge index, from the bodies' current
    vertices.

    Parameters
    ----------
    scene : Scene
    body, edge : (n,) int

    Returns
    -------
    (n, 3) float32
    """
    return _world_normals(scene, body, lambda shape, sel: shape.normals()[1][edge[sel]])


def world_face_normals(scene: Scene, body: np.ndarray, face: np.ndarray) -> np.ndarray:
    """World-space unit normals of faces given by body and face index.

    Parameters
    ----------
    scene : Scene
    body, face : (n,) int

    Returns
    -------
    (n, 3) float32
    """
    return _world_normals(scene, body, lambda shape, sel: shape.face_normals()[face[sel]])


def _world_normals(scene: Scene, body: np.ndarray,
                   local_of: Callable[[Any, np.ndarray], np.ndarray]) -> np.ndarray:
    out = np.zeros((len(body), 3), dtype=np.float32)
    if len(body) == 0:
        return out
    # Normals transform with the inverse transpose of the linear part: once per body.
    bodies, which = np.unique(body, return_inverse=True)
    inv_t = np.linalg.inv(scene.transforms[bodies, :3, :3]).transpose(0, 2, 1)
    shape = scene.body_shape[body]
    for k in np.unique(shape):
        sel = shape == k
        local = np.asarray(local_of(scene.shapes[k], sel), dtype=np.float64)
        world = np.einsum("nij,nj->ni", inv_t[which[sel]], local)
        out[sel] = world / np.maximum(np.linalg.norm(world, axis=1, keepdims=True), 1e-30)
    return out


def world_boxes(local_lo: np.ndarray, local_hi: np.ndarray, radius: np.ndarray,
                transforms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World boxes of bodies, recomputed every frame from their transforms in O(N).

    The intersection of two boxes that both hold the body: the world box of its transformed
    body-space box, and that of its transformed bounding sphere (an ellipsoid under scaling,
    whose half-width along world axis i is the radius times the norm of row i of the linear
    part). The second is tight for round bodies, the first for boxy ones.

    Parameters
    ----------
    local_lo, local_hi : (N, 3) float
        Body-space bounding boxes.
    radius : (N,) float
        Radius of each body's bounding sphere about the centre of its box.
    transforms : (N, 4, 4) float
        World-from-body matrices.

    Returns
    -------
    lo, hi : (N, 3) float64
    """
    t3 = transforms[:, :3, :3]
    centre = np.einsum("nij,nj->ni", t3, 0.5 * (local_lo + local_hi)) + transforms[:, :3, 3]
    # Half-widths along world axis i: of the box, |row i| . (its half extents); of the sphere,
    # the radius times |row i|.
    box = np.einsum("nij,nj->ni", np.abs(t3), 0.5 * (local_hi - local_lo))
    half = np.minimum(box, radius[:, None] * np.linalg.norm(t3, axis=2))
    return centre - half, centre + half

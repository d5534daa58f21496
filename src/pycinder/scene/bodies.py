"""Bodies in, a validated :class:`Scene` out.

A body is a triangle mesh (a ``trimesh.Trimesh`` or a ``(vertices, faces)`` pair) plus a
world-from-body transform. Bodies that share one vertex array and one face array (250 copies of
one sphere) share one :class:`Shape`, so each mesh is checked, measured and uploaded once.

Shapes are cached across calls by content, like topologies: a rigid body passed again costs a
lookup (trimesh meshes carry their own content hash) or one hash of its vertex bytes and one
comparison with a copy of them (plain arrays, of any dtype, so arrays edited in place are seen;
see :func:`_vertex_key`), never a new check. The cache keeps the
shapes of the current and the previous query, whatever their size, and others only within its
byte bound: a body that deforms every frame replaces its shape instead of piling them up.

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
from .normals import face_normals, signed_volume, vertex_and_edge_normals
from .topology import DEFAULT_CACHE_BYTES, Topology, TopologyCache, report_problems

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


MAX_EXTENT = 1e30
"""Largest body extent and distance from its own origin, in its own units: single precision (the
GPU's) holds the re-centred vertices with room to spare."""


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
        Radius of the bounding sphere about the box's centre.
    """

    vertices: np.ndarray
    topology: Topology
    offset: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    radius: float
    _normals: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    _face_normals: np.ndarray | None = field(default=None, repr=False)

    @property
    def centre(self) -> np.ndarray:
        return 0.5 * (self.lo + self.hi)

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


BLOCK = 256
"""Vertices per row of the blocked views the vertex checks work on: NumPy is slow along an axis of
3 (a (V, 3) array's rows) and fast along one of 3 * BLOCK, so a C-contiguous (V, 3) array is
seen as (V // BLOCK, 3 * BLOCK) rows of whole vertices, and the rest."""


def _blocks(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A C-contiguous (V, 3) array as (V // BLOCK, 3 * BLOCK) rows and the (V % BLOCK, 3)
    vertices left (views)."""
    m = len(v) - len(v) % BLOCK
    return v[:m].reshape(-1, 3 * BLOCK), v[m:]


def _blocked(v: np.ndarray) -> bool:
    """Whether ``v`` (V, 3) is worth working on in blocks (and can be)."""
    return len(v) >= 2 * BLOCK and v.flags.c_contiguous


def _columns(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-column minimum and maximum of (V, 3), as float64 (NaN where a column has one).

    Column by column (far faster than ``axis=0``), or over blocks of whole vertices (faster
    still); a box with a zero side is taken column by column, as it always was: which of 0.0
    and -0.0 a minimum keeps depends on the order it compares them in."""
    if _blocked(v):
        lo = _column_extreme(np.minimum, v).astype(np.float64)
        hi = _column_extreme(np.maximum, v).astype(np.float64)
        if (lo != 0).all() and (hi != 0).all():
            return lo, hi
    lo = np.array([v[:, k].min() for k in range(3)], dtype=np.float64)
    hi = np.array([v[:, k].max() for k in range(3)], dtype=np.float64)
    return lo, hi


def _column_extreme(op: np.ufunc, v: np.ndarray) -> np.ndarray:
    """``op`` (np.minimum or np.maximum) reduced over each column of a blocked (V, 3) array
    (see :func:`_blocked`): over its rows of whole vertices, the last BLOCK vertices (which
    overlap them: an extreme is the same taken twice), then down to the 3 columns in two steps
    (a reduction along an axis of 3 costs per row)."""
    rows, _ = _blocks(v)
    last = v[len(v) - BLOCK:].reshape(3 * BLOCK)
    per = op(op.reduce(rows, axis=0), last)                          # (3 * BLOCK,)
    per = op.reduce(per.reshape(BLOCK // 16, 48), axis=0)             # 16 vertices a row
    return op.reduce(per.reshape(16, 3), axis=0)


def _recentred(vertices: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """``(vertices - offset).astype(np.float32)`` in one pass (the same float64 difference,
    rounded once)."""
    out = np.empty(vertices.shape, dtype=np.float32)
    if _blocked(vertices):
        rows, tail = _blocks(vertices)
        out_rows, out_tail = _blocks(out)
        np.subtract(rows, np.tile(offset, BLOCK), out=out_rows, casting="unsafe")
        np.subtract(tail, offset, out=out_tail, casting="unsafe")
    else:
        np.subtract(vertices, offset, out=out, casting="unsafe")
    return out


def _squared_distances(v32: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(V,) float64 squared distances of vertices (V, 3) float32 from ``centre``, summed over x,
    y and z in that order."""
    sq = (v32.astype(np.float64) - centre) ** 2
    d2 = sq[:, 0] + sq[:, 1]
    d2 += sq[:, 2]
    return d2


_ONES32 = np.ones(3, dtype=np.float32)


def _farthest(v32: np.ndarray, centre: np.ndarray) -> float:
    """The largest of :func:`_squared_distances`, computed exactly for the vertices that single
    precision finds within 1e-4 of it (the farthest is among them: its squared distance is off
    by a few units of single precision's rounding, 6e-8, the centre being that of the
    vertices' box), and for all of them where single precision could overflow or underflow."""
    if not _blocked(v32):
        return float(_squared_distances(v32, centre).max())
    c32 = centre.astype(np.float32)
    d = np.empty_like(v32)
    rows, tail = _blocks(v32)
    d_rows, d_tail = _blocks(d)
    with np.errstate(over="ignore", under="ignore"):  # such extents take the exact way below
        np.subtract(rows, np.tile(c32, BLOCK), out=d_rows)
        np.subtract(tail, c32, out=d_tail)
        np.multiply(d, d, out=d)
        e = d @ _ONES32  # a few roundings more or less than the sum's: within the margin
    top = float(e.max())
    if not 1e-30 < top < 1e30:
        return float(_squared_distances(v32, centre).max())
    near = np.flatnonzero(e >= top * (1 - 1e-4))
    if 2 * len(near) > len(v32):
        return float(_squared_distances(v32, centre).max())
    return float(_squared_distances(v32[near], centre).max())


def check_vertices(vertices: Any, label: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Checked, re-centred vertices.

    Parameters
    ----------
    vertices : (V, 3) real
    label : str
        How errors name the body.

    Returns
    -------
    v32 : (V, 3) float32
        The vertices minus ``offset``.
    offset : (3,) float64
        Centre of the vertices' box.
    lo, hi : (3,) float64
        Box of ``v32`` (exactly: the float32 values widened).

    Raises
    ------
    ValueError
        Bad shapes or dtypes, NaN or infinite vertices, or an extent or offset beyond
        :data:`MAX_EXTENT`, naming the body.
    """
    vertices = np.asarray(vertices)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"{label}: vertices must have shape (V, 3), got {vertices.shape}")
    if not np.issubdtype(vertices.dtype, np.number) or np.issubdtype(vertices.dtype, np.complexfloating):
        raise ValueError(f"{label}: vertices must be real numbers, got dtype {vertices.dtype}")
    if len(vertices) == 0:
        raise ValueError(f"{label}: the mesh is empty (0 vertices)")
    lo, hi = _columns(vertices)  # NaN and infinities carry through min and max
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        bad = np.flatnonzero(~np.isfinite(vertices).all(axis=1))
        count = "1 vertex is" if len(bad) == 1 else f"{len(bad)} vertices are"
        raise ValueError(f"{label}: {count} NaN or infinite (first: vertex {int(bad[0])}, "
                         "counting from 0)")
    offset = 0.5 * (lo + hi)
    extent = float((hi - lo).max())
    if extent > MAX_EXTENT or float(np.abs(offset).max()) > MAX_EXTENT:
        raise ValueError(f"{label}: vertices span {extent:.3g} units around {offset.tolist()}; "
                         f"pycinder supports bodies up to {MAX_EXTENT:g} units across and from "
                         "their origin: rescale the scene")
    v32 = _recentred(vertices, offset)
    # The box of what the GPU sees, rounding included: rounding and subtracting a constant keep
    # the order of values, so the extremes of v32 are the rounded extremes (but for which zero
    # a minimum keeps, see _columns).
    lo32 = (lo - offset).astype(np.float32).astype(np.float64)
    hi32 = (hi - offset).astype(np.float32).astype(np.float64)
    if (lo32 != 0).all() and (hi32 != 0).all():
        return v32, offset, lo32, hi32
    lo, hi = _columns(v32)
    return v32, offset, lo, hi


def _measure(vertices: Any, label: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                 float]:
    """:func:`check_vertices`, and the radius of the vertices' bounding sphere about their box's
    centre."""
    v32, offset, lo, hi = check_vertices(vertices, label)
    centre = 0.5 * (lo + hi)
    # single-precision rounding of the vertices is far below the box's own size; pad by it
    radius = float(np.sqrt(_farthest(v32, centre))) * (1 + 1e-6)
    return v32, offset, lo, hi, radius


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
    finite = np.isfinite(t).reshape(n, 16).all(axis=1)
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise ValueError(f"{body_label(i, names[i])}: transform contains NaN or infinite values")
    bottom = np.abs(t[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    if (bottom > 1e-9).any():
        i = int(np.flatnonzero(bottom > 1e-9)[0])
        raise ValueError(
            f"{body_label(i, names[i])}: transform is not affine (last row must be [0, 0, 0, 1])"
        )
    det = np.linalg.det(t[:, :3, :3])
    if (np.abs(det) < 1e-300).any() or not np.isfinite(det).all():
        i = int(np.flatnonzero((np.abs(det) < 1e-300) | ~np.isfinite(det))[0])
        raise ValueError(f"{body_label(i, names[i])}: transform is singular (it flattens the body)")
    far = np.abs(t[:, :3, :]).reshape(n, 12).max(axis=1, initial=0.0) > MAX_EXTENT
    if far.any():
        i = int(np.flatnonzero(far)[0])
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
                  into: np.ndarray | None) -> tuple[tuple, bytes | np.ndarray | None]:
    """:func:`_measure`, and the copy of ``bits`` (from :func:`_vertex_key`) a new cached shape
    keeps (see :func:`_kept_copy`), made in ``into`` when given (a spare of the right size)."""
    return _measure(vertices, label), _kept_copy(bits, into)


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

    def get_many(self, meshes: list[tuple[Any, Any, str]], strict: bool, keep: bool = True
                 ) -> list[Shape]:
        """The shapes of meshes ``(vertices, faces, label)``, in order (see :meth:`get`). Their
        vertices are hashed, checked and measured on several threads when they are large; a
        cached shape is reused when the key matches and the vertices' bytes equal the copy kept
        with it (see :func:`_vertex_key`).
        ``keep=False``: new vertices, by the caller's word (:meth:`PreparedBodies.update`): they
        are not hashed or looked up (an array given twice makes one shape), and the shapes made
        are not cached (their caller holds them), so a loop that makes them outside of queries
        leaves nothing behind."""
        given, topos = [], []
        for vertices, faces, label in meshes:
            v = vertices if type(vertices).__name__ == "TrackedArray" else _array(vertices, label)
            if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0 or v.dtype.kind not in "iuf":
                check_vertices(v, label)  # raises with the message for the shape or dtype
            given.append(v)
            topos.append(self.topologies.get(faces, len(v), label))
        sizes = [v.nbytes for v in given]
        keyed = _map(_vertex_key, [(v,) for v in given], sizes) if keep else \
            [(("given", id(v)), None) for v in given]
        out: list[Shape | None] = [None] * len(meshes)
        missing: dict[tuple, list[int]] = {}  # new content: the meshes that have it
        for i, ((topo, _), (key, bits)) in enumerate(zip(topos, keyed)):
            key = (id(topo), key)
            shape = self._entries.get(key)
            if shape is not None and shape.topology is topo \
                    and _same_bytes(self._kept[key], bits):
                self._entries.move_to_end(key)
                self._used[key] = self.query
                out[i] = shape
                continue
            where = missing.get(key)
            first = keyed[where[0]][1] if keep and where is not None else None
            if first is not None and not _same_bytes(first.tobytes(), bits):
                key = (*key, ("collision", i))  # equal keys, other bytes: a shape of its own
            missing.setdefault(key, []).append(i)
        first = [where[0] for where in missing.values()]
        if keep:
            # The copies new shapes keep are made with their measuring, on its threads.
            measured = _map(_measure_kept, [(given[i], meshes[i][2], keyed[i][1],
                                             self._spare_copy(keyed[i][1])) for i in first],
                            [sizes[i] for i in first])
        else:
            measured = [(m, None) for m in _map(_measure, [(given[i], meshes[i][2])
                                                           for i in first],
                                                [sizes[i] for i in first])]
        for (key, where), (measure, kept) in zip(missing.items(), measured):
            topo, built = topos[where[0]]
            shape = self._made(key, topo, built, measure, meshes[where[0]][2], strict, keep,
                               kept)
            for i in where:
                out[i] = shape
        return out  # type: ignore[return-value]

    def _made(self, key: tuple, topo: Topology, built: bool, measure: tuple, label: str,
              strict: bool, keep: bool = True, kept: bytes | np.ndarray | None = None) -> Shape:
        """A new shape of ``topo`` from its measured vertices, reported on (when its topology is
        new) and cached under ``key`` (when ``keep``) with ``kept``, the copy of the bytes it was
        made from (see :func:`_vertex_key` and :func:`_kept_copy`)."""
        v32, offset, lo, hi, radius = measure
        if built:
            _, areas = face_normals(v32, topo.faces)
            inverted = topo.closed and signed_volume(v32, topo.faces) < 0
            report_problems(topo, int(np.count_nonzero(areas <= 0)), label, strict, inverted)
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
    """

    shapes: list[Shape]
    body_shape: np.ndarray
    transforms: np.ndarray
    names: list[str | None]

    def __len__(self) -> int:
        return len(self.body_shape)

    def label(self, i: int) -> str:
        return body_label(i, self.names[i])

    def shape_of(self, i: int) -> Shape:
        return self.shapes[int(self.body_shape[i])]

    def _per_shape(self, values: list[np.ndarray]) -> np.ndarray:
        return np.asarray(values)[self.body_shape]

    @property
    def local_lo(self) -> np.ndarray:
        """(N, 3) body-space box minimum of every body."""
        return self._per_shape([s.lo for s in self.shapes])

    @property
    def local_hi(self) -> np.ndarray:
        """(N, 3) body-space box maximum of every body."""
        return self._per_shape([s.hi for s in self.shapes])

    @property
    def face_counts(self) -> np.ndarray:
        """(N,) faces of every body (as tested: faces repeating a vertex left out)."""
        return self._per_shape([len(s.topology.faces) for s in self.shapes])

    @property
    def open(self) -> np.ndarray:
        """(N,) whether each body is not a solid (tested as a surface, see
        :attr:`~pycinder.scene.Topology.solid`)."""
        return self._per_shape([not s.topology.solid for s in self.shapes])

    @property
    def radius(self) -> np.ndarray:
        """(N,) radius of every body's body-space bounding sphere about its box's centre."""
        return self._per_shape([s.radius for s in self.shapes])

    def world_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) world box minimum and maximum of every body (see
        :func:`world_boxes`)."""
        return world_boxes(self.local_lo, self.local_hi, self.radius, self.transforms)


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

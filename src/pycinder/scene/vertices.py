"""A body's vertices checked and measured: finite, within range, re-centred in single precision,
with their box and bounding sphere (see :func:`check_vertices` and :func:`measure`).

What this costs is what a query with new vertex arrays pays per body (16 deforming bunnies of
28,098 vertices each: about 0.15 ms a bunny, where copying one costs about 0.02 ms into memory
already mapped and 0.2 ms into fresh memory). Each pass runs over blocks of whole vertices
(NumPy is slow along an axis of 3): the column extremes (which also find NaN and infinities, as
they carry through), the re-centred float32 copy (into memory reused from shapes no longer
referred to, see :class:`VertexMemory`, so no fresh pages are faulted in), and the squared
distances that bound the sphere (in single precision, exact for the few vertices near the
largest).
"""

from __future__ import annotations

import math
import sys
import threading
from collections import deque
from typing import Any

import numpy as np

MAX_EXTENT = 1e30
"""Largest body extent and distance from its own origin, in its own units: single precision (the
GPU's) holds the re-centred vertices with room to spare."""

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
        if 0.0 not in lo.tolist() and 0.0 not in hi.tolist():  # -0.0 == 0.0 too
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
    per = op.reduce(rows, axis=0)                                     # (3 * BLOCK,)
    op(per, v[len(v) - BLOCK:].reshape(3 * BLOCK), out=per)
    per = op.reduce(per.reshape(BLOCK // 16, 48), axis=0)             # 16 vertices a row
    return op.reduce(per.reshape(16, 3), axis=0)


_TILED = np.tile(np.arange(3), BLOCK)
"""Indices that repeat a vertex's x, y and z for a row of BLOCK vertices."""


def _recentred(vertices: np.ndarray, offset: np.ndarray, out: np.ndarray | None = None
               ) -> np.ndarray:
    """``(vertices - offset).astype(np.float32)`` in one pass (the same float64 difference,
    rounded once), written into ``out`` (V, 3) float32 when given."""
    if out is None:
        out = np.empty(vertices.shape, dtype=np.float32)
    if _blocked(vertices):
        rows, tail = _blocks(vertices)
        out_rows, out_tail = _blocks(out)
        np.subtract(rows, offset.take(_TILED), out=out_rows, casting="unsafe")
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
_scratch = threading.local()
SCRATCH_BYTES = 1 << 22
"""Most bytes of each array a thread keeps for :func:`_scratch_array`."""


def _scratch_array(shape: tuple[int, ...], dtype: type) -> np.ndarray:
    """An array of ``shape`` and ``dtype`` that this thread reuses from call to call when it is
    at most :data:`SCRATCH_BYTES` (its contents are then the last call's): working memory with
    no fresh pages to fault in."""
    size = int(np.prod(shape))
    itemsize = np.dtype(dtype).itemsize
    if itemsize * size > SCRATCH_BYTES:
        return np.empty(shape, dtype=dtype)
    name = np.dtype(dtype).name
    have = getattr(_scratch, name, None)
    if have is None or have.size < size:
        have = np.empty(max(size, 3 * 4096), dtype=dtype)
        setattr(_scratch, name, have)
    return have[:size].reshape(shape)


def _farthest(v32: np.ndarray, centre: np.ndarray) -> float:
    """The largest of :func:`_squared_distances`, computed exactly for the vertices that single
    precision cannot rule out, and for all of them where single precision could overflow or
    underflow.

    The centre is that of the vertices' box, and they are re-centred on it: it is within a few
    roundings of the origin. So the squared norms ``e`` of the vertices themselves, in single
    precision, rule a vertex out: the farthest vertex from the centre has a norm within twice
    the centre's of the largest norm, and single precision's error (a few units of 6e-8) is far
    inside the 1e-4 left beside it."""
    if not _blocked(v32):
        return float(_squared_distances(v32, centre).max())
    sq = _scratch_array(v32.shape, np.float32)
    rows, tail = _blocks(v32)
    sq_rows, sq_tail = _blocks(sq)
    with np.errstate(over="ignore", under="ignore"):  # such extents take the exact way below
        np.multiply(rows, rows, out=sq_rows)
        np.multiply(tail, tail, out=sq_tail)
        e = sq @ _ONES32  # a few roundings more or less than the sum's: within the margin
    top = float(e.max())
    if not 1e-30 < top < 1e30:
        return float(_squared_distances(v32, centre).max())
    shift = float(np.sqrt(np.dot(centre, centre)))
    floor = (np.sqrt(top) * (1 - 1e-4) - 2 * shift) ** 2 if np.sqrt(top) * (1 - 1e-4) > \
        2 * shift else 0.0
    near = np.flatnonzero(e >= floor)
    if 2 * len(near) > len(v32):
        return float(_squared_distances(v32, centre).max())
    return float(_squared_distances(v32[near], centre).max())


def check_vertices(vertices: Any, label: str, out: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Checked, re-centred vertices.

    Parameters
    ----------
    vertices : (V, 3) real
    label : str
        How errors name the body.
    out : (V, 3) float32, optional
        Where to write the re-centred vertices (default: a new array).

    Returns
    -------
    v32 : (V, 3) float32
        The vertices minus ``offset`` (``out``, when given).
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
    if vertices.dtype.kind not in "iuf" and (
            not np.issubdtype(vertices.dtype, np.number)
            or np.issubdtype(vertices.dtype, np.complexfloating)):
        raise ValueError(f"{label}: vertices must be real numbers, got dtype {vertices.dtype}")
    if len(vertices) == 0:
        raise ValueError(f"{label}: the mesh is empty (0 vertices)")
    # The few numbers of the box in Python floats (the same double arithmetic as NumPy's,
    # without its cost per call): NaN and infinities carry through min and max.
    lo, hi = (x.tolist() for x in _columns(vertices))
    if not all(map(math.isfinite, lo + hi)):
        bad = np.flatnonzero(~np.isfinite(vertices).all(axis=1))
        count = "1 vertex is" if len(bad) == 1 else f"{len(bad)} vertices are"
        raise ValueError(f"{label}: {count} NaN or infinite (first: vertex {int(bad[0])}, "
                         "counting from 0)")
    offset = [0.5 * (a + b) for a, b in zip(lo, hi)]
    extent = max(b - a for a, b in zip(lo, hi))
    if extent > MAX_EXTENT or max(map(abs, offset)) > MAX_EXTENT:
        raise ValueError(f"{label}: vertices span {extent:.3g} units around {offset}; "
                         f"pycinder supports bodies up to {MAX_EXTENT:g} units across and from "
                         "their origin: rescale the scene")
    centre = np.array(offset)
    v32 = _recentred(vertices, centre, out)
    # The box of what the GPU sees, rounding included: rounding and subtracting a constant keep
    # the order of values, so the extremes of v32 are the rounded extremes (but for which zero
    # a minimum keeps, see _columns).
    lo32 = [float(np.float32(a - o)) for a, o in zip(lo, offset)]
    hi32 = [float(np.float32(b - o)) for b, o in zip(hi, offset)]
    if 0.0 not in lo32 and 0.0 not in hi32:
        return v32, centre, np.array(lo32), np.array(hi32)
    low, high = _columns(v32)
    return v32, centre, low, high


def bounding_radius(v32: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """The radius of the bounding sphere of vertices ``v32`` (V, 3) float32 about the centre of
    their box ``lo``, ``hi`` (3,), padded by more than single precision's rounding."""
    # single-precision rounding of the vertices is far below the box's own size; pad by it
    return float(np.sqrt(_farthest(v32, 0.5 * (lo + hi)))) * (1 + 1e-6)


def measure(vertices: Any, label: str, out: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float | None]:
    """:func:`check_vertices` (into ``out`` when given), and the radius of the vertices'
    bounding sphere about their box's centre (:func:`bounding_radius`) for vertices of fewer
    than 2 * BLOCK vertices; None for larger ones, whose radius is measured when it is first
    needed (see :attr:`~pycinder.scene.bodies.Shape.radius`)."""
    v32, offset, lo, hi = check_vertices(vertices, label, out)
    return v32, offset, lo, hi, None if _blocked(v32) else bounding_radius(v32, lo, hi)


def _refs_when_free() -> int | None:
    """What ``sys.getrefcount`` reads for an array held only by a deque, taken from it and put
    back as :meth:`VertexMemory.take` does; None where it cannot be relied on (no
    ``getrefcount``, or a build without the GIL)."""
    if not hasattr(sys, "getrefcount") or not getattr(sys, "_is_gil_enabled", lambda: True)():
        return None
    probe = deque([np.empty(1)])
    array = probe.popleft()
    probe.append(array)
    return sys.getrefcount(array)


_FREE = _refs_when_free()


class VertexMemory:
    """Float32 arrays for the re-centred vertices of new shapes, reused once nothing refers to
    them any more.

    A body that deforms every frame makes a shape per frame; each shape's vertices in fresh
    memory would cost page faults (more than the copy itself, for a bunny's 337 kB). The arrays
    handed out are kept here, per vertex count, and one is handed out again only when this pool
    is the last to hold it (its reference count says so): no shape, result or view of it (a
    view holds its base) can see it change. Where reference counts cannot be relied on, every
    array is made afresh.

    Parameters
    ----------
    most : int
        Arrays kept per vertex count; the oldest beyond it are forgotten (left to whatever
        holds them).
    """

    FROM_BYTES = 1 << 16
    """Arrays smaller than this are made afresh (they come from the allocator's free lists)."""

    def __init__(self, most: int = 64) -> None:
        self.most = most
        self._kept: dict[int, deque[np.ndarray]] = {}

    def take(self, count: int) -> np.ndarray | None:
        """A (count, 3) float32 array no one else holds, or None (let the caller make one):
        for a small one, or where reference counts cannot be relied on."""
        if 12 * count < self.FROM_BYTES or _FREE is None:
            return None
        kept = self._kept.setdefault(count, deque())
        for _ in range(min(len(kept), 8)):  # the oldest first: the likeliest to be free
            array = kept.popleft()
            kept.append(array)
            if sys.getrefcount(array) <= _FREE:  # the deque's and this name's: no one else's
                return array
            del array
        array = np.empty((count, 3), dtype=np.float32)
        kept.append(array)
        while len(kept) > self.most:
            kept.popleft()
        return array

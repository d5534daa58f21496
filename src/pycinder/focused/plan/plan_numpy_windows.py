"""The windows of candidate pairs, planned on the host in NumPy: the first half of
:func:`~pycinder.focused.plan.plan_numpy.plan_tiles` (the second packs them into the atlas).

For a candidate pair the region is the box where the pair's bounding volumes overlap (both bodies'
oriented boxes and world boxes), taken in one of three frames: the world's axes, or either body's
own axes. The frame whose box projects to the smallest window wins. The view looks along that
box's longest axis, tilted by :data:`TILT` towards its middle axis about its thinnest one. If the
boxes are apart along any axis of the three frames, the pair cannot touch and gets no window.
Pass P1 (:mod:`~pycinder.focused.plan.p1_windows`) plans the same windows on the GPU.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...gpu.layout import FLAG_COUNT_BACK, FLAG_MIRROR, FLAG_OPEN
from ...util import threads
from ...util.arrays import det3, sum3

TILT = 0.41
"""Radians between the view direction and the overlap box's longest axis."""

MARGIN_PX = 1
"""Pixels added around the overlap box's projection, so that a sample near the box's edge still
has a pixel centre in the window."""

PARALLEL_PAIRS = 1024
"""Fewest candidate pairs per thread when planning is shared among threads (see the benchmarks'
README)."""


TINY = float(np.finfo(np.float32).tiny)
"""Float32's smallest normal number: smaller elements of a linear part count as zeros in its
frame's decomposition (see :func:`_qr_frames`)."""


def mirrors(t3: np.ndarray) -> np.ndarray:
    """(N,) bool: whether each linear part ``t3`` (N, 3, 3) mirrors, by the sign of its float64
    determinant (cofactors: what pass P0 is given, and the NumPy planner's flags)."""
    return det3(np.asarray(t3, np.float64)) < 0


def _qr_frames(t3: np.ndarray) -> np.ndarray:
    """Orthonormal frames (n, 3, 3) of linear parts ``t3`` (n, 3, 3), as the columns of Q of
    their QR decomposition with the last column's sign chosen so that the frame is proper.

    Elements of magnitude below float32's smallest normal number (:data:`TINY`) are made
    ``+0.0`` first, and so is every ``-0.0``: LAPACK takes the sign of a zero diagonal element
    as the reflection's, and reflects a column whose part below the diagonal is not exactly zero
    however small, so either would turn an axis of the frame round; pass P0
    (:mod:`pycinder.focused.plan.p0_bodies`) follows LAPACK's steps in float32, on a GPU whose
    compiler need not keep the sign of a zero and may flush subnormal numbers to zero."""
    m = np.where(np.abs(t3) < TINY, 0.0, t3)  # -0.0 too
    q, _ = np.linalg.qr(m)
    # QR's sign convention is arbitrary; that is fine for a frame, but keep it proper.
    det = np.linalg.det(q)
    q[:, :, 2] *= np.where(det < 0, -1.0, 1.0)[:, None]
    return q


def _frames(transforms: np.ndarray) -> np.ndarray:
    """Orthonormal body frames (N, 3, 3), rows = axes, from the transforms' linear parts."""
    return np.transpose(_qr_frames(transforms[:, :3, :3]), (0, 2, 1))


_IDENTITY_BITS = np.eye(3).view(np.int64).reshape(9)
_IDENTITY_FRAME = _qr_frames(np.eye(3)[None])[0]
_last_frames: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
"""The last call's linear parts (as bits), their frames (Q) and whether each mirrors: the frames
of a body whose linear part is bit for bit the same are not decomposed again (rigid bodies that
only move keep theirs; a QR costs about 4 microseconds a body)."""


def _body_frames(transforms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per body, the Q of :func:`_qr_frames` (N, 3, 3) and whether the transform mirrors (N,):
    decomposed only for linear parts other than the identity and other than the last call's (the
    same values as decomposing all of them: each matrix is decomposed on its own)."""
    global _last_frames
    t3 = transforms[:, :3, :3]
    n = len(t3)
    if transforms.dtype != np.float64:
        return _qr_frames(t3), mirrors(t3)
    bits = t3.view(np.int64).reshape(n, 9)
    last = _last_frames
    if last is not None and last[0].shape == bits.shape:
        todo = (bits != last[0]).any(axis=1)
        if not todo.any():
            _last_frames = (bits, last[1], last[2])
            return last[1], last[2]
        q, mirrored = last[1].copy(), last[2].copy()
    else:
        todo = np.ones(n, dtype=bool)
        q, mirrored = np.empty((n, 3, 3)), np.empty(n, dtype=bool)
    same = (bits == _IDENTITY_BITS).all(axis=1)
    eye = todo & same
    if eye.any():
        q[eye] = _IDENTITY_FRAME
        mirrored[eye] = False
        todo &= ~same
    if todo.any():
        i = np.flatnonzero(todo)
        sub = t3[i]
        q[i] = _qr_frames(sub)
        mirrored[i] = mirrors(sub)
    _last_frames = (bits, q, mirrored)
    return q, mirrored


def plan_windows(pairs: np.ndarray, pair_tolerances: np.ndarray, local_lo: np.ndarray,
                 local_hi: np.ndarray, world_lo: np.ndarray, world_hi: np.ndarray,
                 transforms: np.ndarray, *, open_bodies: np.ndarray | None = None,
                 chunk: int = 2048) -> dict | None:
    """The windows of candidate pairs (parameters as
    :func:`~pycinder.focused.plan.plan_numpy.plan_tiles`'), planned in chunks shared among the
    host's worker threads.

    Returns
    -------
    dict or None
        The windows of the pairs whose bounding volumes meet, in pair order, as
        :func:`~pycinder.focused.plan.plan_numpy.tiles_of_windows` takes them; None when every pair
        is apart.
    """
    pairs, pair_tolerances = np.asarray(pairs), np.asarray(pair_tolerances)
    bounds = body_bounds(local_lo, local_hi, world_lo, world_hi, transforms, open_bodies)
    # Chunks of at most ``chunk`` pairs, at least one per worker thread when there are enough
    # pairs to share (NumPy releases the GIL on arrays of this size).
    workers = threads.pool()
    parts_wanted = min(threads.WORKERS, len(pairs) // PARALLEL_PAIRS) if workers else 1
    size = max(-(-len(pairs) // max(parts_wanted, 1)), 1)
    size = min(size, chunk)
    starts = range(0, len(pairs), size)

    def plan(s: int) -> dict | None:
        return _plan_chunk(pairs[s:s + size], pair_tolerances[s:s + size], bounds, s)

    parts = list(workers.map(plan, starts)) if workers and len(starts) > 1 else \
        [plan(s) for s in starts]
    keep = [p for p in parts if p is not None]
    return None if not keep else keep[0] if len(keep) == 1 else \
        {k: np.concatenate([p[k] for p in keep]) for k in keep[0]}


def _support(rows: np.ndarray, centre: np.ndarray, axes: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """Interval of boxes along directions: ``rows @ centre`` and the half-width ``|rows @ axes|``
    summed over the box's half axes. Shapes broadcast as (..., 3, 3) rows, (..., 3) centres,
    (..., 3, 3) axes; returns (..., 3) centres and half-widths."""
    return (rows @ centre[..., None])[..., 0], sum3(np.abs(rows @ axes))


@dataclass
class BodyBounds:
    """Every body's two bounding boxes, and where both hold along the axes of the world and of
    the body's own frame (what a pair's planning needs of each body alone).

    obb_centre : (N, 3)
        World centre of the oriented box (the transformed body-space box).
    obb_axes : (N, 3, 3)
        Its half axes, as columns.
    aabb_centre, aabb_half : (N, 3)
        The world box's centre and half extents.
    frames : (N, 3, 3)
        Orthonormal body frames, rows = axes.
    world : (N, 2, 3)
        Per body, the interval ``(lo, hi)`` along each world axis where both boxes hold.
    own : (N, 2, 3)
        The same along the axes of the body's own frame.
    mirrored : (N,) bool
        Whether the transform mirrors the body.
    q : (N, 3, 3)
        The frames' transposes, contiguous (``frames`` is a view of it).
    choices : (N + 1, 3, 3)
        The frames a pair's view is chosen from, contiguous: the world's axes, then every
        body's frame (body ``i`` at ``i + 1``).
    flags : (2, N) int64
        The tile flags each body brings as body a (row 0) and as body b (row 1): mirrored, open.
    """

    obb_centre: np.ndarray
    obb_axes: np.ndarray
    aabb_centre: np.ndarray
    aabb_half: np.ndarray
    frames: np.ndarray
    world: np.ndarray
    own: np.ndarray
    mirrored: np.ndarray
    q: np.ndarray | None = None
    choices: np.ndarray | None = None
    flags: np.ndarray | None = None
    soa: _Columns | None = None


def interval_meet(first: tuple[np.ndarray, np.ndarray],
                  second: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(..., 2, 3): the interval ``(lo, hi)`` where two intervals given as (centre, half) hold."""
    (c1, h1), (c2, h2) = first, second
    return np.stack([np.maximum(c1 - h1, c2 - h2), np.minimum(c1 + h1, c2 + h2)], axis=-2)


def body_bounds(local_lo: np.ndarray, local_hi: np.ndarray, world_lo: np.ndarray,
                 world_hi: np.ndarray, transforms: np.ndarray,
                 open_bodies: np.ndarray | None = None) -> BodyBounds:
    # Both boxes as centre + M @ [-1, 1]^3 (columns of M: the box's half axes).
    t3 = transforms[:, :3, :3]
    obb_c = np.einsum("nij,nj->ni", t3, 0.5 * (local_lo + local_hi)) + transforms[:, :3, 3]
    obb_m = t3 * (0.5 * (local_hi - local_lo))[:, None, :]
    aabb_c, aabb_h = 0.5 * (world_lo + world_hi), 0.5 * (world_hi - world_lo)
    q, mirrored = _body_frames(transforms)
    frames = np.transpose(q, (0, 2, 1))
    world = interval_meet((obb_c, sum3(np.abs(obb_m))), (aabb_c, aabb_h))
    soa = _Columns(np.ascontiguousarray(q.transpose(1, 2, 0)), np.ascontiguousarray(obb_c.T),
                   np.ascontiguousarray(obb_m.transpose(1, 2, 0)), np.ascontiguousarray(aabb_c.T),
                   np.ascontiguousarray(aabb_h.T))
    # Both boxes along the body's own axes (_support and _support_box of frames, by columns).
    n = len(transforms)
    h1 = sum3(np.abs(frames @ obb_m)).T
    c1 = _dot3(soa.q, soa.obb_centre)
    c2 = _dot3(soa.q, soa.aabb_centre)
    h2 = _dot3(np.abs(soa.q), soa.aabb_half)
    own = np.empty((n, 2, 3))
    np.maximum(c1 - h1, c2 - h2, out=own[:, 0].T)
    np.minimum(c1 + h1, c2 + h2, out=own[:, 1].T)
    choices = np.empty((n + 1, 3, 3))
    choices[0] = np.eye(3)
    choices[1:] = frames
    flags = np.where(mirrored, np.array([[FLAG_MIRROR[0]], [FLAG_MIRROR[1]]]), 0)
    if open_bodies is not None:
        flags |= np.where(open_bodies, np.array([[FLAG_OPEN[0]], [FLAG_OPEN[1]]]), 0)
    return BodyBounds(obb_c, obb_m, aabb_c, aabb_h, frames, world, own, mirrored, q, choices,
                       flags, soa)


def _support_box(rows: np.ndarray, centre: np.ndarray, half: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_support` of world boxes (``half`` (..., 3) along the world's axes)."""
    return (rows @ centre[..., None])[..., 0], (np.abs(rows) @ half[..., None])[..., 0]


_COS, _SIN = float(np.cos(TILT)), float(np.sin(TILT))


@dataclass
class _Columns:
    """Per-body arrays of :class:`BodyBounds` with the body as the last axis (gathers along it
    give arrays whose rows are contiguous, for element-wise products: NumPy is slow along an
    axis of 3)."""

    q: np.ndarray            # (3, 3, N): q[j, i] = frames[:, i, j]
    obb_centre: np.ndarray   # (3, N)
    obb_axes: np.ndarray     # (3, 3, N): obb_axes[j, c] = obb_axes[:, j, c]
    aabb_centre: np.ndarray  # (3, N)
    aabb_half: np.ndarray    # (3, N)


def _dot3(rows: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``M @ x`` per item, rounded as BLAS's dgemv rounds a (3, 3) matrix laid out as a
    transposed one (that is, as ``frames`` is) times a vector, and as its ddot rounds a dot of
    3: ``((0 + m0 * x0) + m1 * x1) + m2 * x2``, the zero first (so no product of -0 stays -0).
    ``rows`` (3, ..., n): ``rows[j]`` holds column j of every item's matrix (its rows along the
    middle axes); ``x`` (3, n). Returns (..., n)."""
    out = rows[0] * x[0]
    out += 0.0
    out += rows[1] * x[1]
    out += rows[2] * x[2]
    return out


def _view_support(view: np.ndarray, soa: _Columns, bodies: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Centres and half-widths (2, m) of the oriented boxes of ``bodies`` (2m,: body a of each
    pair, then body b) along their pair's view direction ``view`` (3, m), as
    :func:`_support` computes them for (m, 1, 3) rows (a dot and a vector times a matrix, both
    rounded as :func:`_dot3`)."""
    m = view.shape[1]
    centre = _dot3(view[:, None, :], soa.obb_centre.take(bodies, axis=1).reshape(3, 2, m))
    # columns[j, c] = obb_axes[:, j, c]: the products of the view with each half axis c.
    columns = soa.obb_axes.take(bodies, axis=2).reshape(3, 3, 2, m)
    return centre, _sum3_first(np.abs(_dot3(view[:, None, None, :], columns)))


def _sum3_first(x: np.ndarray) -> np.ndarray:
    """:func:`sum3` over the first axis (of 3)."""
    out = x[0] + x[1]
    out += x[2]
    return out


def _plan_chunk(pairs: np.ndarray, tol: np.ndarray, bounds: BodyBounds, first: int
                ) -> dict | None:
    """The window of each pair of ``pairs`` (K, 2) whose bounding volumes meet (tolerances
    ``tol`` (K,); the pairs are ``first``, ``first + 1``... of the plan): a dict of the kept
    pairs' ``pair``, ``bodies``, ``axes``, ``origin``, ``pixel``, ``w`` and ``h`` (float),
    ``slab`` and ``flags``; None when every pair is apart.

    The matrix products (``@``, ``einsum``) are made on operands of the same memory layout as
    a product per pair would have (the layout decides which BLAS routine rounds them): every
    value of a plan is the same, bit for bit, whichever way its pairs are chunked."""
    k = len(pairs)
    a, b = pairs[:, 0], pairs[:, 1]
    ab = np.concatenate([a, b])  # each pair seen from body a's frame, then from body b's
    ba = np.concatenate([b, a])
    # The box where all four bounds (both bodies' two boxes) hold, in every candidate frame
    # [frame, pair, axis]: the world's, body a's, body b's. Where a body's own two boxes hold
    # along the world's axes and its own frame's is the body's; only the other body's boxes in
    # a body's frame are the pair's own work.
    lo = np.empty((3, k, 3))
    hi = np.empty((3, k, 3))
    w = bounds.world.take(ab, axis=0)
    np.maximum(w[:k, 0], w[k:, 0], out=lo[0])
    np.minimum(w[:k, 1], w[k:, 1], out=hi[0])
    # The other body's boxes along my frame's axes (rows = frames[ab], [axis, pair] below).
    h1 = sum3(np.abs(bounds.frames.take(ab, axis=0) @ bounds.obb_axes.take(ba, axis=0))).T
    rows = bounds.soa.q.take(ab, axis=2)                  # rows[j, i] = frames[ab][:, i, j]
    c1 = _dot3(rows, bounds.soa.obb_centre.take(ba, axis=1))
    c2 = _dot3(rows, bounds.soa.aabb_centre.take(ba, axis=1))
    h2 = _dot3(np.abs(rows), bounds.soa.aabb_half.take(ba, axis=1))
    mine = bounds.own.take(ab, axis=0).T                                         # (3, 2, 2k)
    np.maximum(mine[:, 0], np.maximum(c1 - h1, c2 - h2), out=lo[1:].reshape(2 * k, 3).T)
    np.minimum(mine[:, 1], np.minimum(c1 + h1, c2 + h2), out=hi[1:].reshape(2 * k, 3).T)
    apart = (hi < lo).any(axis=(0, 2))
    if apart.all():
        return None
    lo = np.minimum(lo, hi)
    extent = hi - lo
    # Each frame's window (the box's long, mid and thin extents) and the smallest one.
    x, y, z = extent[..., 0], extent[..., 1], extent[..., 2]
    top, bottom = np.maximum(x, y), np.minimum(x, y)
    long_, mid, thin = np.maximum(top, z), np.maximum(bottom, np.minimum(top, z)), \
        np.minimum(bottom, z)
    c, s = _COS, _SIN
    win_x = (long_ * s + mid * c) / tol + 2 * MARGIN_PX + 1
    win_y = thin / tol + 2 * MARGIN_PX + 1
    area = win_x * win_y                                                          # (3, k)
    # np.argmin over the frames: the first of the smallest.
    best = (area[1] < area[0]).view(np.int8)
    best = np.where(area[2] < np.minimum(area[0], area[1]), np.int8(2), best)
    idx = np.flatnonzero(~apart)
    m = len(idx)
    f = best.take(idx).astype(np.intp)
    ai, bi = a.take(idx), b.take(idx)
    chosen = f * k + idx                                      # rows of lo, hi, extent (3k, 3)
    lo_f = lo.reshape(3 * k, 3).take(chosen, axis=0)
    hi_f = hi.reshape(3 * k, 3).take(chosen, axis=0)
    e = extent.reshape(3 * k, 3).take(chosen, axis=0)
    choice = np.where(f == 0, 0, np.where(f == 1, ai, bi) + 1)
    frame = bounds.choices.take(choice, axis=0)                                      # (m, 3, 3)
    # The chosen frame's axes by extent, long, mid, thin: np.argsort's order of -extent (ties
    # by index), from where each axis goes (pos_i: how many axes come before axis i).
    e0, e1, e2 = e[:, 0], e[:, 1], e[:, 2]
    pos0 = (e1 > e0).view(np.int8) + (e2 > e0).view(np.int8)
    pos1 = (e0 >= e1).view(np.int8) + (e2 > e1).view(np.int8)
    order = np.empty((m, 3), dtype=np.intp)                          # axis of rank 0, 1, 2
    for rank in (0, 1):
        np.copyto(order[:, rank], np.where(pos0 == rank, 0, np.where(pos1 == rank, 1, 2)))
    np.subtract(3, order[:, 0] + order[:, 1], out=order[:, 2])
    ranked = bounds.choices.reshape(-1, 3).take(3 * choice[:, None] + order, axis=0)
    long_, mid, thin = ranked[:, 0], ranked[:, 1], ranked[:, 2]
    axes = np.empty((m, 3, 3))
    np.add(-s * long_, c * mid, out=axes[:, 0])
    axes[:, 1] = thin
    np.add(c * long_, s * mid, out=axes[:, 2])
    # (x, y, view) = R (long, mid, thin) with det R = 1, and every frame is proper: the view's
    # axes are left-handed exactly when the frame's axes come in an odd order.
    flip = (order[:, 1] - order[:, 0]) % 3 == 2
    if flip.any():
        axes[flip, 1] *= -1
    # The overlap box (axis-aligned in the frame) in view coordinates.
    vc, vh = _support_box(axes @ np.transpose(frame, (0, 2, 1)), 0.5 * (lo_f + hi_f),
                          0.5 * (hi_f - lo_f))
    vlo, vhi = vc - vh, vc + vh
    # Put the window's long side along screen x.
    swap = (vhi[:, 1] - vlo[:, 1]) > (vhi[:, 0] - vlo[:, 0])
    if swap.any():
        nx, ny = axes[swap, 1].copy(), -axes[swap, 0]
        axes[swap, 0], axes[swap, 1] = nx, ny
        lo0, hi0 = vlo[swap, 0].copy(), vhi[swap, 0].copy()
        vlo[swap, 0], vhi[swap, 0] = vlo[swap, 1], vhi[swap, 1]
        vlo[swap, 1], vhi[swap, 1] = -hi0, -lo0
    px = tol.take(idx)
    # Sizes stay floating point until the plan is known to fit (see check_pixels).
    w = np.ceil((vhi[:, 0] - vlo[:, 0]) / px) + 2 * MARGIN_PX
    h = np.ceil((vhi[:, 1] - vlo[:, 1]) / px) + 2 * MARGIN_PX
    zmid = 0.5 * (vlo[:, 2] + vhi[:, 2])
    origin = ((vlo[:, 0] - MARGIN_PX * px)[:, None] * axes[:, 0]
              + (vlo[:, 1] - MARGIN_PX * px)[:, None] * axes[:, 1] + zmid[:, None] * axes[:, 2])
    slab = np.empty((m, 2))
    np.divide(vlo[:, 2] - zmid, px, out=slab[:, 0])
    np.divide(vhi[:, 2] - zmid, px, out=slab[:, 1])
    # Count towards the side of the slab with less of the pair's depth extent behind it.
    view = axes[:, 2].T                                                          # (3, m)
    both = np.concatenate([ai, bi])
    (ca, cb), (ha, hb) = _view_support(view, bounds.soa, both)
    front_len = vlo[:, 2] - np.minimum(ca - ha, cb - hb)
    back_len = np.maximum(ca + ha, cb + hb) - vhi[:, 2]
    flags = np.where(back_len < front_len, FLAG_COUNT_BACK, 0)
    flags |= bounds.flags[0].take(ai)
    flags |= bounds.flags[1].take(bi)
    return {
        "pair": idx + first, "bodies": pairs.take(idx, axis=0), "axes": axes,
        "origin": origin, "pixel": px, "w": w, "h": h, "slab": slab, "flags": flags,
    }

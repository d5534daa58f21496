"""Which pairs of face clusters of a dense candidate pair pass H1 measures, and along which
lines (:func:`depth_items`; :func:`skip_lines` for items packed apart from the shapes, as
regions are).

Two rules leave a cluster pair out along a line: its clusters' projections along the line do
not meet (below), or both bodies are solids wound outward and the two clusters face the same
way along the line (:func:`cluster_facing`: on a ray, a's nearest point is on a face where the
ray enters a and b's farthest on one where it leaves b, or the other way round for the other
way, so the largest ``far b - near a`` over the rays is never a pair of faces that face the same
way, except faces within :data:`FACING` of edge-on, which count as facing both ways). Both
rules leave the figures exactly what every cluster pair gives.

Pass H1 (:mod:`~pycinder.focused.measure.h1_depth`) measures a pair along 19 lines, face pair by
face pair. Along a line ``n`` a face pair adds to the figures only where the faces' projections
along ``n`` meet: every corner and crossing the shader takes lies within ``SLACK`` times the square
root of 3 times the larger face's diameter of both faces' projections, as it computes them. So a
cluster pair whose projections are farther apart than that along some direction of a line's
screen adds nothing along the line: it is measured only along the lines where their projections
meet, and not at all where they meet along none. Each cluster's projection is bounded by its
vertices' extent along four directions of the screen (its axes and their diagonals). Over two
dense surfaces that meet, a cluster of one meets along a line only the clusters of the other in
its own shadow, so the work grows with the clusters that meet, not with the product of their
counts.

The extents are computed in float64 from the vertices and frames the shader reads (its single
precision values, taken exactly) and grown by :data:`CULL_MARGIN` times the largest a coordinate
of the pair's frame can be: over 16 times the shader's rounding of a projected corner and its
slack together. A cluster pair left out along a line is one that no face pair of which could
add to the figures: they are exactly those of every cluster pair measured along every line. A
pair that has a line along which no cluster pair meets is cleared by that line (no ray meets
both bodies): as a whole item stops at the first line that clears it, its lines past that one
are not measured.

A line whose direction lies within rounding of where the shader's choice of screen axes changes
(:data:`AMBIGUOUS`) is not culled: its screen could be either of two.
"""

from __future__ import annotations

import weakref

import numpy as np

from ...scene.pack import ShapePack
from .h1_depth import ITEM_SKIP_SHIFT, ITEM_WHOLE, LINES, WORLD_LINES
from .local_depth import one_outward_solid
from .pair_work import ITEM, spread

CULL_MARGIN = 2.0**-12
"""Growth of the extents, per unit of the largest a coordinate of the pair's frame can be
(``|linear part| |vertex| + |translation|`` of either body): the shader's rounding of a projected
corner is under ``2^-19`` of it, its slack (``SLACK`` times the square root of 3 times a face's
diameter, at most twice that unit) under ``2^-16``."""

SLICE = 2**21
"""Most cluster pairs and lines tested at once (a bound on the host memory of the test)."""

AMBIGUOUS = 1e-6
"""A line whose unit direction's x is this close to the shader's 0.75 (where its screen axes
change) is measured over every cluster pair."""

_WORLD = np.array([(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1),
                   (0, 1, 1), (0, 1, -1), (1, 1, 1), (1, 1, -1), (1, -1, 1), (-1, 1, 1)],
                  np.float64)
assert len(_WORLD) == WORLD_LINES

_VERTICES: weakref.WeakKeyDictionary[ShapePack, dict[int, tuple[np.ndarray, np.ndarray]]] = \
    weakref.WeakKeyDictionary()


def cluster_vertices(pack: ShapePack, shape: int) -> tuple[np.ndarray, np.ndarray]:
    """The distinct vertices of each cluster of one packed shape (kept with the pack).

    Returns
    -------
    index : (n,) int64
        Vertex indices into the shape's own vertices, cluster after cluster.
    start : (C + 1,) int64
        Where each of the shape's C clusters starts in ``index``.
    """
    known = _VERTICES.setdefault(pack, {})
    if shape not in known:
        c0, c1 = int(pack.cluster_start[shape]), int(pack.cluster_start[shape + 1])
        f0, f1 = int(pack.face_start[shape]), int(pack.face_start[shape + 1])
        counts = pack.clusters[c0:c1, 1].astype(np.int64)
        cluster = np.repeat(np.arange(c1 - c0), 3 * counts)
        vertex = pack.faces[f0:f1].reshape(-1).astype(np.int64) - pack.vertex_start[shape]
        n = int(pack.vertex_start[shape + 1] - pack.vertex_start[shape])
        keys = np.unique(cluster * n + vertex)
        start = np.searchsorted(keys // n, np.arange(c1 - c0 + 1))
        known[shape] = (keys % n, start.astype(np.int64))
    return known[shape]


def screens(frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each pair's lines' screen axes as the shader's ``view_of(line(i))`` makes them (in
    float64, from the frames' single-precision values).

    Parameters
    ----------
    frames : (K,) structured array of :data:`~pycinder.focused.measure.pair_work.FRAME`

    Returns
    -------
    axes : (K, LINES, 4, 3) float64
        Screen x and y of each line, in the pair's frame, and the two diagonals between them.
    ambiguous : (K, LINES) bool
        Lines whose screen the shader could take either way (:data:`AMBIGUOUS`).
    """
    k = len(frames)
    d = np.empty((k, LINES, 3))
    d[:, 0:3] = np.swapaxes(frames["m0"][:, :, :3].astype(np.float64), 1, 2)
    d[:, 3:6] = np.swapaxes(frames["m1"][:, :, :3].astype(np.float64), 1, 2)
    d[:, 6:] = _WORLD
    length = np.linalg.norm(d, axis=2, keepdims=True)
    n = np.where(length > 0, d / np.where(length > 0, length, 1.0), [0.0, 0.0, 1.0])
    ambiguous = np.abs(np.abs(n[..., 0]) - 0.75) < AMBIGUOUS
    helper = np.where((np.abs(n[..., 0]) > 0.75)[..., None], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    x = np.cross(helper, n)
    x /= np.linalg.norm(x, axis=2, keepdims=True)
    y = np.cross(n, x)
    return np.stack([x, y, (x + y) * 0.5**0.5, (x - y) * 0.5**0.5], axis=2), ambiguous


def _magnitude(m: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """The largest a coordinate of the pair's frame can be for a body (rows ``m`` (K, 3, 4) of
    its pair-from-body map, vertices within ``reach`` (K,) of its origin)."""
    return np.linalg.norm(m[:, :, :3], axis=(1, 2)) * reach + np.linalg.norm(m[:, :, 3], axis=1)


def screen_boxes(pack: ShapePack, shapes: list, shape: np.ndarray, m: np.ndarray,
                 axes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The extent of every cluster of one body of each pair along each direction of each of its
    lines' screens.

    Parameters
    ----------
    pack : ShapePack
    shapes : list of Shape
        The packed shapes with their current vertices.
    shape : (K,) int
        The body's shape, per pair.
    m : (K, 3, 4) float64
        Its pair-from-body rows.
    axes : (K, LINES, A, 3) float64
        Directions on each line's screen (:func:`screens`).

    Returns
    -------
    lo, hi : (C, LINES, A) float64
        Per cluster (the pairs' clusters, pair after pair), the extent of its vertices'
        projections along each direction.
    owner : (C,) int64
        The pair it belongs to.
    """
    width = axes.shape[1] * axes.shape[2]
    # Screen coordinates: (axes . linear) p + axes . translation, per pair.
    coef = np.einsum("klaj,kji->klai", axes, m[:, :, :3]).reshape(-1, width, 3)
    offset = np.einsum("klaj,kj->kla", axes, m[:, :, 3]).reshape(-1, width)
    points: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    lo, hi, owner = [], [], []
    for k, s in enumerate(np.asarray(shape).tolist()):
        if s not in points:
            index, start = cluster_vertices(pack, s)
            points[s] = (np.asarray(shapes[s].vertices, np.float64)[index], start[:-1])
        p, start = points[s]
        proj = p[:, 0:1] * coef[k, :, 0] + p[:, 1:2] * coef[k, :, 1] + p[:, 2:3] * coef[k, :, 2]
        proj += offset[k]
        lo.append(np.minimum.reduceat(proj, start, axis=0))
        hi.append(np.maximum.reduceat(proj, start, axis=0))
        owner.append(np.full(len(start), k, np.int64))
    out = (-1,) + axes.shape[1:3]
    if not lo:
        empty = np.zeros((0,) + axes.shape[1:3])
        return empty, empty, np.zeros(0, np.int64)
    return (np.concatenate(lo).reshape(out), np.concatenate(hi).reshape(out),
            np.concatenate(owner))


def depth_items(pack: ShapePack, shapes: list, pair_shapes: np.ndarray, frames: np.ndarray,
                cull: bool = True) -> np.ndarray:
    """Pass H1's items for pairs measured cluster pair by cluster pair: every pair of a cluster
    of body a and a cluster of body b whose projections meet along some line, skipping the
    lines along which they do not (see the module), or with ``cull`` False every pair of their
    clusters along every line.

    Parameters
    ----------
    pack : ShapePack
    shapes : list of Shape
        The packed shapes with their current vertices.
    pair_shapes : (K, 2) int
        The shapes of each pair's two bodies.
    frames : (K,) structured array of :data:`~pycinder.focused.measure.pair_work.FRAME`
        The pairs' frames (what the shader reads).
    cull : bool

    Returns
    -------
    (I,) structured array of :data:`~pycinder.focused.measure.pair_work.ITEM`
        ``pair`` is the row of ``pair_shapes``.
    """
    start = pack.cluster_start
    sa, sb = pair_shapes[:, 0], pair_shapes[:, 1]
    count_a, count_b = start[sa + 1] - start[sa], start[sb + 1] - start[sb]
    if not cull:
        pair, i = spread(count_a * count_b)
        ca = start[sa][pair] + i // count_b[pair]
        cb = start[sb][pair] + i % count_b[pair]
        bits = np.full(len(pair), (1 << LINES) - 1, np.int64)
    else:
        pair, ca, cb, bits = _meeting_lines(pack, shapes, pair_shapes, frames)
    items = ITEM.zeros(len(pair))
    items["pair"] = pair
    items["a_start"], items["a_count"] = pack.clusters[ca, 0], pack.clusters[ca, 1]
    items["b_start"], items["b_count"] = pack.clusters[cb, 0], pack.clusters[cb, 1]
    items["whole"] = (((1 << LINES) - 1) & ~bits) << ITEM_SKIP_SHIFT
    return items


def _meet(lo_a: np.ndarray, hi_a: np.ndarray, lo_b: np.ndarray, hi_b: np.ndarray,
          grow: np.ndarray) -> np.ndarray:
    """Whether boxes (..., A) meet along every direction, grown by ``grow`` (...)."""
    grow = grow[..., None]
    return np.all((lo_b <= hi_a + grow) & (lo_a <= hi_b + grow), axis=-1)


FACING = 1e-3
"""A face whose unit normal is within this cosine of square to a line counts as facing both
ways along it (its depth on a ray is never what only the other way's faces give)."""


def cluster_facing(pack: ShapePack, shapes: list, shape: np.ndarray, m: np.ndarray,
                   axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which way each cluster's faces face along each line: whether some face looks against the
    line (a ray along it can enter the body there) and whether some looks along it (a ray can
    leave there). The clusters of a body that is not one solid wound outward
    (:func:`~pycinder.focused.measure.local_depth.one_outward_solid`: open, inside out, or in
    pieces, one of which may be) face both ways.

    Parameters
    ----------
    pack : ShapePack
    shapes : list of Shape
    shape : (K,) int
        The body's shape, per pair.
    m : (K, 3, 4) float64
        Its pair-from-body rows.
    axes : (K, LINES, A, 3) float64
        Each line's screen (:func:`screens`); the line is their cross product.

    Returns
    -------
    enters, leaves : (C, LINES) bool
        Per cluster (pair after pair, as :func:`screen_boxes` orders them).
    """
    lines = np.cross(axes[:, :, 0], axes[:, :, 1])  # (K, LINES, 3) unit, the line's way
    enters, leaves = [], []
    for k, s in enumerate(np.asarray(shape).tolist()):
        c0, c1 = int(pack.cluster_start[s]), int(pack.cluster_start[s + 1])
        if not one_outward_solid(shapes[s]):
            enters.append(np.ones((c1 - c0, LINES), bool))
            leaves.append(np.ones((c1 - c0, LINES), bool))
            continue
        f0, f1 = int(pack.face_start[s]), int(pack.face_start[s + 1])
        corners = pack.faces[f0:f1].reshape(-1, 3).astype(np.int64) - pack.vertex_start[s]
        v = np.asarray(shapes[s].vertices, np.float64)[corners]  # (F, 3, 3)
        # Outward in the pair's frame whether or not the frame mirrors the body (the inverse
        # transpose keeps a normal's side).
        normal = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]) @ np.linalg.inv(m[k, :, :3])
        length = np.linalg.norm(normal, axis=1, keepdims=True)  # outward in the pair's frame
        cos = (normal / np.where(length > 0, length, 1.0)) @ lines[k].T  # (F, LINES)
        cos[length[:, 0] == 0] = 0.0  # a face without a normal faces both ways
        first = np.r_[0, np.cumsum(pack.clusters[c0:c1, 1].astype(np.int64))[:-1]]
        enters.append(np.minimum.reduceat(cos, first, axis=0) < FACING)
        leaves.append(np.maximum.reduceat(cos, first, axis=0) > -FACING)
    if not enters:
        return np.zeros((0, LINES), bool), np.zeros((0, LINES), bool)
    return np.concatenate(enters), np.concatenate(leaves)


def _meeting_lines(pack: ShapePack, shapes: list, pair_shapes: np.ndarray, frames: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The cluster pairs that meet along some line, up to each pair's first line along which
    none does: their pair (K,), clusters of a and of b (packed indices) and the bits of the
    lines they meet along."""
    k = len(frames)
    axes, ambiguous = screens(frames)
    boxes, reach, facing = [], [], []
    for side, field in enumerate(("m0", "m1")):
        m = frames[field].astype(np.float64)
        boxes.append(screen_boxes(pack, shapes, pair_shapes[:, side], m, axes))
        facing.append(cluster_facing(pack, shapes, pair_shapes[:, side], m, axes))
        lo = np.array([shapes[s].lo for s in pair_shapes[:, side]]).reshape(k, 3)
        hi = np.array([shapes[s].hi for s in pair_shapes[:, side]]).reshape(k, 3)
        reach.append(_magnitude(m, np.linalg.norm(np.maximum(np.abs(lo), np.abs(hi)), axis=1)))
    grow = np.where(ambiguous, np.inf, CULL_MARGIN * np.maximum(reach[0], reach[1])[:, None])
    (lo_a, hi_a, own_a), (lo_b, hi_b, own_b) = boxes
    # A pair's clusters are consecutive rows of its side's boxes.
    first_a = np.searchsorted(own_a, np.arange(k + 1))
    first_b = np.searchsorted(own_b, np.arange(k + 1))
    found = []
    for p in range(k):
        # Every cluster of a with every cluster of b, on every line (in slices of a's).
        a0, a1, b0, b1 = first_a[p], first_a[p + 1], first_b[p], first_b[p + 1]
        g = grow[p][None, None, :, None]
        step = max(1, SLICE // max((b1 - b0) * LINES, 1))
        for s0 in range(a0, a1, step):
            s1 = min(s0 + step, a1)
            meet = np.all((lo_b[None, b0:b1] <= hi_a[s0:s1, None] + g)
                          & (lo_a[s0:s1, None] <= hi_b[None, b0:b1] + g), axis=3)
            i, j, line = np.nonzero(meet)
            found.append((i + s0, j + b0, line, np.full(len(i), p, np.int64)))
    row_a, row_b, along, pair = (np.concatenate(x) for x in zip(*found)) if found else \
        (np.zeros(0, np.int64),) * 4
    # On a ray along a line, body a's nearest point is where it enters and b's farthest where it
    # leaves (and the other way round for the other way): a cluster pair that cannot be both
    # adds nothing along that line, though its projections meet.
    (enter_a, leave_a), (enter_b, leave_b) = facing
    useful = ((enter_a[row_a, along] & leave_b[row_b, along])
              | (leave_a[row_a, along] & enter_b[row_b, along]))
    # Lines along which some cluster pair meets; a pair's lines after its first without any
    # are not measured (it is cleared there).
    meets = np.zeros((k, LINES), bool)
    meets[pair, along] = True
    stop = np.where(meets.all(axis=1), LINES - 1, np.argmin(meets, axis=1))
    keep = (along <= stop[pair]) & useful
    row_a, row_b, along = row_a[keep], row_b[keep], along[keep]
    # One item per cluster pair, with the bits of its lines.
    key = row_a * max(len(own_b), 1) + row_b
    order = np.argsort(key, kind="stable")
    key = key[order]
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(key) else np.zeros(0, int)
    bits = np.bitwise_or.reduceat(np.int64(1) << along[order], first) if len(key) else \
        np.zeros(0, np.int64)
    row_a, row_b = row_a[order][first], row_b[order][first]
    # Packed cluster indices.
    pair = own_a[row_a]
    start = pack.cluster_start
    ca = start[pair_shapes[pair, 0]] + row_a - first_a[pair]
    cb = start[pair_shapes[pair, 1]] + row_b - first_b[pair]
    return pair, ca, cb, bits


def skip_lines(positions: np.ndarray, faces: np.ndarray, items: np.ndarray, frames: np.ndarray,
               closed: np.ndarray | None = None) -> np.ndarray:
    """Pass H1's items of chunks of faces (not whole), with the lines along which their two
    chunks' projections are apart skipped, as :func:`depth_items` culls cluster pairs (items
    apart along every line are left out, and a pair's lines past the first along which none
    of its items meets): for items packed apart from the shapes (regions).

    Parameters
    ----------
    positions : (3 P,) float32
        The vertices the items' faces index.
    faces : (3 F,) uint32
    items : (I,) structured array of :data:`~pycinder.focused.measure.pair_work.ITEM`
    frames : (K,) structured array of :data:`~pycinder.focused.measure.pair_work.FRAME`
    closed : (K, 2) bool, optional
        Whether each pair's part of body a, and of b, is a closed solid (its chunks are then
        also left out along the lines where they face the same way, as
        :func:`cluster_facing` says for clusters); without it, none is.

    Returns
    -------
    (I',) structured array of :data:`~pycinder.focused.measure.pair_work.ITEM`
    """
    chunked = (items["whole"] & ITEM_WHOLE) == 0
    if not chunked.any():
        return items
    part = items[chunked]
    k = len(frames)
    points = np.asarray(positions, np.float32).reshape(-1, 3).astype(np.float64)
    corners = np.asarray(faces, np.int64)
    axes, ambiguous = screens(frames)
    width = LINES * axes.shape[2]
    boxes, reach, facing = [], np.zeros(k), []
    lines = np.cross(axes[:, :, 0], axes[:, :, 1])  # (K, LINES, 3): each line's way
    closed = np.zeros((k, 2), bool) if closed is None else np.asarray(closed, bool)
    for side, (first, count, field) in enumerate((("a_start", "a_count", "m0"),
                                                  ("b_start", "b_count", "m1"))):
        m = frames[field].astype(np.float64)
        coef = np.einsum("klaj,kji->klai", axes, m[:, :, :3]).reshape(k, width, 3)
        offset = np.einsum("klaj,kj->kla", axes, m[:, :, 3]).reshape(k, width)
        key = np.stack([part["pair"], part[first], part[count]], axis=1).astype(np.int64)
        chunk, which = np.unique(key, axis=0, return_inverse=True)
        row, j = spread(3 * chunk[:, 2])
        p = points[corners[3 * chunk[row, 1] + j]]
        size = np.linalg.norm(p, axis=1)
        np.maximum.at(reach, chunk[row, 0], _magnitude(m[chunk[row, 0]], size))
        proj = np.empty((len(p), width))
        for pair in np.unique(chunk[:, 0]).tolist():
            rows = slice(*np.searchsorted(chunk[row, 0], [pair, pair + 1]))
            q = p[rows]
            proj[rows] = (q[:, 0:1] * coef[pair, :, 0] + q[:, 1:2] * coef[pair, :, 1]
                          + q[:, 2:3] * coef[pair, :, 2] + offset[pair])
        cut = np.cumsum(3 * chunk[:, 2]) - 3 * chunk[:, 2]
        shape3 = (-1, LINES, axes.shape[2])
        boxes.append((np.minimum.reduceat(proj, cut, axis=0).reshape(shape3)[which.ravel()],
                      np.maximum.reduceat(proj, cut, axis=0).reshape(shape3)[which.ravel()]))
        # Which way each chunk's faces face along each line (both ways where not a solid).
        tri = p.reshape(-1, 3, 3)
        owner = chunk[row[::3], 0]
        # The parts are wound outward in the world; stored through the inverse of the region's
        # map, which turns them inside out where the map mirrors.
        linear = m[:, :, :3]
        normal = np.einsum("ti,tij->tj", np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                           np.linalg.inv(linear)[owner])
        normal *= np.sign(np.linalg.det(linear))[owner][:, None]
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        cos = np.einsum("tj,tlj->tl", normal / np.where(length > 0, length, 1.0), lines[owner])
        cos[length[:, 0] == 0] = 0.0
        open_part = ~closed[chunk[:, 0], side][:, None]
        enters = (np.minimum.reduceat(cos, cut // 3, axis=0) < FACING) | open_part
        leaves = (np.maximum.reduceat(cos, cut // 3, axis=0) > -FACING) | open_part
        facing.append((enters[which.ravel()], leaves[which.ravel()]))
    grow = np.where(ambiguous, np.inf, CULL_MARGIN * reach[:, None])
    pair = part["pair"].astype(np.int64)
    (lo_a, hi_a), (lo_b, hi_b) = boxes
    meet = _meet(lo_a, hi_a, lo_b, hi_b, grow[pair])  # (I, LINES)
    meets = np.zeros((k, LINES), bool)
    np.logical_or.at(meets, pair, meet)
    stop = np.where(meets.all(axis=1), LINES - 1, np.argmin(meets, axis=1))
    meet &= np.arange(LINES) <= stop[pair][:, None]
    (enter_a, leave_a), (enter_b, leave_b) = facing
    meet &= (enter_a & leave_b) | (leave_a & enter_b)  # as for clusters (_meeting_lines)
    bits = (meet.astype(np.int64) << np.arange(LINES)).sum(axis=1)
    part["whole"] = (part["whole"] & ((1 << ITEM_SKIP_SHIFT) - 1)) \
        | ((((1 << LINES) - 1) & ~bits) << ITEM_SKIP_SHIFT)
    return np.concatenate([items[~chunked], part[bits != 0]])


__all__ = ["AMBIGUOUS", "CULL_MARGIN", "SLICE", "cluster_vertices", "depth_items", "screen_boxes",
           "screens", "skip_lines"]

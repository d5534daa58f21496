"""Tiles: an orthographic view per candidate pair over the region where the pair can touch, and the
atlas that holds them all.

For a candidate pair the region is the box where the pair's bounding volumes overlap (both bodies'
oriented boxes and world boxes), taken in one of three frames: the world's axes, or either body's
own axes. The frame whose box projects to the smallest window wins. The view looks along that
box's longest axis, tilted by :data:`TILT` towards its middle axis about its thinnest one, so that
a thin contact slab stays one slab thick on screen and edges that follow the frame's axes are
never seen end-on. If the boxes are apart along any axis of the three frames, the pair cannot
touch and gets no tile (a separating-axis test for free).

The pixel size is the pair's tolerance (see :mod:`pycinder.request` for the contract). A window
is cut into pieces of at most :data:`MAX_TILE` pixels, and the pieces are packed into the atlas:
bands :data:`ATLAS_WIDTH` pixels wide (narrower for a plan whose every class of tiles fits one
narrower band), one band height per class of tile height, each tile at the next free column of
its class's band. A tile that would cross a band's end is cut in two there.
When the atlas would need more pixels than the budget allows, it is processed in rounds.

Tile coordinates: ``u`` and ``v`` count pixels across the window from its corner, ``z`` counts
pixels along the view direction from the middle of the overlap box. World point
``X = origin + p * (u * axes[0] + v * axes[1] + z * axes[2])``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import threads
from .errors import GpuMemoryError
from .layout import FLAG_COUNT_BACK, FLAG_MIRROR, FLAG_OPEN, FLAG_SKIP_IF_HIT


TILT = 0.41
"""Radians between the view direction and the overlap box's longest axis."""

MAX_TILE = (512, 128)
"""Largest tile, (width, height) in pixels; larger windows are split."""

HEIGHT_CLASSES = (8, 16, 32, 64, 128)
"""Band heights of the atlas: a tile goes to the band of the smallest class that holds it."""

ATLAS_WIDTH = 2048
"""Widest atlas (bands of tiles this wide)."""
MIN_ATLAS_WIDTH = 64
"""Narrowest atlas a small plan gets (see :func:`fitted_width`)."""

MARGIN_PX = 1
"""Pixels added around the overlap box's projection, so that a sample near the box's edge still
has a pixel centre in the window."""


PROBE = (24, 24)
"""Largest probe tile: windows larger than this are probed at their centre first. Deep overlaps,
where most pixels go, are then decided by the probe alone."""
PROBE_PLAN = 2**16
"""Fewest pixels of a plan whose windows are all probed: probes cost the frame a second round of
passes, which a small plan of small bodies does not repay (the measurements behind this are in
the benchmarks' README, "Measurements behind the constants")."""
PROBE_FACES = 4096
"""Fewest faces of a pair (both bodies) whose large window is probed in a plan of any size: a
probe spares the rest of the window's faces, which dense meshes make worth a round (see the
benchmarks' README)."""


LEAD_PAIRS = 64
"""Most pairs planned into rounds of their own, first, when a query stops at its first pair
found (:func:`likely_pairs`; a quarter of the candidates up to this): a dense scene then often
stops after them (see the benchmarks' README)."""
LEAD_FROM = 16
"""Fewest candidate pairs from which a query that stops at its first pair runs the likeliest
first (the rounds of their own cost a frame their passes' fixed cost)."""

PARALLEL_PAIRS = 1024
"""Fewest candidate pairs per thread when planning is shared among threads (see the benchmarks'
README)."""


@dataclass
class TilePlan:
    """Every tile of one frame.

    pair : (T,) int64
        Index of each tile's candidate pair.
    bodies : (T, 2) int64
        The pair's bodies ``(a, b)``.
    axes : (T, 3, 3) float64
        Rows: the world directions of screen x, screen y and the view direction (right-handed).
    origin : (T, 3) float64
        World point at ``u = v = z = 0``.
    pixel : (T,) float64
        World size of one pixel.
    window : (T, 4) int64
        Atlas column and row (relative to the tile's round) and width and height in pixels.
    slab : (T, 2) float64
        Depth range ``(z0, z1)`` of the overlap box, in pixels.
    flags : (T,) int64
        ``FLAG_*`` bits of :mod:`pycinder.layout`.
    round : (T,) int64
        The round the tile is processed in.
    round_rows : list[int]
        Atlas rows used by each round.
    separated : int
        Candidate pairs dropped because their bounding volumes are apart.
    """

    pair: np.ndarray
    bodies: np.ndarray
    axes: np.ndarray
    origin: np.ndarray
    pixel: np.ndarray
    window: np.ndarray
    slab: np.ndarray
    flags: np.ndarray
    round: np.ndarray
    round_rows: list[int] = field(default_factory=list)
    atlas_width: int = ATLAS_WIDTH
    separated: int = 0

    def __len__(self) -> int:
        return len(self.pair)

    @property
    def pixels(self) -> int:
        """Pixels of all tiles (what is rasterised), not counting the atlas's unused parts."""
        return int((self.window[:, 2] * self.window[:, 3]).sum())

    @property
    def atlas_pixels(self) -> int:
        return int(sum(self.round_rows)) * self.atlas_width

    def to_world(self, tile: np.ndarray, u: np.ndarray, v: np.ndarray, z: np.ndarray
                 ) -> np.ndarray:
        """World points of tile coordinates.

        Parameters
        ----------
        tile : (n,) int
        u, v, z : (n,) float
            Tile coordinates in pixels.

        Returns
        -------
        (n, 3) float64
        """
        a = self.axes[tile]
        uvz = np.stack([u, v, z], axis=1).astype(np.float64) * self.pixel[tile, None]
        return self.origin[tile] + np.einsum("nk,nkj->nj", uvz, a)

    def tile_from_body(self, transforms: np.ndarray) -> np.ndarray:
        """Per tile and side, the (3, 4) matrix from body coordinates to tile coordinates.

        Parameters
        ----------
        transforms : (N, 4, 4) float
            World-from-body matrices of all bodies.

        Returns
        -------
        (T, 2, 3, 4) float64
        """
        t = transforms[self.bodies]                                   # (T, 2, 4, 4)
        scale = (1.0 / self.pixel)[:, None, None, None]
        rot = (self.axes[:, None] @ t[:, :, :3, :3]) * scale
        shift = (self.axes[:, None] @ (t[:, :, :3, 3] - self.origin[:, None, :])[..., None])[..., 0] \
            * scale[..., 0]
        return np.concatenate([rot, shift[..., None]], axis=3)


def _empty_plan(separated: int = 0) -> TilePlan:
    z = np.zeros(0, dtype=np.int64)
    return TilePlan(z, np.zeros((0, 2), np.int64), np.zeros((0, 3, 3)), np.zeros((0, 3)),
                    np.zeros(0), np.zeros((0, 4), np.int64), np.zeros((0, 2)), z, z, [],
                    separated=separated)


def _frames(transforms: np.ndarray) -> np.ndarray:
    """Orthonormal body frames (N, 3, 3), rows = axes, from the transforms' linear parts."""
    q, r = np.linalg.qr(transforms[:, :3, :3])
    # QR's sign convention is arbitrary; that is fine for a frame, but keep it proper.
    det = np.linalg.det(q)
    q[:, :, 2] *= np.where(det < 0, -1.0, 1.0)[:, None]
    return np.transpose(q, (0, 2, 1))


def plan_tiles(pairs: np.ndarray, tolerance: np.ndarray, local_lo: np.ndarray,
               local_hi: np.ndarray, world_lo: np.ndarray, world_hi: np.ndarray,
               transforms: np.ndarray, *, budget_pixels: int, probe: bool = True,
               open_bodies: np.ndarray | None = None, max_pixels: float = float("inf"),
               faces: np.ndarray | None = None, chunk: int = 16384,
               lead: np.ndarray | None = None) -> TilePlan:
    """Tiles for candidate pairs.

    Parameters
    ----------
    pairs : (K, 2) int
        Candidate pairs from the broad phase.
    tolerance : (K,) float
        Each pair's tolerance; it is the pixel size of the pair's tiles.
    local_lo, local_hi : (N, 3) float
        Body-space bounding boxes.
    world_lo, world_hi : (N, 3) float
        World bounding boxes (at least as tight as the transformed body-space boxes).
    transforms : (N, 4, 4) float
        World-from-body matrices.
    budget_pixels : int
        Most atlas pixels processed in one round.
    probe : bool
        Give large windows a probe tile at their centre that runs first; the rest of the window
        is skipped once the pair has a hit.
    open_bodies : (N,) bool, optional
        Bodies that are not solids (tested as surfaces).
    max_pixels : float
        Most pixels the windows may hold together; a plan over it raises
        :class:`~pycinder.errors.GpuMemoryError` before any tile is made.
    faces : (N,) int, optional
        Faces of each body (dense pairs are probed in plans of any size; see
        :data:`PROBE_FACES`). Default: every pair counts as dense.
    chunk : int
        Most pairs one thread plans at once (temporary memory grows with it, times the
        threads of :mod:`pycinder.threads`).
    lead : (L,) int, optional
        Pairs (indices into ``pairs``) whose tiles come first, in rounds of their own.

    Returns
    -------
    TilePlan
    """
    if len(pairs) == 0:
        return _empty_plan()
    bounds = _body_bounds(local_lo, local_hi, world_lo, world_hi, transforms)
    if open_bodies is None:
        open_bodies = np.zeros(len(transforms), dtype=bool)
    # Chunks of at most ``chunk`` pairs, at least one per worker thread when there are enough
    # pairs to share (NumPy releases the GIL on arrays of this size).
    workers = threads.pool()
    parts_wanted = min(threads.WORKERS, len(pairs) // PARALLEL_PAIRS) if workers else 1
    size = max(-(-len(pairs) // max(parts_wanted, 1)), 1)
    size = min(size, chunk)
    starts = range(0, len(pairs), size)

    def plan(s: int) -> dict | None:
        return _plan_chunk(pairs[s:s + size], tolerance[s:s + size], bounds, open_bodies, s)

    parts = list(workers.map(plan, starts)) if workers and len(starts) > 1 else \
        [plan(s) for s in starts]
    keep = [p for p in parts if p is not None]
    separated = len(pairs) - sum(len(p["pair"]) for p in keep)  # a window per kept pair
    if not keep:
        return _empty_plan(separated)
    cat = {k: np.concatenate([p[k] for p in keep]) for k in keep[0]}
    _check_pixels(cat, pairs, tolerance, max_pixels)
    cat["w"] = cat["w"].astype(np.int64)
    cat["h"] = cat["h"].astype(np.int64)
    cat["dense"] = np.ones(len(cat["w"]), dtype=bool) if faces is None else \
        faces[cat["bodies"][:, 0]] + faces[cat["bodies"][:, 1]] >= PROBE_FACES
    plan_pixels = float((cat["w"] * cat["h"]).sum())
    groups = [cat]
    if lead is not None:
        first = np.isin(cat["pair"], lead)
        groups = [{k: v[first] for k, v in cat.items()}, {k: v[~first] for k, v in cat.items()}]
    phases = []
    for group in groups:
        dense = group.pop("dense")
        phases += [p for p in _phases(group, probe, dense, plan_pixels) if len(p["w"])]
    width = fitted_width(np.concatenate([p["w"] for p in phases]),
                         np.concatenate([p["h"] for p in phases]))
    return concat_plans([_pack(p, budget_pixels, separated, width) for p in phases])


def likely_pairs(lo: np.ndarray, hi: np.ndarray, pairs: np.ndarray, count: int) -> np.ndarray:
    """The ``count`` candidate pairs likeliest to collide: those whose world boxes overlap most,
    as a share of the smaller box's volume.

    Parameters
    ----------
    lo, hi : (N, 3) float
        World boxes.
    pairs : (K, 2) int
    count : int

    Returns
    -------
    (min(count, K),) int64
        Indices into ``pairs``.
    """
    a, b = pairs[:, 0], pairs[:, 1]
    overlap = np.prod(np.clip(np.minimum(hi[a], hi[b]) - np.maximum(lo[a], lo[b]), 0, None),
                      axis=1)
    smaller = np.minimum(np.prod(hi[a] - lo[a], axis=1), np.prod(hi[b] - lo[b], axis=1))
    share = np.divide(overlap, smaller, out=np.zeros(len(pairs)), where=smaller > 0)
    if count >= len(pairs):
        return np.arange(len(pairs))
    return np.argpartition(-share, count)[:count].astype(np.int64)


def fitted_width(w: np.ndarray, h: np.ndarray) -> int:
    """The narrowest atlas, a power of two from :data:`MIN_ATLAS_WIDTH` to :data:`ATLAS_WIDTH`,
    in which every class of tiles (widths ``w``, heights ``h`` (T,)) fits one band: a small plan
    clears and rasterises less unused atlas (two small bodies: 1,872 pixels of tiles in an atlas
    of 4,096 pixels instead of 65,536). Plans that need more take the widest.

    Returns
    -------
    int
    """
    cls = np.searchsorted(np.array(HEIGHT_CLASSES), h)
    widest = max(float(np.bincount(cls, weights=w).max()), float(w.max()), 1.0)
    if widest >= ATLAS_WIDTH:
        return ATLAS_WIDTH
    return max(MIN_ATLAS_WIDTH, 1 << int(np.ceil(np.log2(widest))))


def concat_plans(plans: list[TilePlan]) -> TilePlan:
    """Plans one after another: rounds of later plans follow those of earlier ones."""
    if len(plans) == 1:
        return plans[0]
    offsets = np.cumsum([0] + [len(p.round_rows) for p in plans[:-1]])
    cat = {name: np.concatenate([getattr(p, name) for p in plans])
           for name in ("pair", "bodies", "axes", "origin", "pixel", "window", "slab", "flags")}
    rounds = np.concatenate([p.round + o for p, o in zip(plans, offsets)])
    return TilePlan(**cat, round=rounds, round_rows=sum((p.round_rows for p in plans), []),
                    atlas_width=plans[0].atlas_width, separated=plans[0].separated)


def _support(rows: np.ndarray, centre: np.ndarray, axes: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """Interval of boxes along directions: ``rows @ centre`` and the half-width ``|rows @ axes|``
    summed over the box's half axes. Shapes broadcast as (..., 3, 3) rows, (..., 3) centres,
    (..., 3, 3) axes; returns (..., 3) centres and half-widths."""
    return (rows @ centre[..., None])[..., 0], np.abs(rows @ axes).sum(axis=-1)


@dataclass
class _BodyBounds:
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
    """

    obb_centre: np.ndarray
    obb_axes: np.ndarray
    aabb_centre: np.ndarray
    aabb_half: np.ndarray
    frames: np.ndarray
    world: np.ndarray
    own: np.ndarray
    mirrored: np.ndarray


def _both(first: tuple[np.ndarray, np.ndarray], second: tuple[np.ndarray, np.ndarray]
          ) -> np.ndarray:
    """(..., 2, 3): the interval ``(lo, hi)`` where two intervals given as (centre, half) hold."""
    (c1, h1), (c2, h2) = first, second
    return np.stack([np.maximum(c1 - h1, c2 - h2), np.minimum(c1 + h1, c2 + h2)], axis=-2)


def _body_bounds(local_lo: np.ndarray, local_hi: np.ndarray, world_lo: np.ndarray,
                 world_hi: np.ndarray, transforms: np.ndarray) -> _BodyBounds:
    # Both boxes as centre + M @ [-1, 1]^3 (columns of M: the box's half axes).
    t3 = transforms[:, :3, :3]
    obb_c = np.einsum("nij,nj->ni", t3, 0.5 * (local_lo + local_hi)) + transforms[:, :3, 3]
    obb_m = t3 * (0.5 * (local_hi - local_lo))[:, None, :]
    aabb_c, aabb_h = 0.5 * (world_lo + world_hi), 0.5 * (world_hi - world_lo)
    frames = _frames(transforms)
    world = _both((obb_c, np.abs(obb_m).sum(axis=2)), (aabb_c, aabb_h))
    own = _both(_support(frames, obb_c, obb_m), _support_box(frames, aabb_c, aabb_h))
    return _BodyBounds(obb_c, obb_m, aabb_c, aabb_h, frames, world, own,
                       np.linalg.det(t3) < 0)


def _support_box(rows: np.ndarray, centre: np.ndarray, half: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_support` of world boxes (``half`` (..., 3) along the world's axes)."""
    return (rows @ centre[..., None])[..., 0], (np.abs(rows) @ half[..., None])[..., 0]


def _plan_chunk(pairs: np.ndarray, tol: np.ndarray, bounds: _BodyBounds,
                open_bodies: np.ndarray, first: int) -> dict | None:
    a, b = pairs[:, 0], pairs[:, 1]
    k = len(pairs)
    # Three candidate frames per pair: world, body a's, body b's.
    cand = np.empty((k, 3, 3, 3))
    cand[:, 0] = np.eye(3)
    cand[:, 1] = bounds.frames[a]
    cand[:, 2] = bounds.frames[b]
    # The box where all four bounds (both bodies' two boxes) hold, in every candidate frame:
    # where a body's own two boxes hold along the world's axes and its own frame's is the
    # body's; only the other body's boxes in a body's frame are the pair's own work.
    lo = np.empty((k, 3, 3))                                                          # frame, axis
    hi = np.empty((k, 3, 3))
    wa, wb = bounds.world[a], bounds.world[b]
    lo[:, 0], hi[:, 0] = np.maximum(wa[:, 0], wb[:, 0]), np.minimum(wa[:, 1], wb[:, 1])
    for f, (me, other) in enumerate(((a, b), (b, a)), start=1):
        rows = bounds.frames[me]
        seen = _both(_support(rows, bounds.obb_centre[other], bounds.obb_axes[other]),
                     _support_box(rows, bounds.aabb_centre[other], bounds.aabb_half[other]))
        mine = bounds.own[me]
        lo[:, f], hi[:, f] = np.maximum(mine[:, 0], seen[:, 0]), np.minimum(mine[:, 1], seen[:, 1])
    apart = (hi < lo).any(axis=(1, 2))
    lo = np.minimum(lo, hi)
    extent = hi - lo
    e_sorted = -np.sort(-extent, axis=2)                                      # long, mid, thin
    c, s = np.cos(TILT), np.sin(TILT)
    p = tol[:, None]
    win_x = (e_sorted[..., 0] * s + e_sorted[..., 1] * c) / p + 2 * MARGIN_PX + 1
    win_y = e_sorted[..., 2] / p + 2 * MARGIN_PX + 1
    best = np.argmin(win_x * win_y, axis=1)
    keep = ~apart
    if not keep.any():
        return None
    idx = np.flatnonzero(keep)
    f = best[idx]
    frame = cand[idx, f]                                                                # (m, 3, 3)
    lo_f, hi_f = lo[idx, f], hi[idx, f]
    o = np.argsort(-extent[idx, f], axis=1)  # the chosen frame's axes: long, mid, thin
    r = np.arange(len(idx))
    long_, mid, thin = frame[r, o[:, 0]], frame[r, o[:, 1]], frame[r, o[:, 2]]
    x_axis = -s * long_ + c * mid
    y_axis = thin.copy()
    d_axis = c * long_ + s * mid
    flip = np.einsum("ni,ni->n", np.cross(x_axis, y_axis), d_axis) < 0
    y_axis[flip] *= -1
    axes = np.stack([x_axis, y_axis, d_axis], axis=1)                                   # (m, 3, 3)
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
    px = tol[idx]
    # Sizes stay floating point until the plan is known to fit (see _check_pixels).
    w = np.ceil((vhi[:, 0] - vlo[:, 0]) / px) + 2 * MARGIN_PX
    h = np.ceil((vhi[:, 1] - vlo[:, 1]) / px) + 2 * MARGIN_PX
    zmid = 0.5 * (vlo[:, 2] + vhi[:, 2])
    origin = ((vlo[:, 0] - MARGIN_PX * px)[:, None] * axes[:, 0]
              + (vlo[:, 1] - MARGIN_PX * px)[:, None] * axes[:, 1] + zmid[:, None] * axes[:, 2])
    z0 = (vlo[:, 2] - zmid) / px
    z1 = (vhi[:, 2] - zmid) / px
    # Count towards the side of the slab with less of the pair's depth extent behind it.
    view = axes[:, 2:3]                                                                 # (m, 1, 3)
    (ca, ha), (cb, hb) = (_support(view, bounds.obb_centre[body], bounds.obb_axes[body])
                          for body in (a[idx], b[idx]))                                 # (m, 1)
    front_len = vlo[:, 2] - np.minimum(ca - ha, cb - hb)[:, 0]
    back_len = np.maximum(ca + ha, cb + hb)[:, 0] - vhi[:, 2]
    flags = np.where(back_len < front_len, FLAG_COUNT_BACK, 0)
    flags |= np.where(bounds.mirrored[a[idx]], FLAG_MIRROR[0], 0)
    flags |= np.where(bounds.mirrored[b[idx]], FLAG_MIRROR[1], 0)
    flags |= np.where(open_bodies[a[idx]], FLAG_OPEN[0], 0)
    flags |= np.where(open_bodies[b[idx]], FLAG_OPEN[1], 0)
    return {
        "pair": idx + first, "bodies": pairs[idx], "axes": axes, "origin": origin, "pixel": px,
        "w": w, "h": h, "slab": np.stack([z0, z1], axis=1), "flags": flags,
    }


def _check_pixels(cat: dict, pairs: np.ndarray, tolerance: np.ndarray, max_pixels: float
                  ) -> None:
    """Raise :class:`~pycinder.errors.GpuMemoryError` when the windows hold more than
    ``max_pixels`` pixels, naming the largest pairs and a tolerance that would fit."""
    pixels = cat["w"] * cat["h"]
    total = float(pixels.sum())
    if total <= max_pixels:
        return
    order = np.argsort(-pixels)[:3]
    worst = ", ".join(f"bodies {pairs[cat['pair'][k]].tolist()} ({pixels[k]:.3g} pixels at "
                      f"tolerance {tolerance[cat['pair'][k]]:.3g})" for k in order)
    # Pixels scale with (1 / tolerance) ** 2.
    scale = np.sqrt(total / max_pixels)
    raise GpuMemoryError(
        f"this query's tiles would hold {total:.3g} pixels, more than max_pixels={max_pixels:.3g} "
        f"(largest: {worst}); a tolerance about {scale:.3g} times coarser fits (for one "
        f"tolerance t: {float(tolerance.max()) * scale:.3g}), or raise max_pixels")


def _window_part(t: dict, rep: np.ndarray, u0: np.ndarray, v0: np.ndarray, w: np.ndarray,
                 h: np.ndarray, extra_flags: int = 0) -> dict:
    """Sub-windows of windows ``rep``: offset (u0, v0) pixels, size (w, h) pixels."""
    out = {k: v[rep] for k, v in t.items()}
    out["origin"] = out["origin"] + (u0 * out["pixel"])[:, None] * out["axes"][:, 0] \
        + (v0 * out["pixel"])[:, None] * out["axes"][:, 1]
    out["w"], out["h"] = w, h
    out["flags"] = out["flags"] | extra_flags
    return out


def _pieces(t: dict, which: np.ndarray, extra_flags: int = 0) -> dict:
    """Windows ``which`` cut into a grid of pieces of at most :data:`MAX_TILE` pixels."""
    w, h = t["w"][which], t["h"][which]
    nx = -(-w // MAX_TILE[0])
    ny = -(-h // MAX_TILE[1])
    pieces = nx * ny
    rep = np.repeat(np.arange(len(which)), pieces)
    piece = np.arange(len(rep)) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    u0 = (piece % nx[rep]) * MAX_TILE[0]
    v0 = (piece // nx[rep]) * MAX_TILE[1]
    return _window_part(t, which[rep], u0, v0, np.minimum(w[rep] - u0, MAX_TILE[0]),
                        np.minimum(h[rep] - v0, MAX_TILE[1]), extra_flags)


def _phases(t: dict, probe: bool, dense: np.ndarray, plan_pixels: float) -> list[dict]:
    """The tiles of each phase. Without probes, one phase of every window's pieces. With probes,
    windows larger than :data:`PROBE` first get a probe at their centre (phase 0, with the small
    windows), and their pieces come in phase 1, skipped on the GPU once the pair has a hit. In a
    plan of fewer than :data:`PROBE_PLAN` pixels (``plan_pixels``, of every window of the plan)
    only the windows of ``dense`` pairs (T,) are probed."""
    everything = np.arange(len(t["w"]))
    big = (t["w"] > PROBE[0]) | (t["h"] > PROBE[1])
    if plan_pixels < PROBE_PLAN:
        big &= dense
    if not probe or not big.any():
        return [_pieces(t, everything)]
    small = np.flatnonzero(~big)
    large = np.flatnonzero(big)
    pw = np.minimum(t["w"][large], PROBE[0])
    ph = np.minimum(t["h"][large], PROBE[1])
    probes = _window_part(t, large, (t["w"][large] - pw) // 2, (t["h"][large] - ph) // 2, pw, ph)
    first = {k: np.concatenate([v[small], probes[k]]) for k, v in t.items()}
    return [first, _pieces(t, large, FLAG_SKIP_IF_HIT)]


def _pack(t: dict, budget_pixels: int, separated: int, atlas_width: int | None = None
          ) -> TilePlan:
    """Place the tiles in atlas bands ``atlas_width`` wide (at least a tile's largest width;
    default: :func:`fitted_width`), cutting tiles at band ends, and split the bands into rounds
    of at most ``budget_pixels``."""
    if atlas_width is None:
        atlas_width = fitted_width(t["w"], t["h"])
    classes = np.array(HEIGHT_CLASSES)
    cls = np.searchsorted(classes, t["h"])
    # The tiles are gathered once, at the end: ``order`` sorts them by class, ``src`` appends
    # the second parts of cut tiles, ``o`` sorts them by band.
    order = np.argsort(cls, kind="stable")
    cls = cls[order]
    w = t["w"][order]
    # Start column of every tile in its class's run of bands.
    first_of_class = np.searchsorted(cls, np.arange(len(classes)))
    csum = np.cumsum(w)
    before = np.concatenate([[0], csum[:-1]])
    class_base = np.concatenate([[0], csum])[first_of_class][cls]
    start = before - class_base
    band = start // atlas_width
    end = start + w
    cut = (end - 1) // atlas_width > band
    # Cut the tiles that cross a band's end: the first part keeps the tile, the rest is a copy.
    first_w = np.where(cut, (band + 1) * atlas_width - start, w)
    rest = np.flatnonzero(cut)
    cols = np.concatenate([start % atlas_width, np.zeros(len(rest), np.int64)])
    bands = np.concatenate([band, band[rest] + 1])
    widths = np.concatenate([first_w, w[rest] - first_w[rest]])
    src = np.concatenate([np.arange(len(w)), rest])
    shift = np.concatenate([np.zeros(len(w)), first_w[rest].astype(np.float64)])
    tile_cls = cls[src]
    # Bands of each class, in class order; rows from the top of the atlas.
    class_width = np.bincount(cls, weights=w, minlength=len(classes))
    class_bands = np.ceil(class_width / atlas_width).astype(np.int64)
    band_class = np.repeat(np.arange(len(classes)), class_bands)
    band_rows = classes[band_class]
    band_first = np.concatenate([[0], np.cumsum(class_bands)])[:-1]
    # Rounds: bands in order, a new round whenever the budget would be passed (few bands).
    rows_budget = max(int(budget_pixels) // atlas_width, 1)
    band_round = np.zeros(len(band_rows), np.int64)
    band_row0 = np.zeros(len(band_rows), np.int64)
    round_rows: list[int] = [0]
    for i, rows in enumerate(band_rows.tolist()):
        if round_rows[-1] and round_rows[-1] + rows > rows_budget:  # a band always fits alone
            round_rows.append(0)
        band_round[i] = len(round_rows) - 1
        band_row0[i] = round_rows[-1]
        round_rows[-1] += rows
    global_band = band_first[tile_cls] + bands
    # Tiles in band order, so that each round's tiles are contiguous.
    o = np.argsort(global_band, kind="stable")
    idx = order[src[o]]
    axes, pixel = t["axes"][idx], t["pixel"][idx]
    origin = t["origin"][idx] + (shift[o] * pixel)[:, None] * axes[:, 0]
    window = np.stack([cols[o], band_row0[global_band[o]], widths[o], t["h"][idx]], axis=1)
    return TilePlan(t["pair"][idx], t["bodies"][idx], axes, origin, pixel, window,
                    t["slab"][idx], t["flags"][idx], band_round[global_band[o]], round_rows,
                    atlas_width, separated)


def repack(plan: TilePlan, budget_pixels: int, atlas_width: int = ATLAS_WIDTH) -> TilePlan:
    """The same tiles in rounds of at most ``budget_pixels`` atlas pixels, in an atlas
    ``atlas_width`` wide (a plan whose rounds hold more work than the device's buffers is run
    again in smaller rounds)."""
    parts = []
    for r in range(len(plan.round_rows)):  # each round on its own: probes stay before pieces
        k = np.flatnonzero(plan.round == r)
        t = {"pair": plan.pair[k], "bodies": plan.bodies[k], "axes": plan.axes[k],
             "origin": plan.origin[k], "pixel": plan.pixel[k], "w": plan.window[k, 2],
             "h": plan.window[k, 3], "slab": plan.slab[k], "flags": plan.flags[k]}
        parts.append(_pack(t, budget_pixels, plan.separated, atlas_width))
    return concat_plans(parts)


def split_depth(plan: TilePlan, which: np.ndarray, budget_pixels: int, cut: bool = True
                ) -> TilePlan:
    """Tiles ``which`` of ``plan``, each cut in two along the view at the middle of its box (or
    not cut, with ``cut=False``), packed into a new atlas: each half lists only the crossings
    within its own half of the box.

    Parameters
    ----------
    plan : TilePlan
    which : (n,) int
        Tiles to cut.
    budget_pixels : int
        Most atlas pixels per round.
    """
    z0, z1 = plan.slab[which, 0], plan.slab[which, 1]
    if not cut:
        t = {"pair": plan.pair[which], "bodies": plan.bodies[which], "axes": plan.axes[which],
             "origin": plan.origin[which], "pixel": plan.pixel[which],
             "w": plan.window[which, 2], "h": plan.window[which, 3], "slab": plan.slab[which],
             "flags": plan.flags[which] & ~FLAG_SKIP_IF_HIT}
        return _pack(t, budget_pixels, 0)
    mid = 0.5 * (z0 + z1)
    t = {
        "pair": np.tile(plan.pair[which], 2), "bodies": np.tile(plan.bodies[which], (2, 1)),
        "axes": np.tile(plan.axes[which], (2, 1, 1)), "origin": np.tile(plan.origin[which], (2, 1)),
        "pixel": np.tile(plan.pixel[which], 2), "w": np.tile(plan.window[which, 2], 2),
        "h": np.tile(plan.window[which, 3], 2),
        "slab": np.concatenate([np.stack([z0, mid], axis=1), np.stack([mid, z1], axis=1)]),
        "flags": np.tile(plan.flags[which] & ~FLAG_SKIP_IF_HIT, 2),
    }
    return _pack(t, budget_pixels, 0)

"""Tiles: an orthographic view per candidate pair over the region where the pair can touch, and the
atlas that holds them all.

For a candidate pair the region is the box where the pair's bounding volumes overlap (both bodies'
oriented boxes and world boxes), taken in one of three frames: the world's axes, or either body's
own axes. The frame whose box projects to the smallest window wins. The view looks along that box's
longest axis, tilted by :data:`~pycinder.focused.plan.plan_numpy_windows.TILT` towards its middle
axis about its thinnest one, so that a thin contact slab stays one slab thick on screen and edges
that follow the frame's axes are never seen end-on. If the boxes are apart along any axis of the
three frames, the pair cannot touch and gets no tile (a separating-axis test for free).

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
from typing import Any

import numpy as np

from ...errors import GpuMemoryError
from ...gpu.layout import FLAG_SKIP_IF_HIT
from .plan_numpy_windows import plan_windows


MAX_TILE = (512, 128)
"""Largest tile, (width, height) in pixels; larger windows are split."""

HEIGHT_CLASSES = (8, 16, 32, 64, 128)
"""Band heights of the atlas: a tile goes to the band of the smallest class that holds it."""
HEIGHT_CLASS_CONSTS = {f"CLASS_ROWS_{i}": rows for i, rows in enumerate(HEIGHT_CLASSES)}
"""The classes as the shaders' constants (``plan_height_classes.wgsl``, which names five)."""
assert len(HEIGHT_CLASSES) == 5, "plan_height_classes.wgsl names five height classes"

ATLAS_WIDTH = 2048
"""Widest atlas (bands of tiles this wide)."""
MIN_ATLAS_WIDTH = 64
"""Narrowest atlas a small plan gets (see :func:`fitted_width`)."""


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
        ``FLAG_*`` bits of :mod:`pycinder.gpu.layout`.
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

    def views(self, which: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``axes``, ``origin``, ``pixel`` and ``slab`` of tiles ``which`` (n,) int only."""
        return self.axes[which], self.origin[which], self.pixel[which], self.slab[which]

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
        t = transforms.take(self.bodies, axis=0)                               # (T, 2, 4, 4)
        inv = (1.0 / self.pixel)[:, None, None, None]
        axes = self.axes[:, None]
        rot = axes @ t[:, :, :3, :3]
        rot *= inv
        shift = axes @ (t[:, :, :3, 3] - self.origin[:, None, :])[..., None]
        shift *= inv
        return np.concatenate([rot, shift], axis=3)


def empty_plan(separated: int = 0) -> TilePlan:
    z = np.zeros(0, dtype=np.int64)
    return TilePlan(z, np.zeros((0, 2), np.int64), np.zeros((0, 3, 3)), np.zeros((0, 3)),
                    np.zeros(0), np.zeros((0, 4), np.int64), np.zeros((0, 2)), z, z, [],
                    separated=separated)


def plan_tiles(pairs: np.ndarray, pair_tolerances: np.ndarray, local_lo: np.ndarray,
               local_hi: np.ndarray, world_lo: np.ndarray, world_hi: np.ndarray,
               transforms: np.ndarray, *, budget_pixels: int, probe: bool = True,
               open_bodies: np.ndarray | None = None, max_pixels: float = float("inf"),
               faces: np.ndarray | None = None, chunk: int = 2048,
               lead: np.ndarray | None = None) -> TilePlan:
    """Tiles for candidate pairs.

    Parameters
    ----------
    pairs : (K, 2) int
        Candidate pairs from the broad phase.
    pair_tolerances : (K,) float
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
        threads of :mod:`pycinder.util.threads`).
    lead : (L,) int, optional
        Pairs (indices into ``pairs``) whose tiles come first, in rounds of their own.

    Returns
    -------
    TilePlan
    """
    if len(pairs) == 0:
        return empty_plan()
    cat = plan_windows(pairs, pair_tolerances, local_lo, local_hi, world_lo, world_hi, transforms,
                       open_bodies=open_bodies, chunk=chunk)
    return tiles_of_windows(cat, pairs, pair_tolerances, budget_pixels=budget_pixels, probe=probe,
                            max_pixels=max_pixels, faces=faces, lead=lead)


def tiles_of_windows(cat: dict | None, pairs: np.ndarray, pair_tolerances: np.ndarray, *,
                     budget_pixels: int, probe: bool = True, max_pixels: float = float("inf"),
                     faces: np.ndarray | None = None, lead: np.ndarray | None = None
                     ) -> TilePlan:
    """The tiles of the windows of candidate pairs, packed into the atlas (the second half of
    :func:`plan_tiles`, whose parameters these are).

    Parameters
    ----------
    cat : dict or None
        The windows of the pairs whose bounding volumes meet, in pair order: ``pair`` (m,),
        ``bodies`` (m, 2), ``axes`` (m, 3, 3), ``origin`` (m, 3), ``pixel`` (m,), ``w`` and
        ``h`` (m,) float, ``slab`` (m, 2) and ``flags`` (m,); None when every pair is apart.
    pairs : (K, 2) int
    pair_tolerances : (K,) float

    Returns
    -------
    TilePlan
    """
    separated = len(pairs) - (0 if cat is None else len(cat["pair"]))  # a window per kept pair
    if cat is None:
        return empty_plan(separated)
    check_pixels(cat, pairs, pair_tolerances, max_pixels)
    w, h = cat["w"].astype(np.int64), cat["h"].astype(np.int64)
    if faces is None:
        dense = None  # every pair
    else:
        bodies = cat["bodies"]
        dense = np.take(faces, bodies[:, 0]) + np.take(faces, bodies[:, 1]) >= PROBE_FACES
    plan_pixels = float((w * h).sum())
    groups: list[np.ndarray | None] = [None]
    if lead is not None:
        first = np.isin(cat["pair"], lead)
        groups = [np.flatnonzero(first), np.flatnonzero(~first)]
    phases: list[_Phase] = []
    for group in groups:
        phases += [p for p in _phases_of(w, h, dense, group, probe, plan_pixels) if len(p.w)]
    if len(phases) == 1:
        width = fitted_width(phases[0].w, phases[0].h)
    else:
        width = fitted_width(np.concatenate([p.w for p in phases]),
                             np.concatenate([p.h for p in phases]))
    return concat_plans([_place(cat, p, budget_pixels, separated, width) for p in phases])


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


_CLASSES = np.array(HEIGHT_CLASSES)
_CLASS_INDEX = np.arange(len(HEIGHT_CLASSES))


def class_of(h: np.ndarray | int) -> np.ndarray:
    """The height class (an index into :data:`HEIGHT_CLASSES`) of tiles ``h`` rows tall, at
    most :data:`MAX_TILE`'s height: the lowest class that holds them (``class_of`` of
    ``plan_height_classes.wgsl``)."""
    return np.searchsorted(_CLASSES, h)


def fitted_width(w: np.ndarray, h: np.ndarray) -> int:
    """The narrowest atlas, a power of two from :data:`MIN_ATLAS_WIDTH` to :data:`ATLAS_WIDTH`,
    in which every class of tiles (widths ``w``, heights ``h`` (T,)) fits one band: a small plan
    clears and rasterises less unused atlas (two small bodies: 1,872 pixels of tiles in an atlas
    of 4,096 pixels instead of 65,536). Plans that need more take the widest.

    Returns
    -------
    int
    """
    cls = class_of(h)
    widest = max(float(np.bincount(cls, weights=w).max()), float(w.max()), 1.0)
    if widest >= ATLAS_WIDTH:
        return ATLAS_WIDTH
    return max(MIN_ATLAS_WIDTH, 1 << int(np.ceil(np.log2(widest))))


def concat_plans(plans: list[TilePlan]) -> TilePlan:
    """Plans one after another: rounds of later plans follow those of earlier ones. The tiles'
    views (``axes``, ``origin``, ``pixel``, ``slab``) are joined when first read
    (:class:`ConcatPlan`): a plan of the GPU planner gathers its own only then."""
    if len(plans) == 1:
        return plans[0]
    offsets = np.cumsum([0] + [len(p.round_rows) for p in plans[:-1]])
    cat = {name: np.concatenate([getattr(p, name) for p in plans])
           for name in ("pair", "bodies", "window", "flags")}
    rounds = np.concatenate([p.round + o for p, o in zip(plans, offsets)])
    return ConcatPlan(plans, **cat, round=rounds,
                      round_rows=sum((p.round_rows for p in plans), []),
                      atlas_width=plans[0].atlas_width, separated=plans[0].separated)


class LazyViewPlan(TilePlan):
    """A :class:`TilePlan` whose tiles' views (``axes``, ``origin``, ``pixel``, ``slab``) are
    made when first read (:meth:`_gather`); the other fields are given."""

    def __init__(self, *, pair: np.ndarray, bodies: np.ndarray, window: np.ndarray,
                 flags: np.ndarray, round: np.ndarray, round_rows: list[int], atlas_width: int,
                 separated: int) -> None:
        self.pair, self.bodies, self.window, self.flags, self.round = \
            pair, bodies, window, flags, round
        self.round_rows, self.atlas_width, self.separated = round_rows, atlas_width, separated
        self._gathered: tuple | None = None

    def _gather(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``axes`` (T, 3, 3), ``origin`` (T, 3), ``pixel`` (T,) and ``slab`` (T, 2)."""
        raise NotImplementedError

    def _view(self, k: int) -> np.ndarray:
        gathered = self._gathered
        if gathered is None:  # two threads may both gather: the same arrays either way
            gathered = self._gathered = self._gather()
        return gathered[k]

    axes = property(lambda self: self._view(0), doc="(T, 3, 3) float64, see TilePlan")
    origin = property(lambda self: self._view(1), doc="(T, 3) float64, see TilePlan")
    pixel = property(lambda self: self._view(2), doc="(T,) float64, see TilePlan")
    slab = property(lambda self: self._view(3), doc="(T, 2) float64, see TilePlan")


class ConcatPlan(LazyViewPlan):
    """The :class:`TilePlan` of :func:`concat_plans`: its parts' views are joined when first
    read."""

    def __init__(self, parts: list[TilePlan], **fields: Any) -> None:
        super().__init__(**fields)
        self._parts = parts

    def _gather(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return tuple(np.concatenate([getattr(p, name) for p in self._parts])  # type: ignore
                     for name in ("axes", "origin", "pixel", "slab"))


def check_pixels(cat: dict, pairs: np.ndarray, pair_tolerances: np.ndarray, max_pixels: float
                  ) -> None:
    """Raise :class:`~pycinder.errors.GpuMemoryError` when the windows hold more than
    ``max_pixels`` pixels, naming the largest pairs and a tolerance that would fit."""
    pixels = cat["w"] * cat["h"]
    total = float(pixels.sum())
    if total <= max_pixels:
        return
    order = np.argsort(-pixels)[:3]
    worst = ", ".join(f"bodies {pairs[cat['pair'][k]].tolist()} ({pixels[k]:.3g} pixels at "
                      f"tolerance {pair_tolerances[cat['pair'][k]]:.3g})" for k in order)
    # Pixels scale with (1 / tolerance) ** 2.
    scale = np.sqrt(total / max_pixels)
    raise GpuMemoryError(
        f"this query's tiles would hold {total:.3g} pixels, more than max_pixels={max_pixels:.3g} "
        f"(largest: {worst}); a tolerance about {scale:.3g} times coarser fits (for one "
        f"tolerance t: {float(pair_tolerances.max()) * scale:.3g}), or raise max_pixels")


@dataclass
class _Phase:
    """The tiles of one phase, before they are placed: each a part of a window of the plan's
    windows (``cat``, see :func:`plan_tiles`), gathered from them only once placed.

    src : (T,) int or None
        The tile's window (None: tile ``i`` is window ``i``).
    w, h : (T,) int64
        Its size in pixels.
    moved : bool or (T,) bool
        Whether the tile is a part of its window (its origin moved by ``u0``, ``v0`` pixels,
        as a part's origin is computed even where they are zero).
    u0, v0 : (T,) int64
        The part's offset in its window, in pixels.
    flags : int
        Flags added to the window's.
    """

    src: np.ndarray | None
    w: np.ndarray
    h: np.ndarray
    moved: bool | np.ndarray
    u0: np.ndarray | None = None
    v0: np.ndarray | None = None
    flags: int = 0


def _pieces_of(src: np.ndarray | None, w: np.ndarray, h: np.ndarray, extra_flags: int = 0
               ) -> _Phase:
    """Windows ``src`` (sizes ``w``, ``h``) cut into a grid of pieces of at most
    :data:`MAX_TILE` pixels."""
    nx = -(-w // MAX_TILE[0])
    ny = -(-h // MAX_TILE[1])
    pieces = nx * ny
    if (pieces == 1).all():
        zero = np.zeros(len(w), dtype=np.int64)
        return _Phase(src, w, h, True, zero, zero, extra_flags)
    rep = np.repeat(np.arange(len(w)), pieces)
    piece = np.arange(len(rep)) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    across = nx[rep]
    u0 = (piece % across) * MAX_TILE[0]
    v0 = (piece // across) * MAX_TILE[1]
    return _Phase(rep if src is None else src[rep], np.minimum(w[rep] - u0, MAX_TILE[0]),
                  np.minimum(h[rep] - v0, MAX_TILE[1]), True, u0, v0, extra_flags)


def _phases_of(w: np.ndarray, h: np.ndarray, dense: np.ndarray | None,
               group: np.ndarray | None, probe: bool, plan_pixels: float) -> list[_Phase]:
    """The tiles of each phase of windows ``group`` (None: all) of sizes ``w``, ``h``. Without
    probes, one phase of every window's pieces. With probes, windows larger than :data:`PROBE`
    first get a probe at their centre (phase 0, with the small windows), and their pieces come
    in phase 1, skipped on the GPU once the pair has a hit. In a plan of fewer than
    :data:`PROBE_PLAN` pixels (``plan_pixels``, of every window of the plan) only the windows of
    ``dense`` pairs (None: every pair is) are probed; the others go whole in phase 0, in pieces
    where larger than a tile."""
    if group is not None:
        w, h = w[group], h[group]
        dense = None if dense is None else dense[group]
    big = (w > PROBE[0]) | (h > PROBE[1])
    if plan_pixels < PROBE_PLAN and dense is not None:
        big &= dense
    if not probe or not big.any():
        return [_pieces_of(group, w, h)]
    # Windows left unprobed go whole (those larger than a tile: in pieces, after them).
    fits = (w <= MAX_TILE[0]) & (h <= MAX_TILE[1])
    small = np.flatnonzero(~big & fits)
    oversize = np.flatnonzero(~big & ~fits)
    large = np.flatnonzero(big)
    wl, hl = w[large], h[large]
    pw = np.minimum(wl, PROBE[0])
    ph = np.minimum(hl, PROBE[1])
    cut = _pieces_of(oversize, w[oversize], h[oversize])
    ns = len(small)
    which = np.concatenate([small, cut.src, large])
    moved = np.ones(len(which), dtype=bool)
    moved[:ns] = False
    zero = np.zeros(ns, dtype=np.int64)
    first = _Phase(which if group is None else group[which],
                   np.concatenate([w[small], cut.w, pw]), np.concatenate([h[small], cut.h, ph]),
                   moved, np.concatenate([zero, cut.u0, (wl - pw) // 2]),
                   np.concatenate([zero, cut.v0, (hl - ph) // 2]))
    return [first, _pieces_of(large if group is None else group[large], wl, hl,
                              FLAG_SKIP_IF_HIT)]


@dataclass
class _Layout:
    """Where tiles go in the atlas (see :func:`_layout`): ``tile`` (T',) the tile each placed
    part is of, in atlas order; ``shift`` (T',) float64, the part's column in its tile; its
    ``window`` (T', 4) and ``round`` (T',); and each round's rows."""

    tile: np.ndarray
    shift: np.ndarray
    window: np.ndarray
    round: np.ndarray
    round_rows: list[int]


def _layout(w: np.ndarray, h: np.ndarray, budget_pixels: int, atlas_width: int) -> _Layout:
    """Place tiles of sizes ``w``, ``h`` (T,) in atlas bands ``atlas_width`` wide, cutting
    tiles at band ends, and split the bands into rounds of at most ``budget_pixels``."""
    width = int(atlas_width)
    n = len(w)
    cls = class_of(h)
    # ``order`` sorts the tiles by class; the second parts of cut tiles come after them.
    order = np.argsort(cls, kind="stable")
    cls = cls[order]
    w = w[order]
    # Start column of every tile in its class's run of bands.
    csum = np.cumsum(w)
    ends = np.concatenate([[0], csum])
    first_of_class = np.searchsorted(cls, _CLASS_INDEX)
    start = (csum - w) - ends[first_of_class][cls]
    band = start // width
    cut = (start + w - 1) // width > band
    # Bands of each class, in class order; rows from the top of the atlas.
    class_ends = ends[first_of_class]
    class_width = np.concatenate([class_ends[1:], ends[-1:]]) - class_ends
    class_bands = -(-class_width // width)
    band_first = np.cumsum(class_bands) - class_bands
    # Rounds: bands in order, a new round whenever the budget would be passed (a band always
    # fits alone); the bands of a class have the same rows, so a class's bands go into a round
    # as many at a time as fit.
    rows_budget = max(int(budget_pixels) // width, 1)
    round_rows: list[int] = [0]
    runs: list[tuple[int, int, int, int]] = []                 # round, first row, rows, bands
    for rows, count in zip(HEIGHT_CLASSES, class_bands.tolist()):
        while count:
            at = round_rows[-1]
            if at and at + rows > rows_budget:
                round_rows.append(0)
                at = 0
            fit = min(count, max(rows_budget // rows, 1) if at == 0 else (rows_budget - at) // rows)
            runs.append((len(round_rows) - 1, at, rows, fit))
            round_rows[-1] = at + fit * rows
            count -= fit
    if len(runs) == 1:
        (rnd, at, rows, count), = runs
        band_round = np.full(count, rnd, dtype=np.int64)
        band_row0 = np.arange(at, at + count * rows, rows, dtype=np.int64)
    else:
        band_round = np.repeat(np.array([r[0] for r in runs], dtype=np.int64),
                               [r[3] for r in runs])
        band_row0 = np.concatenate([np.arange(at, at + count * rows, rows, dtype=np.int64)
                                    for _, at, rows, count in runs] or [np.zeros(0, np.int64)])
    global_band = band_first[cls] + band
    rest = np.flatnonzero(cut)
    if len(rest) == 0:
        tile, shift, cols, widths = order, np.zeros(n), start % width, w
    else:
        # Cut the tiles that cross a band's end: the first part keeps the tile, the rest is a
        # copy; then all in band order, so that each round's tiles are contiguous.
        first_w = np.where(cut, (band + 1) * width - start, w)
        global_band = np.concatenate([global_band, global_band[rest] + 1])
        o = np.argsort(global_band, kind="stable")
        global_band = global_band[o]
        tile = order[np.concatenate([np.arange(n), rest])[o]]
        shift = np.concatenate([np.zeros(n), first_w[rest].astype(np.float64)])[o]
        cols = np.concatenate([start % width, np.zeros(len(rest), np.int64)])[o]
        widths = np.concatenate([first_w, w[rest] - first_w[rest]])[o]
    window = np.empty((len(tile), 4), dtype=np.int64)
    window[:, 0] = cols
    window[:, 1] = band_row0[global_band]
    window[:, 2] = widths
    window[:, 3] = h[tile]
    return _Layout(tile, shift, window, band_round[global_band], round_rows)


def _place(cat: dict, phase: _Phase, budget_pixels: int, separated: int, atlas_width: int
           ) -> TilePlan:
    """The tiles of ``phase`` placed in the atlas (see :func:`_layout`), gathered from the
    windows ``cat`` once."""
    lay = _layout(phase.w, phase.h, budget_pixels, atlas_width)
    tile = lay.tile
    src = tile if phase.src is None else phase.src[tile]
    axes = cat["axes"].take(src, axis=0)
    pixel = cat["pixel"].take(src)
    origin = cat["origin"].take(src, axis=0)
    if phase.moved is not False:
        # As a part's origin has always been computed (its window's, plus zero or more pixels
        # along screen x and y), then a band's cut.
        moved = origin + (phase.u0[tile] * pixel)[:, None] * axes[:, 0] \
            + (phase.v0[tile] * pixel)[:, None] * axes[:, 1]
        origin = moved if phase.moved is True else \
            np.where(phase.moved[tile][:, None], moved, origin)
    origin = origin + (lay.shift * pixel)[:, None] * axes[:, 0]
    flags = cat["flags"].take(src)
    if phase.flags:
        flags |= phase.flags
    return TilePlan(cat["pair"].take(src), cat["bodies"].take(src, axis=0), axes, origin,
                    pixel, lay.window, cat["slab"].take(src, axis=0), flags, lay.round,
                    lay.round_rows, atlas_width, separated)


def _pack(t: dict, budget_pixels: int, separated: int, atlas_width: int | None = None
          ) -> TilePlan:
    """Place the tiles ``t`` (a dict of :class:`TilePlan`'s arrays, with ``w`` and ``h`` in
    place of ``window``) in atlas bands ``atlas_width`` wide (at least a tile's largest width;
    default: :func:`fitted_width`), cutting tiles at band ends, and split the bands into rounds
    of at most ``budget_pixels``."""
    if atlas_width is None:
        atlas_width = fitted_width(t["w"], t["h"])
    lay = _layout(t["w"], t["h"], budget_pixels, atlas_width)
    idx = lay.tile
    axes, pixel = t["axes"][idx], t["pixel"][idx]
    origin = t["origin"][idx] + (lay.shift * pixel)[:, None] * axes[:, 0]
    return TilePlan(t["pair"][idx], t["bodies"][idx], axes, origin, pixel, lay.window,
                    t["slab"][idx], t["flags"][idx], lay.round, lay.round_rows, atlas_width,
                    separated)


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
    axes, origin, pixel, slab = plan.views(which)
    z0, z1 = slab[:, 0], slab[:, 1]
    if not cut:
        t = {"pair": plan.pair[which], "bodies": plan.bodies[which], "axes": axes,
             "origin": origin, "pixel": pixel,
             "w": plan.window[which, 2], "h": plan.window[which, 3], "slab": slab,
             "flags": plan.flags[which] & ~FLAG_SKIP_IF_HIT}
        return _pack(t, budget_pixels, 0)
    mid = 0.5 * (z0 + z1)
    t = {
        "pair": np.tile(plan.pair[which], 2), "bodies": np.tile(plan.bodies[which], (2, 1)),
        "axes": np.tile(axes, (2, 1, 1)), "origin": np.tile(origin, (2, 1)),
        "pixel": np.tile(pixel, 2), "w": np.tile(plan.window[which, 2], 2),
        "h": np.tile(plan.window[which, 3], 2),
        "slab": np.concatenate([np.stack([z0, mid], axis=1), np.stack([mid, z1], axis=1)]),
        "flags": np.tile(plan.flags[which] & ~FLAG_SKIP_IF_HIT, 2),
    }
    return _pack(t, budget_pixels, 0)

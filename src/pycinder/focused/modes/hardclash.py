"""Hard clashes: every pair of bodies that penetrate deeper than a depth ``d``, with its depth.

``Detector(min_depth=d)`` (or ``min_depth=d`` on any entry point) answers "does A penetrate B by
more than d?", Navisworks' hard clash with a tolerance and IfcClash's intersection mode. How deep
a pair is:

* both bodies convex, or one open: its penetration depth, the length of the shortest
  translation that separates it (FCL's and coal's definition); a body inside another is as deep
  as the translation that takes it out;
* a closed body non-convex: its local depth (:mod:`~pycinder.focused.measure.local_depth`), its
  deepest overlapping part's directional depth (below), with both bodies cut to that part's box
  grown by ``d``: how deep they overlap where they overlap, not how far one must travel to leave a
  ring or an opening.

Its contract:

1. A pair deeper than ``d`` is always reported, whatever its shapes: closed or open, convex or
   not, one inside the other.
2. A pair of convex bodies at most ``d / 2`` deep is never reported: touching pairs (face on
   face, end on face, edge on face, butt joints) and pairs apart included; nor is a pair with a
   non-convex body whose overlapping parts, cut to their boxes, are convex and at most ``d / 2``
   deep (a pipe grazing its sleeve).
3. Each reported pair carries its depth (``result.depths``). For convex bodies it is an upper
   bound of the penetration depth (up to rounding), which lies within ``result.depth_errors``
   below it: the distance from the origin to the hull of the measured translations ``U(n) n``
   (each on the boundary of the set of translations that keep convex bodies overlapping, so the
   hull lies inside it) bounds the penetration depth from below, and so does ``DIRECTION_COS``
   times the figure. For a pair measured locally it is the local depth, within its rounding.

How. Along a direction ``n``, moving body a by ``s n`` leaves all of body b behind it on every ray
parallel to ``n`` once ``s`` exceeds the largest ``(farthest point of b) - (nearest point of a)``
over those rays: that ``U(n)`` is a translation that separates the pair, so it is never less than
the penetration depth. Pass H1 (:mod:`pycinder.focused.measure.h1_depth`) finds it exactly over
every face of a and face of b, both ways along 19 lines: the 13 through a cube's centre and its
faces, edges and corners, and each body's own three axes. The pair's directional depth is the least
of them (0 where a direction clears the pair: touching bodies). For convex bodies ``U(n)`` is
exactly the shortest separating translation along ``n``, at most the penetration depth over the
cosine of the angle between ``n`` and the best direction; every direction is within
:data:`DIRECTION_COS` of one of the 26, so the figure is at most ``1 / 0.886`` times the penetration
depth, which keeps promise 2. A pair whose shortest separating translation lies along one of the 19
lines (boxes and beams meeting face to face, whichever way they are turned) is measured exactly;
where it lies elsewhere (two turned boxes meeting edge to edge) the figure is up to that factor
high, within ``result.depth_errors``. Open bodies have no inside: their surfaces' points are the
rays' extremes, so two surfaces crossing deeper than ``d`` are a clash.

Precision. A pair is measured in a frame of its own, centred where its world boxes meet;
single precision bounds a figure's rounding by :data:`ERROR_SCALE` times ``L``, the farthest the
vertices it is computed from lie from that centre. A pair is reported when its figure exceeds
``d`` less that bound, which keeps promise 2 while the bound is at most ``d / 16``. A pair whose
whole bodies would break that (an 84 m slab, a model in map coordinates) keeps its whole figure
where that decides it all the same (more than its bound over ``d``: deeper than ``d``; at most
``d / 2`` less its bound: never reported) and is measured otherwise in
regions (:mod:`~pycinder.focused.measure.regions`): boxes covering where its world boxes meet,
grown by :data:`PRECISION_GROW` ``d``, small enough that their rounding is at most ``d / 32``,
with both bodies cut to each in float64 (solids closed by the box's walls) before they are
rounded. A translation that separates the bodies separates their parts in a region, so a
region's figure is never more than the whole pair's (promise 2 holds as before); whether the pair
is reported is decided by its deepest region's figure. Its reported depth is still the whole
pair's figure, the upper bound of promise 3, and its ``depth_errors`` include the whole pair's
rounding (a region's parts can be separated by less than the whole bodies, as a pipe inside a
wall that a region cuts can leave it through the region's wall). A pair that would need more than
:data:`~pycinder.focused.measure.regions.MAX_REGIONS` regions raises a ``ValueError`` naming it.
A pair measured locally (a non-convex body, figure over ``d`` less its bound, or too large for a
frame of its own) is measured in the same way, in regions covering its overlapping parts' boxes
instead, grown by :data:`~pycinder.focused.measure.local_depth.LOCAL_GROW` ``d``, and reports its
deepest region's figure as its depth, with that region's rounding.

Cost. No pixels, tolerance or records. A pair whose world boxes a translation of at most ``d / 2``
along a world axis clears (a wall standing on its slab, a beam on its column: a third to a half of
the candidate pairs of the real models in the building benchmark) is at most that deep, and takes no
pass at all (:func:`box_figures`). A pair of small bodies is one item, one workgroup's work, which
stops at the first line that clears the pair: touching and apart pairs, most of a building's other
candidates, cost a line or a few. A pair of larger bodies is measured cluster pair by cluster pair,
and a face pair adds to a line's figures only where the faces' projections along it meet: each pair
of face clusters is measured only along the lines where their projections meet
(:mod:`~pycinder.focused.measure.h1_items`, on the host), and within it only the face pairs whose
screen boxes meet are tested exactly (on the GPU), so the cost follows the faces that meet along
each line rather than the product of the two face counts. Where both bodies are solids wound
outward, a cluster pair whose clusters face the same way along a line is left out along it too: on a
ray, body a's nearest point is where it enters and b's farthest where it leaves (and the other way
round), so such a pair adds nothing. Such a pair measures its bodies' axes first and stops there
when one clears it. A pair measured locally whatever its whole figure, with more than
:data:`LOCAL_FIRST_WORK` face pairs, skips the whole-pair pass (:func:`local_first`); the others
measured locally whenever their figure may be over ``d`` need that figure only up to ``d``, their
frame's cap: a line stops as soon as both its figures reach it (a pair overlapping in volume stops
each line at the first face pairs deeper than ``d``). Two spheres of 20,480 faces each overlapping
deeply take 0.8 to 1.4 s as placed and 1.2 s turned, pressed together by 0.4% of their radius 0.55
s, 0.5% apart 0.23 s, and a 20,000-face torus through one 1.5 s (measured locally, in regions),
where every cluster pair along every line took 194 to 274 s (lavapipe on 2 shared CPU cores:
``benchmarks/results/dense.md``).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ...records import empty_records
from ...result import CollisionResult, Stats
from ...scene import Scene
from ...scene.pack import ShapePack
from ..broad.broad_numpy import PairList, sweep_and_prune
from .clearance import ERROR_SCALE
from ..measure.h1_items import depth_items, skip_lines
from ..measure.h1_depth import (
    ITEM_FLIPPED,
    ITEM_WHOLE,
    LINES,
    WHOLE_FACES,
    WHOLE_WORK,
    WORLD_LINES,
    Depth,
    hull_lower_bound,
    lines,
)
from ..measure.local_depth import LOCAL_GROW, convex_pairs, overlap_parts, pair_kinds
from ..measure.pair_work import ITEM, pair_frames
from ..measure.regions import RegionBuffers, meeting_regions, tile_side

if TYPE_CHECKING:
    from .base import ModeHost

PASSES = (Depth,)
"""The hard-clash query's one pass (the pass table is generated from it)."""

CHUNK_PAIRS = 2**16
"""Most pairs measured by one dispatch of pass H1 (their figures, 152 bytes a pair, are read
back per chunk)."""

PRECISION_GROW = 1.0
"""Regions of a pair too large for one frame are grown by this many ``d`` on every side."""

LOCAL_FIRST_WORK = 2**22
"""Face pairs (the product of two bodies' face counts) above which a pair measured locally
skips the whole-pair pass (:func:`local_first`): about two 2,000-face bodies."""

LEAST_LINE = float(np.finfo(np.float32).max)
"""Pass H1's cap for a pair whose figure is its least line's alone: a line stops once both its
figures reach the least figure of the lines measured before it (see ``measure_depth.wgsl``)."""

DIRECTION_COS = 0.886
"""Every direction is within this cosine of one of the 26 directions through a cube's centre and
its faces, edges and corners (the least over all directions is 0.88645)."""


class Figures(NamedTuple):
    """What pass H1 tells of each candidate pair (all (K,) float64 but ``normal``)."""

    depth: np.ndarray
    """The depth reported: the directional depth, or for a pair measured locally its local
    depth."""
    normal: np.ndarray
    """(K, 3): unit direction from body a into body b; moving a by ``-depth * normal`` clears
    the pair (or, measured locally, its deepest part)."""
    rounding: np.ndarray
    """Bound of ``depth``'s rounding."""
    figure: np.ndarray
    """What decides whether a pair is deeper than ``d`` (reported where ``figure > d -
    figure_rounding``): ``depth``, or for a pair measured in regions, its deepest region's."""
    figure_rounding: np.ndarray
    """Bound of ``figure``'s rounding."""
    error: np.ndarray
    """``depth_errors``: for convex pairs, how far below ``depth`` the penetration depth may
    lie; for a pair measured locally, ``depth``'s rounding."""


def plan(scene: Scene, pack: ShapePack, pairs: np.ndarray, cull: bool = True
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The work of pass H1: each pair's frame and its items: its two bodies whole, when one has at
    most :data:`~pycinder.focused.measure.h1_depth.WHOLE_FACES` faces and they make at most
    :data:`~pycinder.focused.measure.h1_depth.WHOLE_WORK` face pairs, else the pairs of their face
    clusters that meet along some line, each along those lines alone
    (:func:`~pycinder.focused.measure.h1_items.depth_items`; with ``cull`` False, every pair of
    their clusters along every line: the same figures, at the cost of the product of their counts).

    Parameters
    ----------
    scene : Scene
    pack : ShapePack
    pairs : (K, 2) int
    cull : bool

    Returns
    -------
    items : (I,) structured array of :data:`~pycinder.focused.measure.pair_work.ITEM`
    frames : (K,) structured array of :data:`~pycinder.focused.measure.pair_work.FRAME`
    reach : (K,) float64
        How far each pair's bodies reach from its frame's centre (``L`` of the rounding bound).
    """
    lo, hi = scene.world_boxes()
    a, b = pairs[:, 0], pairs[:, 1]
    frames, reach = pair_frames(scene.transforms, pairs, lo, hi, np.maximum(lo[a], lo[b]),
                                np.minimum(hi[a], hi[b]), ~scene.open)
    faces = np.diff(pack.face_start)
    shape_a, shape_b = scene.body_shape[a], scene.body_shape[b]
    fa, fb = faces[shape_a], faces[shape_b]
    # A whole pair is one item of both bodies' faces, the body with fewer in workgroup memory.
    w = np.flatnonzero((np.minimum(fa, fb) <= WHOLE_FACES) & (fa * fb <= WHOLE_WORK))
    flip = fa[w] < fb[w]
    small = np.where(flip, shape_a[w], shape_b[w])
    large = np.where(flip, shape_b[w], shape_a[w])
    whole = ITEM.zeros(len(w))
    whole["pair"] = w
    whole["a_start"], whole["a_count"] = pack.face_start[large], faces[large]
    whole["b_start"], whole["b_count"] = pack.face_start[small], faces[small]
    whole["whole"] = ITEM_WHOLE | np.where(flip, ITEM_FLIPPED, 0)
    # The others, cluster pair by cluster pair.
    dense = np.setdiff1d(np.arange(len(pairs)), w)
    items = depth_items(pack, scene.shapes, np.stack([shape_a[dense], shape_b[dense]], axis=1),
                        frames[dense], cull)
    items["pair"] = dense[items["pair"]]
    return np.concatenate([whole, items]), frames, reach


def box_figures(scene: Scene, pairs: np.ndarray, figures: np.ndarray, most: float
                ) -> np.ndarray:
    """Which pairs their world boxes clear by at most ``most`` along a world axis, with those
    axes' figures written (in place) for them.

    Moving body a along world axis ``x`` by ``hi_b - lo_a`` (or against it by ``hi_a - lo_b``)
    takes it past body b's box, and so past b on every ray parallel to ``x``: a separating
    translation along the line, never less than the pair's figure along it (pass H1's) nor than
    its local depth. The boxes hold the bodies (:meth:`~pycinder.scene.Scene.world_boxes`), in
    double precision, so the bound needs no rounding allowance. Such a pair is at most ``most``
    deep; its other lines' figures are set to the largest float so that its least figure is the
    boxes'.

    Parameters
    ----------
    scene : Scene
    pairs : (K, 2) int
    figures : (K, LINES, 2) float64
        Written for the pairs returned: the three world axes' figures (lines 6 to 8, both
        ways) and :data:`LEAST_LINE` elsewhere.
    most : float
        The largest such translation that clears a pair.

    Returns
    -------
    (K,) bool
    """
    lo, hi = scene.world_boxes()
    a, b = np.asarray(pairs, np.int64).T
    box = np.maximum(np.stack([hi[b] - lo[a], hi[a] - lo[b]], axis=2), 0.0)  # (K, 3, 2)
    out = box.min(axis=(1, 2)) <= most
    k = np.flatnonzero(out)
    figures[k] = LEAST_LINE
    world = LINES - WORLD_LINES  # the first world line, x (then y and z)
    figures[k, world:world + 3] = box[k]
    return out


def local_first(scene: Scene, pack: ShapePack, pairs: np.ndarray,
                kinds: np.ndarray | None = None) -> np.ndarray:
    """Which pairs go straight to their local depth, without the whole-pair pass: those measured
    locally whatever their whole figure (:func:`~pycinder.focused.measure.local_depth.pair_kinds`)
    whose bodies make more than :data:`LOCAL_FIRST_WORK` face pairs. The local depth is at most the
    whole figure, so a pair the whole figure would clear is cleared locally too; for a dense
    pair, cutting it with manifold3d costs less than the whole-pair pass over its cluster pairs,
    while for the many small pairs of a building it would cost more.

    Parameters
    ----------
    scene : Scene
    pack : ShapePack
    pairs : (K, 2) int
    kinds : (K,) bool, optional
        :func:`~pycinder.focused.measure.local_depth.pair_kinds` of the pairs, where known.

    Returns
    -------
    (K,) bool
    """
    out = np.zeros(len(pairs), bool)
    if len(pairs) == 0:
        return out
    faces = np.diff(pack.face_start)[scene.body_shape[np.asarray(pairs, np.int64)]]
    dense = np.flatnonzero(faces[:, 0] * faces[:, 1] > LOCAL_FIRST_WORK)
    if len(dense):
        out[dense] = kinds[dense] if kinds is not None else pair_kinds(scene, pairs[dense])
    return out


class HardClash:
    """Hard-clash queries on a focused strategy's device and shapes.

    Parameters
    ----------
    strategy : ModeHost
        The focused strategy that runs the mode.
    """

    def __init__(self, strategy: ModeHost) -> None:
        self.strategy = strategy
        self.depth = Depth(strategy.gpu, timeout=strategy.request.timeout)
        self.regions = RegionBuffers(strategy.gpu.device, "H1 regions")

    def run(self, scene: Scene, stats: Stats, d: float, groups: np.ndarray | None,
            within: np.ndarray | PairList | None) -> CollisionResult:
        """The pairs deeper than ``d`` of a validated scene (see the module's contract)."""
        if len(scene) < 2:
            empty = CollisionResult.empty(stats)
            empty.records_kept = "none"
            return _with_figures(empty, np.zeros(0), np.zeros(0))
        t0 = time.perf_counter()
        lo, hi = scene.world_boxes()
        pairs = sweep_and_prune(lo, hi, within, groups)
        stats.candidates = len(pairs)
        stats.broad_phase = "numpy"
        stats.add_ms("broad phase", (time.perf_counter() - t0) * 1e3)
        f = self.measure_figures(scene, stats, pairs, d)
        keep = f.figure > d - f.figure_rounding
        result = CollisionResult(pairs[keep], empty_records(), stats, scene=scene,
                                 records_kept="none")
        return _with_figures(result, f.depth[keep], f.error[keep])

    def measure(self, scene: Scene, stats: Stats, pairs: np.ndarray, d: float | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each pair's directional depth, the direction it is measured along, and the bound on
        its rounding (of :meth:`measure_figures`)."""
        f = self.measure_figures(scene, stats, pairs, d)
        return f.depth, f.normal, f.rounding

    def measure_figures(self, scene: Scene, stats: Stats, pairs: np.ndarray,
                        d: float | None = None) -> Figures:
        """Each pair's depth, the direction it is measured along, and its bounds (pass H1 on
        the shapes as the strategy uploads them; with ``d``, pairs with a non-convex body that
        may be deeper than ``d`` measured locally, :mod:`~pycinder.focused.measure.local_depth`, and
        pairs too large for one frame in regions).

        Parameters
        ----------
        scene : Scene
        stats : Stats
        pairs : (K, 2) int
        d : float, optional
            The query's depth.

        Returns
        -------
        Figures
        """
        t1 = time.perf_counter()
        pack = self.strategy.pack(scene, stats)
        buffers = self.strategy.frames.buffers  # the shapes as just uploaded, current vertices
        error = np.zeros(len(pairs))
        figures = np.zeros((len(pairs), LINES, 2))
        # Pairs their world boxes clear by at most d / 2 along a world axis (a wall on its
        # slab) are never reported: that translation is their figure, with no pass at all.
        boxed = np.zeros(len(pairs), bool)
        if d is not None and len(pairs):
            boxed = box_figures(scene, pairs, figures, d / 2)
        # Pairs measured locally whenever their whole figure may be over d: that figure
        # matters only up to d (the frames' cap), and dense ones skip the whole-pair pass
        # (see local_first). Of the others, only a pair of convex solids needs every line's
        # figure (the hull's bound): the rest need their least line's.
        kinds, convex = np.zeros(len(pairs), bool), np.zeros(len(pairs), bool)
        rest = np.flatnonzero(~boxed)
        if d is not None and len(rest):
            kinds[rest] = pair_kinds(scene, pairs[rest])
            convex[rest] = convex_pairs(scene, pairs[rest])
        cap = np.where(kinds, d or 0.0, np.where(convex, 0.0, LEAST_LINE))
        first = local_first(scene, pack, pairs, kinds)
        whole = np.flatnonzero(~first & ~boxed)
        for start in range(0, max(len(whole), 1), CHUNK_PAIRS):
            part = whole[start:start + CHUNK_PAIRS]
            items, frames, reach = plan(scene, pack, pairs[part])
            frames["cap"] = cap[part]
            error[part] = ERROR_SCALE * reach
            t2 = time.perf_counter()
            stats.add_ms("upload", (t2 - t1) * 1e3)
            figures[part] = self.depth.run(buffers.positions, buffers.faces, items, frames)
            stats.bytes_read += figures[part].size * 4  # two words per line and pair
            t1 = time.perf_counter()
            stats.add_ms("depth", (t1 - t2) * 1e3)
        flat = np.maximum(figures.reshape(len(pairs), 2 * LINES), 0.0)
        best = np.argmin(flat, axis=1)
        depth = flat[np.arange(len(pairs)), best]
        direction = lines(scene.transforms[pairs[:, 0]], scene.transforms[pairs[:, 1]])
        # Convex pairs: the penetration depth lies within the directions' cosine of the figure
        # (and, for the pairs reported, between the hull of the measured points and it: below).
        bound = depth * (1 - DIRECTION_COS) + error
        figure, rounding = depth.copy(), error.copy()
        if d is not None:
            # Pairs too large (or too far from the origin) for the whole-pair frame to decide
            # are measured in the regions where they meet: those whose figure, within its
            # rounding, may lie above d / 2 and at most d (a figure more than its rounding above
            # d is deeper than d, one at most d / 2 less its rounding never is).
            large = (error > d / 16) & (figure + error > d / 2) & (figure - error <= d)
            near = figure > d - rounding
            local = first | ((near | large) & kinds)
            if local.any():
                k = np.flatnonzero(local)
                figure[k], best[k], rounding[k] = self._local_depth(scene, stats, pairs[k], d)
                depth[k], error[k] = figure[k], rounding[k]
                bound[k] = rounding[k]  # the local depth is the figure itself
            self._large(scene, stats, pairs, d, large & ~local, figure, rounding)
            # The hull's bound (a convex hull per pair) only where it is reported, and only for
            # convex pairs: their measured points lie on the boundary of the translations that
            # keep them overlapping, which the hull then lies within.
            k = np.flatnonzero((figure > d - rounding) & ~local)
            k = k[convex[k]]
            lower = np.maximum(DIRECTION_COS * depth[k], hull_lower_bound(flat[k], direction[k]))
            bound[k] = depth[k] - lower + error[k]
        along = direction[np.arange(len(pairs)), best // 2]
        # Moving a along +n clears the pair (word 2 i): b lies behind a, along -n.
        normal = np.where((best % 2 == 0)[:, None], -along, along)
        return Figures(depth, normal, error, figure, rounding, bound)

    def _local_depth(self, scene: Scene, stats: Stats, pairs: np.ndarray, d: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each pair's local depth (:mod:`~pycinder.focused.measure.local_depth`): its deepest
        overlapping part's figure, the word it is measured along and its rounding bound (0, word
        0 and 0 for a pair that does not overlap in volume)."""
        t0 = time.perf_counter()
        owner, lo, hi = overlap_parts(scene, pairs)
        stats.add_ms("overlap", (time.perf_counter() - t0) * 1e3)
        grow = LOCAL_GROW * d
        region, word, bound, part, _ = self._regions(
            scene, stats, pairs[owner], d, tile_side(d, grow), grow, search=(lo, hi))
        return _deepest(owner[part], len(pairs), region, word, bound)

    def _large(self, scene: Scene, stats: Stats, pairs: np.ndarray, d: float, large: np.ndarray,
               figure: np.ndarray, rounding: np.ndarray) -> None:
        """Measure in regions (in place) the pairs ``large`` flags, too large for a whole-pair
        frame: in tiles small enough for single precision, grown by :data:`PRECISION_GROW`
        ``d``; each pair's figure is its deepest region's."""
        if large.any():
            k = np.flatnonzero(large)
            region, word, bound, owner, _ = self._regions(
                scene, stats, pairs[k], d, tile_side(d, PRECISION_GROW * d), PRECISION_GROW * d)
            figure[k], _, rounding[k] = _deepest(owner, len(k), region, word, bound)

    def _regions(self, scene: Scene, stats: Stats, pairs: np.ndarray, d: float, side: float,
                 grow: float, search: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                            tuple[np.ndarray, np.ndarray]]:
        """Pass H1 over the regions where pairs meet (:func:`~.regions.meeting_regions`: tiles
        of at most ``side``, grown by ``grow``, with the bodies cut to each in float64).

        Returns
        -------
        figure : (R,) float64
            Each region's directional depth.
        word : (R,) int64
            The word it is measured along (``2 * line + way``).
        rounding : (R,) float64
            Its rounding bound.
        owner : (R,) int64
            The row of ``pairs`` it belongs to.
        boxes : (R, 3) float64, (R, 3) float64
            Its world box.
        """
        t0 = time.perf_counter()
        geometry, owner = meeting_regions(scene, pairs, grow, side, solids=True, orient=True,
                                          option="min_depth", value=d, search=search)
        positions, faces, items, frames, reach = geometry.packed(WHOLE_FACES)
        items = skip_lines(positions, faces, items, frames,
                           np.array(geometry.closed, bool).reshape(-1, 2))
        stats.add_ms("regions", (time.perf_counter() - t0) * 1e3)
        t1 = time.perf_counter()
        figures = np.zeros((0, LINES, 2))
        if len(frames):
            self.regions.write(positions, faces)
            figures = self.depth.run(self.regions.positions, self.regions.faces, items, frames)
        stats.bytes_read += figures.size * 4
        stats.add_ms("depth", (time.perf_counter() - t1) * 1e3)
        flat = np.maximum(figures.reshape(len(frames), 2 * LINES), 0.0)
        word = np.argmin(flat, axis=1) if len(frames) else np.zeros(0, np.int64)
        boxes = (np.array([box[0] for box in geometry.boxes]).reshape(-1, 3),
                 np.array([box[1] for box in geometry.boxes]).reshape(-1, 3))
        return flat[np.arange(len(frames)), word], word, ERROR_SCALE * reach, owner, boxes


def _deepest(owner: np.ndarray, n: int, figure: np.ndarray, word: np.ndarray,
             rounding: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pair (``owner`` (R,) of ``n``), its deepest region's figure and word (the one whose
    figure less rounding is largest, what the report tests), and its regions' largest rounding
    bound (0 and word 0 for a pair without regions)."""
    depth = np.zeros(n)
    best = np.zeros(n, np.int64)
    error = np.zeros(n)
    np.maximum.at(error, owner, rounding)
    if len(owner):
        order = np.lexsort((figure - rounding, owner))
        last = order[np.flatnonzero(np.r_[owner[order][1:] != owner[order][:-1], True])]
        depth[owner[last]] = figure[last]
        best[owner[last]] = word[last]
    return depth, best, error


def _with_figures(result: CollisionResult, depths: np.ndarray, errors: np.ndarray
                  ) -> CollisionResult:
    result.depths = np.asarray(depths, np.float64)
    result.depth_errors = np.asarray(errors, np.float64)
    return result


__all__ = ["DIRECTION_COS", "ERROR_SCALE", "LOCAL_FIRST_WORK", "PASSES", "Figures", "HardClash",
           "box_figures", "local_first", "plan"]

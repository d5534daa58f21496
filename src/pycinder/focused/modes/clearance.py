"""Clearance queries: every pair of bodies closer than a distance ``c``, with its distance.

``Detector(clearance=c)`` (or ``clearance=c`` on any entry point) answers "is A within c of B?",
Navisworks' and IfcClash's clearance test, a robot link's padding. Its contract:

1. A pair whose surfaces are closer than ``c`` is always reported; so is every pair that
   overlaps (surfaces that cross or touch, or a body inside a closed other).
2. A pair whose surfaces are more than ``c + c/8`` apart is never reported.
3. Each reported pair carries its distance (``result.distances``): the distance between the two
   surfaces, 0 for pairs that overlap, within ``result.distance_errors`` of the truth.

How. The candidates are the pairs whose world boxes are within ``c``. For each, pass C1
(:mod:`pycinder.focused.measure.c1_distance`) measures the distance between the two surfaces
exactly, in single precision, over the pairs of face clusters whose world boxes are within ``c``:
two triangles are closest at an edge and an edge or at a vertex and a face, or are 0 apart where an
edge of one passes through the other. Only the cluster pairs that can be nearer than the least
distance found are measured (:meth:`~pycinder.focused.measure.c1_distance.Distance.nearest`): first
each pair's cluster pairs with the nearest points, then those of the others whose boxes are
nearer than the least distance found so far plus :data:`NEAREST_MARGIN` times its error bound
(none once it is 0); a cluster pair left out could not have been nearer, so the figure is that
of every cluster pair within ``c``, bit for bit. A distance of surfaces misses a body wholly
inside another with their surfaces farther apart than ``c``: of such a pair, whose surfaces do
not meet, one body is inside the other (closed) one exactly where one of its vertices is, which
a ray-parity test of one vertex finds, in float64 against the other's faces (distance 0). No
pixels are drawn: the query has no tolerance and keeps no records.

Precision. Each pair is measured in a frame of its own, centred where its bodies can be within
``c``; single precision then bounds the error of a distance by :data:`ERROR_SCALE` times ``L``,
the farthest the measured vertices lie from that centre (``result.distance_errors``). A pair is
reported when its measured distance is below ``c`` plus that bound (promise 1), which keeps
promise 2 while the bound is at most ``c / 16``. A pair whose whole bodies would break that, and
whose whole-pair distance within its bound is neither below ``c`` nor above ``c + c / 8``, is
measured in regions (:mod:`~pycinder.focused.measure.regions`): boxes where its world boxes meet,
grown by ``c`` and small enough for a bound of ``c / 32``, with the faces clipped to each in
float64; two points closer than ``c`` lie in one region, so the least distance over the regions
is the pair's. A pair that would need more than
:data:`~pycinder.focused.measure.regions.MAX_REGIONS` regions raises a ``ValueError`` naming it.

Cost. The distance pass runs over cluster pairs (64 x 64 triangle pairs each) near the pair's
closest approach: surfaces that cross cost the few cluster pairs measured first, surfaces apart
those whose boxes are within the least distance of each other, so the cost grows with the
surface near the closest approach rather than with all the surface within ``c``; the test of
a vertex inside the other body runs once per pair whose surfaces do not meet, against the
other body's faces when the vertex lies in its box. Two overlapping spheres of 20,480 faces each at
``c`` = 10% of their radius take 0.02 s, a pair 0.5% of their radius apart 0.24 s
(lavapipe on 2 shared CPU cores, ``benchmarks/results/dense.md``; every cluster pair within
``c`` took 0.8 s).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from ...records import empty_records
from ...result import CollisionResult, Stats
from ...scene import Scene
from ...scene.pack import ShapePack
from ..broad.broad_numpy import PairList, sweep_and_prune
from ..measure.c1_distance import ITEM, Distance
from ..measure.pair_work import pair_frames, spread
from ..measure.regions import (
    RegionBuffers,
    body_vertices,
    contains,
    meeting_regions,
    tile_side,
    world_triangles,
)

if TYPE_CHECKING:
    from .base import ModeHost

PASSES = (Distance,)
"""The clearance query's one pass (the pass table is generated from it)."""

ERROR_SCALE = 2.0**-16
"""Bound of a measured distance's error, per unit of the pair's reach from its frame's centre."""

NEAREST_MARGIN = 4.0
"""Cluster pairs whose boxes are farther apart than the least distance found plus this many
times a distance's error bound are not measured (they could not be nearer)."""


def cluster_boxes(pack: ShapePack, shapes: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body-space box of every cluster of the packed shapes, and a point of its surface near
    the box's centre, from the shapes' current vertices (a pack keeps those of the frame that
    made it; a deforming shape has new ones).

    Parameters
    ----------
    pack : ShapePack
    shapes : list of Shape
        The shapes packed, in the pack's order.

    Returns
    -------
    lo, hi : (C, 3) float64
    point : (C, 3) float64
        The centroid of the cluster's face whose centroid is nearest the box's centre.
    """
    positions = np.concatenate([s.vertices for s in shapes]) if shapes else pack.positions
    corners = positions[pack.faces.reshape(-1)].reshape(-1, 3, 3).astype(np.float64)
    face_lo, face_hi = corners.min(axis=1), corners.max(axis=1)
    start = pack.clusters[:, 0].astype(np.int64)
    if len(start) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3))
    lo, hi = np.minimum.reduceat(face_lo, start), np.maximum.reduceat(face_hi, start)
    cluster = np.repeat(np.arange(len(start)), pack.clusters[:, 1].astype(np.int64))
    centroid = corners.mean(axis=1)
    off = ((centroid - 0.5 * (lo + hi)[cluster]) ** 2).sum(axis=1)
    order = np.lexsort((off, cluster))
    return lo, hi, centroid[order[np.searchsorted(cluster[order], np.arange(len(start)))]]


def _world(lo: np.ndarray, hi: np.ndarray, transforms: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """World boxes (n, 3) of body-space boxes, each under its transform (n, 4, 4)."""
    linear = transforms[:, :3, :3]
    centre = np.einsum("nij,nj->ni", linear, 0.5 * (lo + hi)) + transforms[:, :3, 3]
    half = np.einsum("nij,nj->ni", np.abs(linear), 0.5 * (hi - lo))
    return centre - half, centre + half


def _gap(lo_a: np.ndarray, hi_a: np.ndarray, lo_b: np.ndarray, hi_b: np.ndarray) -> np.ndarray:
    """Distance between boxes (broadcasting over leading axes): a lower bound of the distance
    between anything inside them."""
    apart = np.maximum(np.maximum(lo_a - hi_b, lo_b - hi_a), 0.0)
    return np.sqrt((apart * apart).sum(axis=-1))


def plan(scene: Scene, pack: ShapePack, pairs: np.ndarray, c: float,
         boxes: tuple[np.ndarray, np.ndarray, np.ndarray]
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The work of pass C1: each pair's frame and its cluster pairs within ``c``.

    Parameters
    ----------
    scene : Scene
    pack : ShapePack
    pairs : (K, 2) int
    c : float
    boxes : (C, 3) float, (C, 3) float, (C, 3) float
        :func:`cluster_boxes` of ``pack``.

    Returns
    -------
    items : (I,) structured array of :data:`~pycinder.focused.measure.pair_work.ITEM`
    frames : (K,) structured array of :data:`~pycinder.focused.measure.pair_work.FRAME`
    reach : (K,) float64
        How far each pair's bodies reach from its frame's centre (``L`` of the error bound).
    gap : (I,) float64
        The distance between each item's cluster boxes (at most ``c``): a lower bound of its
        clusters' distance.
    apart : (I,) float64
        The distance between a point of each of its clusters: an upper bound of it.
    """
    lo_all, hi_all, point_all = boxes
    start = pack.cluster_start
    face_start = pack.clusters[:, 0].astype(np.int64)
    face_count = pack.clusters[:, 1].astype(np.int64)
    world_lo, world_hi = scene.world_boxes()
    a, b = pairs[:, 0], pairs[:, 1]
    frames, reach = pair_frames(scene.transforms, pairs, world_lo, world_hi,
                                np.maximum(world_lo[a], world_lo[b]) - c,
                                np.minimum(world_hi[a], world_hi[b]) + c)
    # Per side, the clusters of each pair's body within c of the other body's world box.
    near = []
    for body, other in ((a, b), (b, a)):
        shape = scene.body_shape[body]
        row, j = spread(start[shape + 1] - start[shape])
        ids = start[shape][row] + j
        t = scene.transforms[body[row]]
        lo, hi = _world(lo_all[ids], hi_all[ids], t)
        keep = _gap(lo, hi, world_lo[other[row]], world_hi[other[row]]) <= c
        point = np.einsum("nij,nj->ni", t[keep, :3, :3], point_all[ids[keep]]) + t[keep, :3, 3]
        near.append((row[keep], ids[keep], lo[keep], hi[keep], point))
    (row_a, ia, la, ha, pa), (row_b, ib, lb, hb, pb) = near
    # Every near cluster of a with every near cluster of b of the same pair, kept within c.
    na, nb = np.bincount(row_a, minlength=len(pairs)), np.bincount(row_b, minlength=len(pairs))
    pair, i = spread(na * nb)
    first_a, first_b = np.cumsum(na) - na, np.cumsum(nb) - nb
    ka = first_a[pair] + i // np.maximum(nb[pair], 1)
    kb = first_b[pair] + i % np.maximum(nb[pair], 1)
    gap = _gap(la[ka], ha[ka], lb[kb], hb[kb])
    close = gap <= c
    ka, kb = ka[close], kb[close]
    pair, ca, cb, gap = pair[close], ia[ka], ib[kb], gap[close]
    apart = np.sqrt(((pa[ka] - pb[kb]) ** 2).sum(axis=1))
    items = ITEM.zeros(len(pair))
    items["pair"] = pair
    items["a_start"], items["a_count"] = face_start[ca], face_count[ca]
    items["b_start"], items["b_count"] = face_start[cb], face_count[cb]
    return items, frames, reach, gap, apart


class Clearance:
    """Clearance queries on a focused strategy's device and shapes.

    Parameters
    ----------
    strategy : ModeHost
        The focused strategy that runs the mode.
    """

    def __init__(self, strategy: ModeHost) -> None:
        self.strategy = strategy
        self.distance = Distance(strategy.gpu, timeout=strategy.request.timeout)
        self.regions = RegionBuffers(strategy.gpu.device, "C1 regions")
        self._boxes: tuple[tuple, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None

    def run(self, scene: Scene, stats: Stats, c: float, groups: np.ndarray | None,
            within: np.ndarray | PairList | None) -> CollisionResult:
        """The pairs within ``c`` of a validated scene (see the module's contract)."""
        if len(scene) < 2:
            return _with_figures(CollisionResult.empty(stats), np.zeros((0, 2), np.int64),
                                 np.zeros(0), np.zeros(0))
        t0 = time.perf_counter()
        lo, hi = scene.world_boxes()
        pairs = sweep_and_prune(lo - 0.5 * c, hi + 0.5 * c, within, groups)
        stats.candidates = len(pairs)
        stats.broad_phase = "numpy"
        stats.add_ms("broad phase", (time.perf_counter() - t0) * 1e3)
        pack = self.strategy.pack(scene, stats)
        items, frames, reach, gap, apart = plan(scene, pack, pairs, c,
                                                self._cluster_boxes(pack, scene))
        error = ERROR_SCALE * reach
        t0 = time.perf_counter()
        buffers = self.strategy.frames.buffers  # the shapes as just uploaded, current vertices
        # Cluster pairs farther apart than the least distance found are not measured (the
        # figures are those of every cluster pair within c: see Distance.nearest).
        measured = self.distance.nearest(buffers.positions, buffers.faces, items, frames, gap,
                                         apart, NEAREST_MARGIN * error).astype(np.float64)
        # Pairs too large (or too far from the origin) for the whole-pair frame to decide are
        # measured in the regions where they come within c: those whose distance, within its
        # rounding, may be c or more and at most c + c / 8.
        local = (error > c / 16) & (measured + error >= c) & (measured - error <= 1.125 * c)
        if local.any():
            k = np.flatnonzero(local)
            measured[k], error[k] = self._measure_regions(scene, pairs[k], c)
        stats.add_ms("distance", (time.perf_counter() - t0) * 1e3)
        t0 = time.perf_counter()
        near = measured < c + error
        # A pair whose surfaces do not meet overlaps only where one body lies wholly inside the
        # other (closed) one: then any vertex of it does (distance 0, however far apart its
        # surfaces are: a pipe inside a slab, 0.5 c or 2 c from its face).
        contained = np.zeros(len(pairs), bool)
        open_body = scene.open
        for k in np.flatnonzero(measured > 0):
            contained[k] = _nested(scene, int(pairs[k, 0]), int(pairs[k, 1]), lo, hi, open_body)
        stats.add_ms("inside", (time.perf_counter() - t0) * 1e3)
        keep = near | contained
        distances = np.where(contained, 0.0, np.minimum(measured, np.finfo(np.float64).max))
        kept = pairs[keep]
        order = np.lexsort((kept[:, 1], kept[:, 0]))
        result = CollisionResult(kept[order].astype(np.int64), empty_records(), stats,
                                 scene=scene, records_kept="none")
        return _with_figures(result, kept[order].astype(np.int64), distances[keep][order],
                             error[keep][order])

    def _measure_regions(self, scene: Scene, pairs: np.ndarray, c: float
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Pairs measured in the regions where they come within ``c`` (:mod:`~.regions`): tiles
        of the box where their world boxes meet grown by ``c``, each grown by ``c`` and small
        enough that its rounding is at most ``c / 32``, with the faces cut to it in float64.
        Two points closer than ``c`` lie in one grown tile, so the least over the regions is
        the pair's distance wherever that is below ``c``.

        Returns
        -------
        distance : (K,) float64
            The least over the pair's regions (+inf where none holds faces of both).
        error : (K,) float64
            The largest rounding bound of the pair's regions.
        """
        geometry, owner = meeting_regions(scene, pairs, c, tile_side(c, c), solids=False,
                                          orient=False, option="clearance", value=c)
        positions, faces, items, frames, reach = geometry.packed()
        distance = np.full(len(pairs), np.inf)
        error = np.zeros(len(pairs))
        if len(frames):
            self.regions.write(positions, faces)
            measured = self.distance.run(self.regions.positions, self.regions.faces, items,
                                         frames).astype(np.float64)
            np.minimum.at(distance, owner, measured)
            np.maximum.at(error, owner, ERROR_SCALE * reach)
        return distance, error

    def _cluster_boxes(self, pack: ShapePack, scene: Scene
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # A shape object is made for new vertex content: the shapes' identities are the key.
        key = (id(pack), tuple(id(s) for s in scene.shapes))
        if self._boxes is None or self._boxes[0] != key:
            self._boxes = (key, cluster_boxes(pack, scene.shapes))
        return self._boxes[1]


def _nested(scene: Scene, a: int, b: int, lo: np.ndarray, hi: np.ndarray,
            open_body: np.ndarray) -> bool:
    """Whether either body of a pair whose surfaces do not meet lies inside the other (closed)
    one: then any vertex of it does (float64, :func:`~.regions.contains`). ``lo``, ``hi``: the
    scene's world boxes; ``open_body``: :attr:`Scene.open`."""
    origin = 0.5 * (np.maximum(lo[a], lo[b]) + np.minimum(hi[a], hi[b]))
    for inner, outer in ((a, b), (b, a)):
        if open_body[outer]:
            continue
        point = body_vertices(scene, inner, origin)[0][0]
        # A vertex outside the outer body's world box is outside it (whatever boxes the scene
        # has: measured, or given larger by whoever placed the bodies).
        if np.any(point + origin < lo[outer]) or np.any(point + origin > hi[outer]):
            continue
        if contains(world_triangles(scene, outer, origin), point):
            return True
    return False


def _with_figures(result: CollisionResult, pairs: np.ndarray, distances: np.ndarray,
                  errors: np.ndarray) -> CollisionResult:
    """``result`` with the clearance's pairs and figures."""
    result.pairs = pairs
    result.distances = distances
    result.distance_errors = errors
    return result


__all__ = ["ERROR_SCALE", "NEAREST_MARGIN", "PASSES", "Clearance", "cluster_boxes", "plan"]

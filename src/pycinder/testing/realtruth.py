"""Exact truth for real IFC models: every pair of elements whose boxes meet (or lie within a
margin), classified by exact geometry, for the real-model building benchmark
(``benchmarks/buildingreal.py`` of a checkout)::

    IfcModel -> pairs whose world boxes lie within the margin
             -> per pair: python-fcl distance, manifold3d overlap volume (float64), and where
                the elements overlap, two certificates: a ball inside the overlap (its radius
                r bounds every depth from below: any translation that separates the elements,
                here or in a box around the overlap, is at least 2 r), and a translation by
                d / 2 along one of 26 directions or the overlap's own axes that leaves no
                volume in common (the elements are at most d / 2 deep)
             -> must report / must not report / either way, per mode (:func:`verdict`)

The rules, for a hard-clash depth ``d``, a clearance ``c`` and the default query's tolerance
``t`` (1% of the smaller element's size, as pycinder's default):

* hard clashes: must report a pair whose overlap holds a ball of diameter more than ``d``; must
  not report a pair apart, touching (an overlap of no volume), or one that a translation by
  ``d / 2`` separates; either way otherwise (a pair with an element manifold3d cannot take as a
  solid, and touching or crossing: its depth is a surface's). A pair between the certificates
  (deeper than ``d / 2``, no ball of diameter ``d``) is counted as such, never scored.
* clearance: must report a pair closer than ``c`` (touching and overlapping ones included);
  must not report one more than ``9 c / 8`` apart;
* the default query: must report a pair whose overlap holds a ball of radius ``0.71 t``; must not
  report one at least ``t`` apart.

Distances and volumes are computed from the meshes pycinder tests (IfcOpenShell's iterator, as
:func:`~pycinder.bim.ifc.read_ifc` runs it); IfcClash tessellates the same files again with its
own settings, so a pair within a tessellation's chord error of a threshold may differ for it. A
1 nm slack (:data:`EXACT`) absorbs the placements' rounding.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..focused.measure.regions import mesh_solid
from ..util.optional import require
from . import fcl_object

EXACT = 1e-9
"""Metres: distances and depths within this of a threshold count as on it."""
VOLUME = 1e-12
"""Cubic metres of overlap under which two elements only touch (rounding of a float64 boolean
between faces that coincide)."""
BALL_RADIUS = 0.71
"""The default query's contract: a pair whose overlap holds a ball of this many tolerances'
radius is always reported."""

_DIRECTIONS = np.array([v for v in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(v)])
_DIRECTIONS /= np.linalg.norm(_DIRECTIONS, axis=1, keepdims=True)


@dataclass
class PairTruth:
    """One pair's exact figures.

    Attributes
    ----------
    a, b : int
        The model's body indices, ``a < b``.
    distance : float
        Metres between the surfaces (python-fcl), 0 where the elements overlap in volume.
    volume : float or None
        Cubic metres in common (manifold3d), None where an element is not a solid manifold3d
        takes (open, or wound past repair).
    ball : float
        Radius of a ball found inside the overlap (0 where none was sought or found).
    shallow : dict
        Depth ``d`` to whether a translation by ``d / 2`` separates the elements (only for
        overlapping solids).
    tolerance : float
        The default query's tolerance of the pair (1% of the smaller element's box diagonal).
    """

    a: int
    b: int
    distance: float
    volume: float | None
    ball: float = 0.0
    shallow: dict[float, bool] = field(default_factory=dict)
    tolerance: float = 0.0

    @property
    def kind(self) -> str:
        """``"apart"``, ``"touching"``, ``"overlapping"`` or ``"crossing"`` (a surface
        touching or crossing the other element: no volume to tell)."""
        if self.distance > EXACT:
            return "apart"
        if self.volume is None:
            return "crossing"
        return "overlapping" if self.volume > VOLUME else "touching"


def verdict(p: PairTruth | None, mode: str, value: float | None = None) -> str:
    """``"must"``, ``"never"`` or ``"either"``: what a pair's truth asks of ``mode``
    (``"min_depth"`` with ``value`` d, ``"clearance"`` with ``value`` c, or ``"default"``; see
    the module's rules). A pair outside the truth (None) is farther apart than its margin and
    its default tolerance (:func:`truth_pairs`)."""
    if p is None:
        return "never"
    if mode == "clearance":
        assert value is not None
        if p.distance < value - EXACT:
            return "must"
        return "never" if p.distance > value * 9 / 8 + EXACT else "either"
    kind = p.kind
    if mode == "default":
        if p.distance >= p.tolerance - EXACT:
            return "never"
        return "must" if p.ball >= BALL_RADIUS * p.tolerance else "either"
    assert value is not None
    if kind in ("apart", "touching"):
        return "never"
    if kind == "crossing":
        return "either"
    if 2.0 * p.ball > value + EXACT:
        return "must"
    return "never" if p.shallow.get(value, False) else "either"


def inscribed_radius(part: Any) -> float:
    """A lower bound of the radius of the largest ball inside a manifold3d solid: the best of
    a grid of points over its box and the centre of its faces, refined by a pattern search,
    each point's distance from the surface exact (trimesh's closest points, in float64)."""
    import trimesh

    mesh = part.to_mesh64()
    v = np.asarray(mesh.vert_properties, np.float64)[:, :3]
    f = np.asarray(mesh.tri_verts, np.int64).reshape(-1, 3)
    tm = trimesh.Trimesh(v, f, process=False)
    lo, hi = v.min(axis=0), v.max(axis=0)
    axes = [np.linspace(lo[i], hi[i], 10)[1:-1] for i in range(3)]
    points = np.vstack([np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3),
                        tm.triangles_center.mean(axis=0)[None]])
    depth = trimesh.proximity.signed_distance(tm, points)  # positive inside
    k = int(np.argmax(depth))
    best, x = float(depth[k]), points[k]
    step = float((hi - lo).max()) / 16
    while step > 1e-6 * max(1.0, float((hi - lo).max())):
        moves = x + step * np.vstack([np.eye(3), -np.eye(3)])
        got = trimesh.proximity.signed_distance(tm, moves)
        j = int(np.argmax(got))
        if got[j] > best:
            best, x = float(got[j]), moves[j]
        else:
            step /= 2
    return max(best, 0.0)


def _separated_by(a: Any, b: Any, shift: float, part: Any) -> bool:
    """Whether moving solid ``b`` by ``shift`` along one of the 26 directions, or along one of
    the overlap ``part``'s own axes either way, leaves no volume in common with ``a``."""
    mesh = part.to_mesh64()
    v = np.asarray(mesh.vert_properties, np.float64)[:, :3]
    axes = np.linalg.svd(v - v.mean(axis=0), full_matrices=False)[2] if len(v) > 3 else \
        np.eye(3)
    for u in np.vstack([_DIRECTIONS, axes, -axes]):
        if (a ^ b.translate(tuple(shift * u))).volume() <= VOLUME:
            return True
    return False


def truth_pairs(model: Any, margin: float) -> np.ndarray:
    """(K, 2) int64: the pairs of the model's bodies whose world boxes lie within ``margin`` of
    each other, or within the pair's default tolerance (:func:`body_tolerances`) where that is
    more: a pair left out is farther apart than every threshold its verdicts use."""
    from ..focused.broad.broad_numpy import sweep_and_prune

    bounds = np.array([b.mesh.bounds for b in model.bodies], np.float64).reshape(-1, 2, 3)
    size = body_tolerances(model)
    widest = max(margin, float(size.max(initial=0.0)))
    pairs = sweep_and_prune(bounds[:, 0] - widest / 2, bounds[:, 1] + widest / 2)
    a, b = pairs[:, 0], pairs[:, 1]
    gap = np.maximum(np.maximum(bounds[b, 0] - bounds[a, 1], bounds[a, 0] - bounds[b, 1]), 0.0)
    keep = np.linalg.norm(gap, axis=1) <= np.maximum(margin, np.minimum(size[a], size[b]))
    return pairs[keep]


def body_tolerances(model: Any) -> np.ndarray:
    """(N,) float64: each element's default tolerance alone, 1% of its box diagonal (a pair's is
    the smaller of its two)."""
    return np.array([0.01 * float(np.linalg.norm(b.mesh.extents)) for b in model.bodies])


def exact_truth(model: Any, margin: float, depths: Sequence[float] = (),
                progress: Any = None) -> dict[tuple[int, int], PairTruth]:
    """Every pair of the model's elements within ``margin`` of each other (or within their
    default tolerance, :func:`truth_pairs`), with its exact figures (:class:`PairTruth`),
    the certificates made for each hard-clash depth of ``depths``. The overlap volume is
    computed for every pair within ``margin`` and every pair one of whose boxes holds the
    other's (one element inside the other, its surfaces apart).

    Parameters
    ----------
    model : IfcModel
    margin : float
        Metres: pairs whose boxes lie farther apart (and farther than their tolerance) are
        apart by more, and left out.
    depths : sequence of float
        Hard-clash depths ``d`` whose ``d / 2`` translations are tried on overlapping pairs.
    progress : callable, optional
        Called with a line of text every 500 pairs.

    Returns
    -------
    dict
        ``(a, b)`` to :class:`PairTruth`.
    """
    fcl = require("fcl", "the real-model truth", "bench", package="python-fcl")
    bodies = model.bodies
    size = body_tolerances(model)
    objects: dict[int, Any] = {}
    out: dict[tuple[int, int], PairTruth] = {}
    pairs = truth_pairs(model, margin)
    for n, (i, j) in enumerate(pairs.tolist()):
        if progress is not None and n % 500 == 0:
            progress(f"exact truth: {n:,} of {len(pairs):,} pairs")
        a, b = bodies[i].mesh, bodies[j].mesh
        for k in (i, j):
            if k not in objects:
                objects[k] = fcl_object(bodies[k].mesh)
        hit = fcl.collide(objects[i], objects[j], fcl.CollisionRequest(), fcl.CollisionResult())
        distance = 0.0 if hit else float(fcl.distance(
            objects[i], objects[j], fcl.DistanceRequest(), fcl.DistanceResult()))
        truth = PairTruth(i, j, max(distance, 0.0), None,
                          tolerance=float(min(size[i], size[j])))
        # Surfaces apart, yet overlapping: one element inside the other (its box inside the
        # other's), however far their surfaces lie apart.
        inside = bool(np.all(a.bounds[0] >= b.bounds[0]) and np.all(a.bounds[1] <= b.bounds[1])
                      or np.all(b.bounds[0] >= a.bounds[0]) and np.all(b.bounds[1] <= a.bounds[1]))
        if distance <= margin or inside:
            lo, hi = np.maximum(a.bounds[0], b.bounds[0]), np.minimum(a.bounds[1], b.bounds[1])
            origin = 0.5 * (lo + hi)
            sa = mesh_solid(a.vertices, a.faces, origin)
            sb = mesh_solid(b.vertices, b.faces, origin)
            if sa is not None and sb is not None:
                overlap = sa ^ sb
                truth.volume = max(float(overlap.volume()), 0.0)
                if truth.volume > VOLUME:
                    truth.distance = 0.0  # one inside the other has surfaces apart
                    parts = [p for p in overlap.decompose() if p.volume() > VOLUME]
                    truth.ball = max((inscribed_radius(p) for p in parts), default=0.0)
                    truth.shallow = {d: 2.0 * truth.ball <= d and
                                     _separated_by(sa, sb, 0.5 * d, parts[0])
                                     for d in depths} if len(parts) == 1 else {}
        out[(i, j)] = truth
    return out


def score(truth: dict[tuple[int, int], PairTruth], reported: set[tuple[int, int]], mode: str,
          value: float | None = None, names: Sequence[str] | None = None,
          shown: int = 8) -> dict[str, Any]:
    """Reported pairs (body indices, ``a < b``) against the truth.

    Returns
    -------
    dict
        ``must``, ``found``, ``recall``, ``false`` (reported where they must not be),
        ``either`` (reported where either way is right), ``undecided`` (pairs of the truth that
        may go either way), ``reported``; ``missed`` and ``wrong``: up to ``shown`` of the
        missed and false pairs, in words.
    """
    verdicts = {k: verdict(p, mode, value) for k, p in truth.items()}
    must = {k for k, v in verdicts.items() if v == "must"}
    false = [k for k in sorted(reported) if verdicts.get(k, "never") == "never"]
    either = sum(verdicts.get(k) == "either" for k in reported)

    def said(k: tuple[int, int]) -> str:
        p = truth.get(k)
        who = " / ".join(names[x] if names else str(x) for x in k)
        if p is None:
            return f"{who}: apart by more than the margin"
        return (f"{who}: {p.kind}, distance {p.distance * 1e3:.3g} mm, ball radius "
                f"{p.ball * 1e3:.3g} mm")

    found = len(must & reported)
    return {"must": len(must), "found": found, "recall": found / len(must) if must else 1.0,
            "false": len(false), "either": int(either), "reported": len(reported),
            "undecided": sum(v == "either" for v in verdicts.values()),
            "missed": [said(k) for k in sorted(must - reported)[:shown]],
            "wrong": [said(k) for k in false[:shown]]}


__all__ = ["BALL_RADIUS", "EXACT", "VOLUME", "PairTruth", "exact_truth", "inscribed_radius",
           "score", "body_tolerances", "truth_pairs", "verdict"]

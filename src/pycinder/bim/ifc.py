"""Buildings: IFC files in, clash sets, clashes out (``pip install 'pycinder[bim]'``).

IFC files are read by :mod:`pycinder.files.ifc_elements` (:func:`read_ifc`: one body per element, in
a federated :class:`IfcModel`; :class:`Group` selects clash sets); :func:`find_clashes` checks
group A against group B (or A against itself) and gives a :class:`Clash` list, which
:mod:`pycinder.bim.bcf` writes as BCF. ``pycinder.ifc`` is this module under its earlier name.

* **Modes**: ``min_depth=d`` (hard clashes) and ``clearance=c`` are passed to
  :class:`~pycinder.Detector` as they are. A hard-clash query reports every pair deeper than
  ``d``, never a pair of convex elements at most ``d / 2`` deep (touching pairs included), each
  with its depth and the bound on its error (see :mod:`pycinder.focused.modes.hardclash`); a
  clearance query every pair closer than ``c``, touching and overlapping ones included, each with
  its distance and its bound (see :mod:`pycinder.focused.modes.clearance`). Without either, the
  default query's tolerance contract holds (see :mod:`pycinder.request`): pairs at least ``t``
  apart are never reported, pairs at least ``2 t`` deep always are, and touching pairs may go
  either way.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..files.ifc_elements import (IfcBody, IfcModel, Group, default_cache_dir, files_are_ifc,

    load_file, read_ifc)
from .rules import ClashRules, SetAside, candidate_pairs, set_aside

__all__ = ["IfcBody", "IfcModel", "Group", "Clash", "ClashList", "ClashRules", "read_ifc",
           "find_clashes", "default_cache_dir", "files_are_ifc", "load_file"]


@dataclass(frozen=True)
class Clash:
    """One clashing pair of elements.

    Attributes
    ----------
    a, b : IfcBody
        The two elements (``a`` from the clash set's group A where the groups differ).
    mode : {"default", "min_depth", "clearance"}
        The question answered.
    depth : float or None
        ``min_depth`` mode: the penetration depth in metres (``result.depths``: an upper bound
        of the shortest translation that separates the two, exact for convex elements within
        :attr:`depth_error`); None in the other modes.
    distance : float or None
        ``clearance`` mode: the distance in metres (``result.distances``, 0 where the elements
        overlap); None in the other modes.
    point : (3,) float
        Where to look: the centre of the two elements' bounding boxes' overlap (or of the gap
        between them), in metres.
    depth_error : float or None
        The bound on :attr:`depth`'s error (``result.depth_errors``), where there is a depth.
    distance_error : float or None
        The bound on :attr:`distance`'s error (``result.distance_errors``), where there is a
        distance.
    """

    a: IfcBody
    b: IfcBody
    mode: str
    depth: float | None
    distance: float | None
    point: np.ndarray
    depth_error: float | None = None
    distance_error: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """The clash as plain data (``pycinder check --json``'s pair)."""
        return {"a": self.a.name, "b": self.b.name,
                "a_global_id": self.a.global_id, "b_global_id": self.b.global_id,
                "a_class": self.a.ifc_class, "b_class": self.b.ifc_class,
                "a_file": self.a.file, "b_file": self.b.file, "mode": self.mode,
                "depth": self.depth, "depth_error": self.depth_error,
                "distance": self.distance, "distance_error": self.distance_error,
                "point": [round(float(x), 6) for x in self.point]}


class ClashList(list):
    """The clashes of :func:`find_clashes` (a list of :class:`Clash`), with what its clash rules
    set aside.

    Attributes
    ----------
    set_aside : SetAside
        Each rule's count of pairs set aside, those pairs, and the duplicated GlobalIds
        (:mod:`pycinder.bim.rules`).
    """

    set_aside: SetAside


def mode_options(min_depth: float | None = None, clearance: float | None = None
                 ) -> tuple[str, dict[str, float]]:
    """The query mode (``"default"``, ``"min_depth"``, ``"clearance"``) and the detector
    options that ask for it; a ValueError for both at once or a value that is not positive."""
    if min_depth is not None and clearance is not None:
        raise ValueError("min_depth and clearance ask different questions: give one of them")
    for name, value in (("min_depth", min_depth), ("clearance", clearance)):
        if value is not None:
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a positive distance in metres, got {value!r}")
            return name, {name: float(value)}
    return "default", {}


def make_detector(min_depth: float | None = None, clearance: float | None = None,
                  **options: Any) -> Any:
    """A :class:`~pycinder.Detector` for the mode (:func:`mode_options`), with ``options``
    (other options of :class:`~pycinder.CollisionRequest`)."""
    from ..detector import Detector

    _, extra = mode_options(min_depth, clearance)
    return Detector(**options, **extra)


_FIGURES = {"min_depth": ("depths", "depth_errors"),
            "clearance": ("distances", "distance_errors")}
"""The result's figures of each mode and the bounds on their errors."""


def _figures(result: Any, mode: str, count: int) -> dict[str, np.ndarray | None]:
    """Each pair's figures where the mode's result carries them: ``depth`` and ``depth_error``
    of a hard-clash query (``result.depths``, ``result.depth_errors``), ``distance`` and
    ``distance_error`` of a clearance query; None for every figure the result does not hold."""
    out: dict[str, np.ndarray | None] = {}
    for name, (figure, bound) in _FIGURES.items():
        for key, attr in ((name, figure), (f"{name}_error", bound)):
            value = getattr(result, attr, None) if mode == name else None
            out[key] = None if value is None else np.asarray(value, np.float64).reshape(count)
    return {"depth": out["min_depth"], "depth_error": out["min_depth_error"],
            "distance": out["clearance"], "distance_error": out["clearance_error"]}


def _look_at(a: IfcBody, b: IfcBody) -> np.ndarray:
    lo = np.maximum(a.mesh.bounds[0], b.mesh.bounds[0])
    hi = np.minimum(a.mesh.bounds[1], b.mesh.bounds[1])
    return (lo + hi) / 2


def find_clashes(model: IfcModel, a: Group | str | None = None, b: Group | str | None = None,
                 *, min_depth: float | None = None, clearance: float | None = None,
                 tolerance: float | None = None, detector: Any = None,
                 rules: ClashRules | str | Any = None, **options: Any) -> ClashList:
    """The clashes of a clash set: group ``a`` against group ``b``, or ``a`` against itself.

    Parameters
    ----------
    model : IfcModel
        From :func:`read_ifc`.
    a : Group or str, optional
        Group A (a :class:`Group`, or a selector); default: every element.
    b : Group or str, optional
        Group B; default: A against itself. An element in both groups is tested against the
        others of both.
    min_depth : float, optional
        Hard clashes: every pair deeper than this (metres) is reported, with its depth
        (:attr:`Clash.depth`); a pair of convex elements at most ``min_depth / 2`` deep never
        is, touching pairs included; a non-convex pair only where its depth along one of the
        directions tried exceeds ``min_depth``. Passed to :class:`~pycinder.Detector` as
        ``min_depth`` (see :mod:`pycinder.focused.modes.hardclash`).
    clearance : float, optional
        Clearance: every pair closer than this (metres) is reported, touching and overlapping
        ones included, with its distance (:attr:`Clash.distance`). Passed as ``clearance``
        (see :mod:`pycinder.focused.modes.clearance`).
    tolerance : float, optional
        The detector's tolerance in metres (default: the detector's own).
    detector : Detector, optional
        A detector to query (its request decides the mode); then give no mode or tolerance.
    rules : ClashRules, str or sequence of str, optional
        Which clash rules set pairs aside before the query (:mod:`pycinder.bim.rules`): a
        :class:`ClashRules`, a list for :meth:`ClashRules.parse` (``"default,system"``,
        ``"none"``), or rule names (those only); default: the rules' defaults (doors and
        windows in their openings, other elements in theirs, parts of one assembly, connected
        elements and duplicated GlobalIds set aside; elements of one system tested).
    **options
        Other options of :class:`~pycinder.CollisionRequest`.

    Returns
    -------
    ClashList
        The clashes (a list of :class:`Clash`) in the order of the bodies, ``a`` in group A
        where the groups differ; its ``set_aside`` says what each rule set aside.

    Raises
    ------
    ValueError
        Both modes at once, a mode's value that is not a positive distance, a file that is not
        the model's, a selector IfcOpenShell cannot use.

    Examples
    --------
    .. code-block:: python

        model = read_ifc(["structure.ifc", "mep.ifc"])
        for c in find_clashes(model, "IfcPipeSegment, IfcDuctSegment", "IfcBeam, IfcColumn"):
            print(c.a.name, c.b.name)
        # Hard clashes deeper than 1 cm, each with its depth (touching elements are not):
        for c in find_clashes(model, "IfcPipeSegment", "IfcBeam", min_depth=0.01):
            print(c.a.name, c.b.name, f"{c.depth:.3f} m")
    """
    in_a = model.select(a)
    in_b = model.select(b) if b is not None else in_a
    if detector is None:
        mode, _ = mode_options(min_depth, clearance)
        if tolerance is not None:
            options["tolerance"] = tolerance
        detector = make_detector(min_depth, clearance, **options)
    else:
        if min_depth is not None or clearance is not None or tolerance is not None or options:
            raise ValueError("with a detector, its request decides the mode and tolerance: "
                             "pass no min_depth, clearance, tolerance or options")
        request = detector.request
        mode = ("min_depth" if getattr(request, "min_depth", None) is not None else
                "clearance" if getattr(request, "clearance", None) is not None else "default")
    used = np.flatnonzero(in_a | in_b)
    if b is None or not np.any(in_a & in_b):
        groups = None if b is None else np.where(in_a[used], 0, 1)
    else:  # groups overlap: every pair, then only those across A and B
        groups = None
    bodies = [model.bodies[i] for i in used]
    rules = ClashRules.of(rules)
    out = ClashList()
    margin = getattr(detector.request, "clearance", None) or 0.0
    candidates = candidate_pairs(model, used, groups, 1.001 * margin)
    if b is not None:  # only pairs across the groups
        ca, cb = used[candidates[:, 0]], used[candidates[:, 1]]
        candidates = candidates[(in_a[ca] & in_b[cb]) | (in_b[ca] & in_a[cb])]
    kept, out.set_aside = set_aside(model, used, candidates, rules)
    if len(bodies) < 2:
        return out
    focused = detector.request.strategy == "focused"
    result = detector.find_collisions([x.mesh for x in bodies], None,
                                      names=[x.name for x in bodies],
                                      pairs=kept if focused else None)
    pairs = result.pairs.reshape(-1, 2)
    if not focused:  # the scene strategy tests every pair: keep those the rules leave
        allowed = set(map(tuple, kept.tolist()))
        keep = np.array([tuple(p) in allowed for p in pairs.tolist()], bool)
        for name in ("depths", "depth_errors", "distances", "distance_errors"):
            if getattr(result, name, None) is not None:
                setattr(result, name, np.asarray(getattr(result, name))[keep])
        pairs = pairs[keep]
    figures = _figures(result, mode, len(pairs))
    for k, (i, j) in enumerate(pairs.tolist()):
        gi, gj = used[i], used[j]
        if b is not None:
            if not ((in_a[gi] and in_b[gj]) or (in_b[gi] and in_a[gj])):
                continue
            if not (in_a[gi] and in_b[gj]):  # a from group A, b from group B
                gi, gj = gj, gi
        ba, bb = model.bodies[gi], model.bodies[gj]
        each = {name: None if value is None else float(value[k])
                for name, value in figures.items()}
        out.append(Clash(ba, bb, mode, each["depth"], each["distance"], _look_at(ba, bb),
                         depth_error=each["depth_error"],
                         distance_error=each["distance_error"]))
    return out

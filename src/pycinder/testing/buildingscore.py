"""Answers scored against the generated building (the tests' and the building benchmark's):
reported pairs, depths, distances and groups against the exact truth of
:mod:`pycinder.testing.buildings`.

    truth (exact distance and depth of every pair within 0.2 m, and the tessellation's error)
        -> must report / must not report / either way, per mode and figure d or c
        -> each answer's pairs, figures and groups counted against it

The rules (:func:`must_report`, :func:`must_not_report`), for a hard-clash depth ``d`` or a
clearance ``c``:

* Hard clashes (pycinder's ``min_depth``, IfcClash's intersection mode): every pair deeper than
  ``d`` beyond the tessellation's error must be reported; no pair at most ``d / 2`` deep may be
  (touching and apart pairs included). A pair deeper than ``d / 2`` and at most ``d`` deep may go
  either way: the building's ducts 1 mm into a slab are exactly ``d / 2`` deep at ``d = 2 mm``
  (must not) and exactly ``d`` deep at ``d = 1 mm`` (either way).
* Clearance: every pair closer than ``c`` beyond the tessellation's error must be reported
  (touching and overlapping ones included); none farther than ``9 c / 8``.
* The default query and IfcClash's collision mode: every pair deeper than ``d``; no pair apart.

Only the "must report" side subtracts the tessellation's error: IfcOpenShell tessellates each
circle as a polygon inscribed in it, so every tessellated solid lies inside its exact one, and
a pair's tessellated depth is at most its exact depth and its tessellated distance at least its
exact distance (a translation that separates the exact solids separates the parts inside
them). A pair at most ``d / 2`` deep, or farther than ``9 c / 8``, stays so once tessellated.
Comparisons with ``d``, ``d / 2`` and ``c`` allow :data:`~pycinder.testing.buildings.EXACT` (1 nm)
for the rounding of the placements' sums, so a pair built exactly ``d`` deep is exactly ``d`` deep
whichever way its figure rounds.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from .buildings import EXACT, Building, Relation

DEPTH = 0.01
"""``min_depth`` of the hard-clash runs of the original table, and IfcClash's intersection
tolerance there (metres)."""
CLEARANCE = 0.05
"""``clearance`` of the clearance runs of the original table (metres)."""
HARD = ("min_depth", "intersection")
"""Modes that answer hard clashes: deeper than ``d``, never at most ``d / 2`` deep."""
SHOWN = 8
"""Most pairs named in a score's ``missed`` and ``wrong`` lists."""


def must_report(r: Relation, mode: str, depth: float = DEPTH,
                clearance: float = CLEARANCE) -> bool:
    """Whether a pair of the truth must be reported by ``mode`` (see the module's rules).

    Parameters
    ----------
    r : Relation
        The pair's exact relation.
    mode : {"default", "min_depth", "clearance", "intersection", "collision"}
    depth, clearance : float
        ``d`` and ``c`` in metres.
    """
    if mode == "clearance":
        return r.distance < clearance - r.error - EXACT
    return r.depth > depth + r.error + EXACT


def must_not_report(r: Relation | None, mode: str, depth: float = DEPTH,
                    clearance: float = CLEARANCE) -> bool:
    """Whether a pair must never be reported by ``mode`` (None: a pair outside the truth, at
    least :data:`~pycinder.testing.buildings.MARGIN` apart; see the module's rules)."""
    if r is None:
        return True
    if mode == "clearance":
        return r.distance > clearance * 9 / 8 + EXACT
    if mode in HARD:
        return r.depth <= depth / 2 + EXACT
    return r.distance > 0


def truth_classes(building: Building, mode: str, depth: float = DEPTH,
                  clearance: float = CLEARANCE) -> dict[str, int]:
    """How many of the truth's pairs ``mode`` must report, must not, or may either way.

    Returns
    -------
    dict
        ``must``, ``never`` and ``either`` (counts of the truth's pairs; pairs outside the truth
        are never reported, and not counted).
    """
    out = {"must": 0, "never": 0, "either": 0}
    for r in building.truth.values():
        key = ("must" if must_report(r, mode, depth, clearance) else
               "never" if must_not_report(r, mode, depth, clearance) else "either")
        out[key] += 1
    return out


def _pair_text(building: Building, key: tuple[str, str], r: Relation | None) -> str:
    parts = building.by_id()
    names = " / ".join(parts[g].name if g in parts else g for g in key)
    if r is None:
        return f"{names}: at least 0.2 m apart"
    return (f"{names}: {r.kind}, depth {r.depth * 1e3:.3g} mm, distance "
            f"{r.distance * 1e3:.3g} mm")


def score(building: Building, reported: set[tuple[str, str]], mode: str,
          depth: float = DEPTH, clearance: float = CLEARANCE) -> dict[str, Any]:
    """Score reported pairs (sorted GlobalIds) against the truth.

    Parameters
    ----------
    building : Building
    reported : set of (str, str)
    mode : {"default", "min_depth", "clearance", "intersection", "collision"}
        What the pairs answer (see the module's rules, :func:`must_report` and
        :func:`must_not_report`): the hard-clash modes must find every pair deeper than
        ``depth`` and never one at most ``depth / 2`` deep; clearance every pair closer than
        ``clearance`` and never one farther than ``clearance * 9 / 8``; the default and
        IfcClash's collision mode every overlap deeper than ``depth``, never a pair apart.
    depth, clearance : float
        ``d`` and ``c`` in metres.

    Returns
    -------
    dict
        ``must`` (pairs that must be found), ``found`` (of those), ``recall``, ``touching``
        (touching pairs reported), ``grazes`` (pairs more than 0 and at most ``depth / 2``
        deep, reported), ``near`` (pairs apart but within the margin, reported), ``either``
        (reported pairs that may go either way), ``false`` (pairs that must not be reported,
        reported), ``reported``; ``missed`` and ``wrong``: up to :data:`SHOWN` of the pairs
        missed and of the false ones, in words.
    """
    truth = building.truth
    must = {k for k, r in truth.items() if must_report(r, mode, depth, clearance)}
    false = touching = grazes = near = either = 0
    wrong: list[str] = []
    for k in sorted(reported):
        r = truth.get(k)
        if must_not_report(r, mode, depth, clearance):
            false += 1
            if len(wrong) < SHOWN:
                wrong.append(_pair_text(building, k, r))
        elif k not in must:
            either += 1
        if r is None:
            continue
        touching += r.kind == "touching"
        near += r.kind == "near"
        grazes += 0 < r.depth <= depth / 2 + EXACT
    found = len(must & reported)
    missed = [_pair_text(building, k, truth[k]) for k in sorted(must - reported)[:SHOWN]]
    return {"must": len(must), "found": found,
            "recall": found / len(must) if must else 1.0, "touching": touching,
            "grazes": grazes, "near": near, "either": either, "false": false,
            "reported": len(reported), "missed": missed, "wrong": wrong}


def check_depths(building: Building, clashes: Sequence[Any]) -> dict[str, Any]:
    """Each hard clash's depth against the exact truth.

    Parameters
    ----------
    building : Building
    clashes : sequence of Clash
        From :func:`pycinder.bim.ifc.find_clashes` with ``min_depth``.

    Returns
    -------
    dict
        ``depths_checked`` (clashes whose pair is in the truth), ``depths_outside`` (of those,
        clashes whose depth is farther from the true depth than the two bounds together: the
        clash's :attr:`~pycinder.bim.ifc.Clash.depth_error` and the tessellation's
        :attr:`~pycinder.testing.buildings.Relation.error`) and ``depth_worst`` (the largest
        difference from the true depth, in metres; 0 with nothing checked).
    """
    return _check(building, clashes, "depth", "depths")


def check_distances(building: Building, clashes: Sequence[Any]) -> dict[str, Any]:
    """Each clearance clash's distance against the exact truth, as :func:`check_depths` checks
    depths: ``distances_checked``, ``distances_outside`` (farther from the true distance than
    the clash's :attr:`~pycinder.bim.ifc.Clash.distance_error` and the tessellation's error
    together) and ``distance_worst`` (metres)."""
    return _check(building, clashes, "distance", "distances")


def _check(building: Building, clashes: Sequence[Any], figure: str,
           plural: str) -> dict[str, Any]:
    checked = outside = 0
    worst = 0.0
    for c in clashes:
        r = building.truth.get(tuple(sorted((c.a.global_id, c.b.global_id))))
        value = getattr(c, figure)
        if r is None or value is None:
            continue
        checked += 1
        off = abs(value - getattr(r, figure))
        worst = max(worst, off)
        outside += off > (getattr(c, f"{figure}_error") or 0.0) + r.error + EXACT
    return {f"{plural}_checked": checked, f"{plural}_outside": outside,
            f"{figure}_worst": worst}


def group_counts(clashes: Sequence[Any]) -> dict[str, int]:
    """How many groups the clashes form (:func:`pycinder.bim.groups.group_clashes`): ``groups``
    at the default distance (3 m), ``groups_by_element`` by element alone."""
    from ..bim.groups import group_clashes as group

    return {"groups": len(group(clashes)), "groups_by_element": len(group(clashes, 0))}

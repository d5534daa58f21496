"""Clash rules: pairs of elements a coordinator does not want tested, read from the IFC files
(``pip install 'pycinder[bim]'``).

Building elements touch and overlap by design where the model says they belong together: a door
stands in its wall's opening, the flights of a stair are one stair, walls are joined at their
corners. Navisworks, Solibri and IfcClash users set such pairs aside with rules. Each rule here
reads one kind of relation the files hold (:attr:`pycinder.files.ifc_elements.IfcModel.relations`)
and sets aside the candidate pairs it names, before the query: those pairs are neither tested nor
reported, and each rule says how many it set aside.

======================  ==============================================================  =======
rule                    sets aside                                                      default
======================  ==============================================================  =======
``fills``               a door or window and the element whose opening it fills         on
                        (IfcRelFillsElement, IfcRelVoidsElement)
``openings``            an element in an opening and the element the opening voids:     on
                        one that fills it (IfcRelFillsElement) other than a door or
                        window, or one whose volume reaches into it (a stair through
                        its slab's opening, a duct through its provision for a void)
``assembly``            parts of one assembly, and each part with the whole             on
                        (IfcRelAggregates: a stair's flights, a curtain wall's plates)
``connected``           elements the model connects (IfcRelConnectsElements and its     on
                        subclasses: walls joined at their ends; IfcRelConnectsPorts)
``system``              elements of one system (IfcRelAssignsToGroup to an IfcSystem)   off
``duplicates``          the copies of one GlobalId in two files: reported apart, as     on
                        duplicates, not tested against each other
======================  ==============================================================  =======

A candidate pair is one whose elements' boxes meet (grown by the clearance in a clearance
query): a pair set aside is one the query would have tested. A pair two rules name is counted
under the first, in the order above, so the counts add up to the pairs set aside.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

__all__ = ["ClashRules", "SetAside", "RULES", "set_aside", "candidate_pairs"]

RULES = ("fills", "openings", "assembly", "connected", "system", "duplicates")
"""The rules, in the order a pair is counted under them."""

_DOORS = ("IfcDoor", "IfcWindow")
"""Classes of the ``fills`` rule (IfcDoorStandardCase and IfcWindowStandardCase among them)."""


@dataclass(frozen=True)
class ClashRules:
    """Which rules apply (see the module's table).

    Examples
    --------
    >>> from pycinder.bim.rules import ClashRules
    >>> ClashRules.parse("default,system,-connected").on()
    ['fills', 'openings', 'assembly', 'system', 'duplicates']
    >>> ClashRules.parse("none").on()
    []
    """

    fills: bool = True
    openings: bool = True
    assembly: bool = True
    connected: bool = True
    system: bool = False
    duplicates: bool = True

    def on(self) -> list[str]:
        """The rules that apply, in :data:`RULES` order."""
        return [name for name in RULES if getattr(self, name)]

    @classmethod
    def parse(cls, text: str) -> ClashRules:
        """Rules from a comma-separated list: ``default`` (the defaults), ``all``, ``none``, a
        rule's name (on) or its name after ``-`` (off), in order (``"none,fills"``,
        ``"default,-connected,system"``). A list of names alone means those rules only.

        Raises
        ------
        ValueError
            A word that is neither a rule nor one of the keywords, naming the rules.
        """
        words = [w.strip() for w in text.split(",") if w.strip()]
        on = dict.fromkeys(RULES, False)
        if not words or all(w in RULES for w in words):
            pass  # names alone: those only
        else:
            on = {f.name: f.default for f in fields(cls)}
        for word in words:
            if word == "default":
                on = {f.name: f.default for f in fields(cls)}
            elif word == "all":
                on = dict.fromkeys(RULES, True)
            elif word == "none":
                on = dict.fromkeys(RULES, False)
            elif word.lstrip("+-") in RULES:
                on[word.lstrip("+-")] = not word.startswith("-")
            else:
                raise ValueError(f"{word!r} is not a clash rule: the rules are "
                                 f"{', '.join(RULES)} (and default, all, none; -name turns one "
                                 f"off)")
        return cls(**on)

    @classmethod
    def of(cls, rules: ClashRules | str | Sequence[str] | None) -> ClashRules:
        """Rules as given: a :class:`ClashRules`, a string for :meth:`parse`, a sequence of
        rule names (those only), or None (the defaults)."""
        if rules is None:
            return cls()
        if isinstance(rules, ClashRules):
            return rules
        if isinstance(rules, str):
            return cls.parse(rules)
        return cls.parse(",".join(["none", *rules]))


@dataclass
class SetAside:
    """What the rules set aside in one query.

    Attributes
    ----------
    rules : ClashRules
    counts : dict
        Rule name to the candidate pairs it set aside (every rule that applies, 0 included).
    pairs : (K, 2) int64
        The pairs set aside, as indices of the model's bodies (``i < j``).
    rule : (K,) object
        The rule each was set aside by.
    duplicates : list of list of int
        Per GlobalId in more than one file, its bodies among those tested (the ``duplicates``
        rule reports them here rather than as clashes).
    """

    rules: ClashRules
    counts: dict[str, int]
    pairs: np.ndarray
    rule: np.ndarray
    duplicates: list[list[int]]

    def as_json(self, model: Any) -> dict[str, Any]:
        """The rules, their counts and the duplicates as plain data (``pycinder check
        --json``'s ``rules`` and ``duplicates``)."""
        return {"rules": {name: {"on": getattr(self.rules, name),
                                 "set_aside": self.counts.get(name, 0)} for name in RULES},
                "duplicates": [{"global_id": model.bodies[group[0]].global_id,
                                "elements": [model.bodies[k].name for k in group],
                                "files": [model.bodies[k].file for k in group]}
                               for group in self.duplicates]}

    def summary(self) -> str:
        """A few words: the pairs the rules set aside, and how many each (those that set
        some aside)."""
        if not self.rules.on():
            return "no clash rules"
        total = len(self.pairs)
        if not total:
            return "the clash rules set no pair aside"
        parts = [f"{name} {self.counts[name]}" for name in self.rules.on() if self.counts[name]]
        plural = "" if total == 1 else "s"
        return f"the clash rules set {total} pair{plural} aside ({', '.join(parts)})"


def candidate_pairs(model: Any, used: np.ndarray, groups: np.ndarray | None,
                    margin: float) -> np.ndarray:
    """The pairs of ``used`` bodies whose world boxes meet, grown by ``margin``, across
    ``groups`` where given.

    Parameters
    ----------
    model : IfcModel
    used : (U,) int
        Indices of the bodies queried.
    groups : (U,) int, optional
    margin : float

    Returns
    -------
    (K, 2) int64
        Indices into ``used``, ``i < j``, sorted.
    """
    from ..focused.broad.broad_numpy import sweep_and_prune

    bounds = np.array([model.bodies[k].mesh.bounds for k in used], np.float64).reshape(-1, 2, 3)
    return sweep_and_prune(bounds[:, 0] - margin / 2, bounds[:, 1] + margin / 2, None, groups)


def _roots(parent: dict[Any, Any]) -> dict[Any, Any]:
    """Each part's topmost whole, following ``parent`` (cycles stop where they close)."""
    out = {}
    for start in parent:
        top, seen = start, {start}
        while top in parent and parent[top] not in seen:
            top = parent[top]
            seen.add(top)
        out[start] = top
    return out


OPENING_SLACK = 1e-9
"""Volume (cubic metres) an element must share with an opening to be in it: more than rounding
makes of an element that only touches the opening's sides."""


def _through_openings(model: Any, index: dict[tuple[str, str], int], a: np.ndarray,
                      b: np.ndarray) -> np.ndarray:
    """(K,) bool: which pairs of bodies ``a``, ``b`` (K,) hold an element and a host whose
    opening the element's volume reaches into (by more than :data:`OPENING_SLACK`; an open
    element, by one of its vertices inside the opening's box). Only an element whose box
    overlaps the opening's (more than touching it) is cut with it."""
    out = np.zeros(len(a), bool)
    holes: dict[int, list[int]] = {}
    for n, opening in enumerate(model.openings):
        host = index.get((opening.file, opening.host))
        if host is not None:
            holes.setdefault(host, []).append(n)
    if not holes:
        return out
    rows, elements, openings = [], [], []
    for k, (i, j) in enumerate(zip(a.tolist(), b.tolist())):
        for element, host in ((i, j), (j, i)):
            for n in holes.get(host, ()):
                rows.append(k)
                elements.append(element)
                openings.append(n)
    if not rows:
        return out
    # Each mesh's box read once (trimesh checks its cache on every read).
    body_ids, body_of = np.unique(elements, return_inverse=True)
    hole_ids, hole_of = np.unique(openings, return_inverse=True)
    body_box = np.array([model.bodies[k].mesh.bounds for k in body_ids], np.float64)
    hole_box = np.array([model.openings[n].mesh.bounds for n in hole_ids], np.float64)
    lo = np.maximum(body_box[body_of, 0], hole_box[hole_of, 0])
    hi = np.minimum(body_box[body_of, 1], hole_box[hole_of, 1])
    for m in np.flatnonzero(np.all(hi > lo, axis=1)):  # boxes apart or touching: not in it
        k = rows[m]
        if not out[k] and _reaches_into(model.bodies[elements[m]].mesh,
                                        model.openings[openings[m]].mesh, lo[m], hi[m]):
            out[k] = True
    return out


def _reaches_into(mesh: Any, opening: Any, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether an element's volume reaches into an opening whose box overlaps its own in
    ``lo``, ``hi`` (3,) (see :func:`_through_openings`)."""
    from ..focused.measure.regions import mesh_solid

    origin = 0.5 * (lo + hi)
    hole = mesh_solid(opening.vertices, opening.faces, origin)
    if hole is None:
        return False
    body = mesh_solid(mesh.vertices, mesh.faces, origin)
    if body is None:  # a surface: a vertex of it inside the opening's box
        v = np.asarray(mesh.vertices, np.float64)
        return bool(np.any(np.all((v > lo) & (v < hi), axis=1)))
    return (hole ^ body).volume() > OPENING_SLACK


def set_aside(model: Any, used: np.ndarray, candidates: np.ndarray,
              rules: ClashRules) -> tuple[np.ndarray, SetAside]:
    """The candidate pairs the rules leave to test, and what they set aside.

    Parameters
    ----------
    model : IfcModel
    used : (U,) int
        The bodies queried (indices of the model's).
    candidates : (K, 2) int
        Pairs of indices into ``used`` (:func:`candidate_pairs`).
    rules : ClashRules

    Returns
    -------
    kept : (K', 2) int64
        The candidates no rule sets aside (indices into ``used``).
    set_aside : SetAside
        With its pairs as indices of the model's bodies.
    """
    candidates = np.asarray(candidates, np.int64).reshape(-1, 2)
    bodies = model.bodies
    index = {(bodies[k].file, bodies[k].global_id): k for k in range(len(bodies))}
    global_a, global_b = used[candidates[:, 0]], used[candidates[:, 1]]
    n = len(bodies)
    keys = np.minimum(global_a, global_b) * n + np.maximum(global_a, global_b)

    def pair_keys(rows: list[tuple[int, int]]) -> np.ndarray:
        if not rows:
            return np.zeros(0, np.int64)
        table = np.sort(np.array(rows, np.int64), axis=1)
        return table[:, 0] * n + table[:, 1]

    def related(kind: str, keep: Any = None) -> list[tuple[int, int]]:
        rows = []
        for label, relations in model.relations.items():
            for x, y in relations.get(kind, np.zeros((0, 2), str)).tolist():
                i, j = index.get((label, x)), index.get((label, y))
                if i is not None and j is not None and i != j and (keep is None or keep(i)):
                    rows.append((i, j))
        return rows

    is_door = [any(model._is_a(b, [c]) for c in _DOORS) for b in bodies] if rules.fills or \
        rules.openings else []
    found: dict[str, np.ndarray] = {}
    if rules.fills:
        found["fills"] = np.isin(keys, pair_keys(related("fills", lambda i: is_door[i])))
    if rules.openings:
        found["openings"] = np.isin(keys, pair_keys(
            related("fills", lambda i: not is_door[i]))) | _through_openings(
                model, index, global_a, global_b)
    if rules.assembly:
        # Follow parts to their topmost whole by GlobalId: a whole need not be a body (a stair
        # has no shape of its own; its flights, stringers and railings do).
        parent = {(label, x): (label, y) for label, relations in model.relations.items()
                  for x, y in relations.get("aggregates", np.zeros((0, 2), str)).tolist()}
        root = _roots(parent)
        wholes = set(parent.values())
        key = [(b.file, b.global_id) for b in bodies]
        top_key = [root.get(k, k if k in wholes else None) for k in key]
        ids = {t: i for i, t in enumerate(dict.fromkeys(t for t in top_key if t is not None))}
        top = np.array([ids[t] if t is not None else -1 - k for k, t in enumerate(top_key)])
        found["assembly"] = top[global_a] == top[global_b]
    if rules.connected:
        found["connected"] = np.isin(keys, pair_keys(related("connects")))
    if rules.system:
        member: dict[int, set[str]] = {}
        for label, relations in model.relations.items():
            for x, system in relations.get("systems", np.zeros((0, 2), str)).tolist():
                k = index.get((label, x))
                if k is not None:
                    member.setdefault(k, set()).add(f"{label}/{system}")
        found["system"] = np.array([bool(member.get(a, set()) & member.get(b, set()))
                                    for a, b in zip(global_a.tolist(), global_b.tolist())], bool)
    queried = set(used.tolist())
    twice = [[k for k in group if k in queried] for group in model.duplicates()]
    twice = [group for group in twice if len(group) > 1]
    if rules.duplicates:
        gid = np.array([b.global_id for b in bodies], dtype=object)
        files = np.array([b.file for b in bodies], dtype=object)
        found["duplicates"] = ((gid[global_a] == gid[global_b])
                               & (files[global_a] != files[global_b]))
    taken = np.zeros(len(candidates), bool)
    rule = np.empty(len(candidates), dtype=object)
    counts: dict[str, int] = {}
    for name in RULES:
        if name not in found:
            continue
        mine = found[name] & ~taken
        counts[name] = int(np.count_nonzero(mine))
        rule[mine] = name
        taken |= mine
    pairs = np.sort(np.stack([global_a[taken], global_b[taken]], axis=1), axis=1)
    return candidates[~taken], SetAside(rules, counts, pairs, rule[taken],
                                        twice if rules.duplicates else [])

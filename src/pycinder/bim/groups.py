"""Clashes grouped: clashes close to each other, of one element, on one storey or between one
pair of classes form one group (``pip install 'pycinder[bim]'``).

A coordinator works through issues, not pairs. :func:`group_clashes` groups clashes by one of:

* ``"distance"`` (the default): groups of clashes whose points
  (:attr:`~pycinder.bim.ifc.Clash.point`) lie at most ``distance`` apart (3 m unless given,
  IfcClash's ``max_eps``), every two of a group: each group spans at most the distance, so that
  a model whose clashes are everywhere is not one chain of neighbours' neighbours. The densest
  spot is grouped first: the clash with the most others within the distance gathers them,
  nearest first, each that lies within the distance of every one gathered so far; then the
  densest of those left, and so on. No group takes more than a tenth of a run's clashes (in a
  run of twenty or more, :data:`MOST_IN_GROUP`): the others are grouped anew. A spot holding more
  than that is a convention of the model rather than an issue (see the clash rules,
  :mod:`pycinder.bim.rules`).
* ``"element"``: the clashes of one element, each clash with whichever of its two elements has
  more clashes (a wall that four pipes run through is one issue).
* ``"storey"``: the clashes on one building storey (element ``a``'s, else ``b``'s).
* ``"classes"``: the clashes between one pair of IFC classes (``IfcDuctSegment`` against
  ``IfcBeam``).

The answer depends on neither the clashes' order nor their number's parity: clashes are taken in
the order of their keys, and groups are numbered in the order of their first clashes as given.

Each clash and each group has a key and a GUID that depend only on GlobalIds (:func:`pair_key`,
:func:`topic_guid`): a clash's key is its two GlobalIds, sorted; a group's is the smallest key of
its clashes. A run on an edited model gives an unchanged clash, or a group whose smallest clash
is unchanged, the same GUID, so a BCF viewer updates its topic instead of adding one
(:mod:`pycinder.bim.tracking` carries GUIDs over from a previous run where groups change).
"""

from __future__ import annotations

import heapq
import uuid
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..util.optional import require

__all__ = ["ClashGroup", "group_clashes", "pair_key", "topic_guid", "DEFAULT_GROUP_DISTANCE",
           "GROUP_BY", "MOST_IN_GROUP", "CAPPED_FROM"]

DEFAULT_GROUP_DISTANCE = 3.0
"""Grouping distance in metres when none is given: IfcClash's default ``max_eps``."""

GROUP_BY = ("distance", "element", "storey", "classes")
"""The ways :func:`group_clashes` groups."""

MOST_IN_GROUP = 0.1
"""The largest share of a run's clashes that one group of :func:`group_clashes` takes by
distance, in a run of :data:`CAPPED_FROM` clashes or more."""
CAPPED_FROM = 20
"""Clashes of the smallest run whose groups :data:`MOST_IN_GROUP` caps (a tenth of fewer than 20
is less than two: no group at all)."""

GUID_NAMESPACE = uuid.UUID("c10f7a6c-2cde-4b27-a7ff-d3c7921e19c5")
"""The namespace of pycinder's clash and group GUIDs (UUID5 of a key)."""


def pair_key(a: str, b: str) -> tuple[str, str]:
    """A clash's key: its two elements' GlobalIds, sorted."""
    return (a, b) if a <= b else (b, a)


def topic_guid(key: tuple[str, str], salt: str = "") -> str:
    """The GUID of the BCF topic of a clash or group whose key is ``key`` (UUID5 in
    :data:`GUID_NAMESPACE` of ``"A/B"``, and of ``salt`` where given)."""
    return str(uuid.uuid5(GUID_NAMESPACE, f"{key[0]}/{key[1]}{salt}"))


@dataclass
class ClashGroup:
    """Clashes that are one issue: they share an element, or lie close to each other.

    Attributes
    ----------
    index : int
        The group's number in this run, from 1, in the order of the groups' first clashes.
    clashes : list of Clash
        Its clashes, in the order given to :func:`group_clashes`.
    key : (str, str)
        The smallest :func:`pair_key` of its clashes.
    guid : str
        Its BCF topic's GUID: :func:`topic_guid` of :attr:`key`, or the GUID of the previous
        run's topic it continues (:func:`pycinder.bim.tracking.track`).
    status : {"new", "active"}
        ``"new"`` unless :func:`pycinder.bim.tracking.track` found one of its clashes in the
        previous run.
    resolved : list of (str, str)
        Clashes of the previous run's topic that this group continues, gone now (sorted
        GlobalIds; set by :func:`pycinder.bim.tracking.track`).
    """

    index: int
    clashes: list[Any]
    key: tuple[str, str]
    guid: str
    status: str = "new"
    resolved: list[tuple[str, str]] = field(default_factory=list)

    @property
    def elements(self) -> list[Any]:
        """Its elements (IfcBody), each once, in the order of its clashes (``a`` before
        ``b``)."""
        seen: dict[tuple[str, str], Any] = {}
        for c in self.clashes:
            for body in (c.a, c.b):
                seen.setdefault((body.file, body.global_id), body)
        return list(seen.values())

    @property
    def point(self) -> np.ndarray:
        """(3,) float: the mean of its clashes' points, in metres."""
        return np.mean([np.asarray(c.point, np.float64) for c in self.clashes], axis=0)

    def title(self) -> str:
        """Its BCF topic's title: its clash's title (IfcClash's), or its first clash's and how
        many more there are."""
        c = self.clashes[0]
        text = (f"{c.a.ifc_class}/{c.a.element_name or c.a.global_id} and "
                f"{c.b.ifc_class}/{c.b.element_name or c.b.global_id}")
        more = len(self.clashes) - 1
        return text if not more else f"{text} (+{more} clash{'es' if more > 1 else ''})"


def check_group_distance(distance: float | None) -> float | None:
    """``distance`` as a float, or None for no grouping; a ValueError for a negative or
    non-finite one."""
    if distance is None:
        return None
    value = float(distance)
    if not np.isfinite(value) or value < 0:
        raise ValueError(f"the grouping distance must be 0 or a positive distance in metres, "
                         f"got {distance!r}")
    return value


def _by_distance(points: np.ndarray, order: np.ndarray, distance: float) -> np.ndarray:
    """(n,) int: each point's group, no two points of a group farther apart than ``distance``,
    the densest first, none of more than :data:`MOST_IN_GROUP` of them where there are
    :data:`CAPPED_FROM` or more (see the module); ``order`` (n,) ranks the points for ties."""
    spatial = require("scipy.spatial", "grouping clashes by distance", "bim", package="scipy")
    n = len(points)
    near = spatial.cKDTree(points).query_ball_point(points, r=distance)
    count = np.array([len(x) for x in near], np.int64)
    rank = np.empty(n, np.int64)
    rank[order] = np.arange(n)
    heap = [(-int(count[i]), int(rank[i]), i) for i in range(n)]
    heapq.heapify(heap)
    label = np.full(n, -1, np.int64)
    most = max(int(MOST_IN_GROUP * n), 2) if n >= CAPPED_FROM else n
    groups = 0
    while heap:
        c, _, i = heapq.heappop(heap)
        if label[i] >= 0:
            continue
        if -c != count[i]:  # stale: its count fell since it was pushed
            heapq.heappush(heap, (-int(count[i]), int(rank[i]), i))
            continue
        free = np.array([j for j in near[i] if label[j] < 0 and j != i], np.int64)
        gap = np.linalg.norm(points[free] - points[i], axis=1) if len(free) else np.zeros(0)
        members = [i]
        for j in free[np.lexsort((rank[free], gap))].tolist():  # nearest first
            if len(members) >= most:
                break
            if np.linalg.norm(points[members] - points[j], axis=1).max() <= distance:
                members.append(j)
        label[members] = groups
        groups += 1
        for j in members:
            for k in near[j]:
                if label[k] < 0:
                    count[k] -= 1
    return label


def _by_key(keys: Sequence[Any]) -> np.ndarray:
    """(n,) int: one group per distinct key."""
    seen: dict[Any, int] = {}
    return np.array([seen.setdefault(k, len(seen)) for k in keys], np.int64)


def group_clashes(clashes: Sequence[Any], distance: float | None = DEFAULT_GROUP_DISTANCE, *,
                  by: str = "distance") -> list[ClashGroup]:
    """Group clashes (see the module).

    Parameters
    ----------
    clashes : sequence of Clash
        From :func:`pycinder.bim.ifc.find_clashes`.
    distance : float or None
        Metres: with ``by="distance"``, no two clashes of a group lie farther apart than this;
        0 groups by element (as ``by="element"``); None makes a group of each clash, whatever
        ``by`` says.
    by : {"distance", "element", "storey", "classes"}

    Returns
    -------
    list of ClashGroup
        In the order of their first clashes, numbered from 1; each with :func:`topic_guid` of
        its key and status ``"new"``.

    Raises
    ------
    ValueError
        A negative or non-finite ``distance``, or another ``by``.
    ImportError
        Without scipy, grouping by a positive distance (``pip install 'pycinder[bim]'``).

    Examples
    --------
    .. code-block:: python

        groups = group_clashes(find_clashes(model, min_depth=0.01), distance=2.0)
        for g in groups:
            print(g.index, g.title(), len(g.clashes))
        by_storey = group_clashes(clashes, by="storey")
    """
    distance = check_group_distance(distance)
    if by not in GROUP_BY:
        raise ValueError(f"clashes are grouped by one of {', '.join(GROUP_BY)}, not {by!r}")
    n = len(clashes)
    if n == 0:
        return []
    keys = [pair_key(c.a.global_id, c.b.global_id) for c in clashes]
    order = np.array(sorted(range(n), key=lambda k: (keys[k], k)), np.int64)
    if distance is None:
        label = np.arange(n)
    elif by == "element" or distance == 0:
        seen: dict[tuple[str, str], int] = {}
        for c in clashes:
            for body in (c.a, c.b):
                seen[(body.file, body.global_id)] = seen.get((body.file, body.global_id), 0) + 1
        first: dict[tuple[str, str], int] = {}
        for k in order.tolist():
            for body in (clashes[k].a, clashes[k].b):
                first.setdefault((body.file, body.global_id), k)

        def element(c: Any) -> tuple[str, str]:
            a, b = (c.a.file, c.a.global_id), (c.b.file, c.b.global_id)
            return a if (seen[a], -first[a]) >= (seen[b], -first[b]) else b

        label = _by_key([element(c) for c in clashes])
    elif by == "storey":
        label = _by_key([getattr(c.a, "storey", "") or getattr(c.b, "storey", "")
                         for c in clashes])
    elif by == "classes":
        label = _by_key([tuple(sorted((c.a.ifc_class, c.b.ifc_class))) for c in clashes])
    else:
        points = np.array([np.asarray(c.point, np.float64) for c in clashes])
        label = _by_distance(points, order, distance) if n > 1 else np.zeros(1, np.int64)
    members: dict[int, list[int]] = {}
    for k, g in enumerate(label.tolist()):
        members.setdefault(g, []).append(k)
    out = []
    taken: dict[tuple[str, str], int] = {}
    for index, ks in enumerate(sorted(members.values(), key=lambda m: m[0]), start=1):
        chosen = [clashes[k] for k in ks]
        key = min(keys[k] for k in ks)
        # The same GlobalIds may clash twice (one pair in two files, a model against its
        # revised copy): the later groups' GUIDs are salted, so that every topic has its own.
        taken[key] = taken.get(key, 0) + 1
        salt = f"#{taken[key] - 1}" if taken[key] > 1 else ""
        out.append(ClashGroup(index, chosen, key, topic_guid(key, salt)))
    return out

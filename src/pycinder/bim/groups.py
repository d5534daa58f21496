"""Clashes grouped: clashes of one element, or close to each other, form one group
(``pip install 'pycinder[bim]'``).

IfcClash's smart grouping clusters the clashes' points with scikit-learn's OPTICS
(``min_samples=2``, ``max_eps`` 3 m by default). :func:`group_clashes` clusters them with
scikit-learn's DBSCAN at ``min_samples=1``, which is single linkage cut at the grouping
distance: two clashes whose points (:attr:`~pycinder.bim.ifc.Clash.point`) lie at most
``distance`` apart are in one group, and so, through them, are their neighbours' neighbours;
the answer depends on neither the clashes' order nor a density. Clashes sharing an element
(the same GlobalId in the same file) are in one group too, however far apart: a wall that four
pipes run through is one issue to a coordinator.

Each clash and each group has a key and a GUID that depend only on GlobalIds (:func:`pair_key`,
:func:`topic_guid`): a clash's key is its two GlobalIds, sorted; a group's is the smallest key of
its clashes. A run on an edited model gives an unchanged clash, or a group whose smallest clash
is unchanged, the same GUID, so a BCF viewer updates its topic instead of adding one
(:mod:`pycinder.bim.tracking` carries GUIDs over from a previous run where groups change).
"""

from __future__ import annotations

import uuid
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..util.optional import require

__all__ = ["ClashGroup", "group_clashes", "pair_key", "topic_guid", "DEFAULT_GROUP_DISTANCE"]

DEFAULT_GROUP_DISTANCE = 3.0
"""Grouping distance in metres when none is given: IfcClash's default ``max_eps``."""

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


def _union_find(n: int, links: Sequence[tuple[int, int]]) -> np.ndarray:
    """(n,) int: each item's component's smallest member, for the given links."""
    parent = list(range(n))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in links:
        ri, rj = root(i), root(j)
        if ri != rj:
            parent[max(ri, rj)] = min(ri, rj)
    return np.array([root(i) for i in range(n)], dtype=np.int64)


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


def group_clashes(clashes: Sequence[Any], distance: float | None = DEFAULT_GROUP_DISTANCE, *,
                  by_element: bool = True) -> list[ClashGroup]:
    """Group clashes: those of one element, or within ``distance`` of each other.

    Parameters
    ----------
    clashes : sequence of Clash
        From :func:`pycinder.bim.ifc.find_clashes`.
    distance : float or None
        Metres: clashes whose points lie at most this far apart are in one group, through
        chains of such neighbours (DBSCAN with ``min_samples=1``). 0 groups by element alone;
        None makes a group of each clash (and ignores ``by_element``).
    by_element : bool
        Clashes sharing an element (the same file and GlobalId) are in one group.

    Returns
    -------
    list of ClashGroup
        In the order of their first clashes, numbered from 1; each with :func:`topic_guid` of
        its key and status ``"new"``.

    Raises
    ------
    ValueError
        A negative or non-finite ``distance``.
    ImportError
        Without scikit-learn, where ``distance`` is positive (``pip install 'pycinder[bim]'``).

    Examples
    --------
    .. code-block:: python

        groups = group_clashes(find_clashes(model, min_depth=0.01), distance=2.0)
        for g in groups:
            print(g.index, g.title(), len(g.clashes))
    """
    distance = check_group_distance(distance)
    n = len(clashes)
    if n == 0:
        return []
    links: list[tuple[int, int]] = []
    if distance is not None:
        if distance > 0 and n > 1:
            cluster = require("sklearn.cluster", "grouping clashes by distance", "bim",
                              package="scikit-learn")
            points = np.array([np.asarray(c.point, np.float64) for c in clashes])
            labels = cluster.DBSCAN(eps=distance, min_samples=1).fit(points).labels_
            first: dict[int, int] = {}
            for k, label in enumerate(labels.tolist()):
                links.append((first.setdefault(label, k), k))
        if by_element:
            owner: dict[tuple[str, str], int] = {}
            for k, c in enumerate(clashes):
                for body in (c.a, c.b):
                    links.append((owner.setdefault((body.file, body.global_id), k), k))
    roots = _union_find(n, links)
    members: dict[int, list[int]] = {}
    for k, r in enumerate(roots.tolist()):
        members.setdefault(r, []).append(k)
    out = []
    seen: dict[tuple[str, str], int] = {}
    for index, ks in enumerate(sorted(members.values(), key=lambda m: m[0]), start=1):
        chosen = [clashes[k] for k in ks]
        key = min(pair_key(c.a.global_id, c.b.global_id) for c in chosen)
        # The same GlobalIds may clash twice (one pair in two files, a model against its
        # revised copy): the later groups' GUIDs are salted, so that every topic has its own.
        seen[key] = seen.get(key, 0) + 1
        salt = f"#{seen[key] - 1}" if seen[key] > 1 else ""
        out.append(ClashGroup(index, chosen, key, topic_guid(key, salt)))
    return out

"""Clashes tracked from one run to the next: new, active or resolved.

A previous run is read from its BCF file (:func:`pycinder.bim.bcf.write_bcf`'s: each topic's
GUID, status and, in its description, a line per clash naming both GlobalIds) or from its
``pycinder check --json`` output (:func:`read_previous`). :func:`track` then marks each clash
``"new"`` (not open in the previous run) or ``"active"`` (open in it), each group ``"active"``
when one of its clashes is, and lists the previous run's open clashes that are gone as
resolved. A group continues the previous topic it shares most clashes with, taking its GUID, so
that a BCF viewer importing the new file updates that topic; a previous topic that no group
continues comes back as a resolved topic under its own GUID, closing it in the viewer.
"""

from __future__ import annotations

import json
import os
import re
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .groups import ClashGroup, pair_key, topic_guid

__all__ = ["PreviousTopic", "Tracking", "read_previous", "track", "STATUSES"]

STATUSES = ("new", "active", "resolved")
"""A clash's or group's status against a previous run."""

CLASH_LINE = re.compile(r"^- (\S+) <-> (\S+) \[(new|active)\]: ?(.*)$")
"""A clash's line in a BCF topic's description: ``- A <-> B [status]: what it is``."""


@dataclass(frozen=True)
class PreviousTopic:
    """A topic (a group of clashes) of a previous run.

    Attributes
    ----------
    guid : str
        The topic's GUID.
    title : str
    status : {"new", "active", "resolved"}
        Its status in that run; a resolved topic's clashes are not open.
    pairs : dict
        Its clashes: :func:`~pycinder.bim.groups.pair_key` to a description (the two names).
    """

    guid: str
    title: str
    status: str
    pairs: dict[tuple[str, str], str]


@dataclass
class Tracking:
    """What changed since a previous run (:func:`track`).

    Attributes
    ----------
    clashes : dict
        :func:`~pycinder.bim.groups.pair_key` of each clash now to ``"new"`` or ``"active"``.
    resolved : dict
        The previous run's open clashes that are gone: key to the description it had.
    closed : list of PreviousTopic
        The previous run's open topics that no group continues, as resolved topics: their
        ``pairs`` are their clashes that are gone (the others moved to another group).
    source : str
        The previous run's file.
    """

    clashes: dict[tuple[str, str], str] = field(default_factory=dict)
    resolved: dict[tuple[str, str], str] = field(default_factory=dict)
    closed: list[PreviousTopic] = field(default_factory=list)
    source: str = ""

    def counts(self) -> dict[str, int]:
        """Clashes per status: ``{"new": n, "active": n, "resolved": n}``."""
        values = list(self.clashes.values())
        return {"new": values.count("new"), "active": values.count("active"),
                "resolved": len(self.resolved)}


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _read_bcf(path: Path) -> list[PreviousTopic]:
    import xml.etree.ElementTree as ET

    out = []
    with zipfile.ZipFile(path) as z:
        for name in z.namelist():
            if not name.endswith("/markup.bcf"):
                continue
            markup = ET.fromstring(z.read(name))
            topic = next((e for e in markup.iter() if _local(e.tag) == "Topic"), None)
            if topic is None:
                raise ValueError(f"{path.name}: {name} holds no Topic")
            texts = {_local(e.tag): e.text or "" for e in topic}
            labels = [e.text or "" for e in topic if _local(e.tag) == "Labels"]
            status = next((s for s in STATUSES if s in labels), "active")
            pairs = {}
            for line in texts.get("Description", "").splitlines():
                m = CLASH_LINE.match(line.strip())
                if m:
                    pairs[pair_key(m.group(1), m.group(2))] = m.group(4)
            if not pairs:  # another tool's topic: no clash lines to track
                continue
            out.append(PreviousTopic(topic.get("Guid", ""), texts.get("Title", ""), status,
                                     pairs))
    return out


def _read_json(path: Path) -> list[PreviousTopic]:
    try:
        report = json.loads(path.read_text(encoding="utf-8"))
        pairs = report["pairs"]
        keys = [pair_key(p["a_global_id"], p["b_global_id"]) for p in pairs]
        names = [f"{p.get('a', p['a_global_id'])} and {p.get('b', p['b_global_id'])}"
                 for p in pairs]
    except (ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path.name}: not the JSON of 'pycinder check --json' on IFC files "
                         f"({type(exc).__name__}: {exc})") from None
    if "groups" not in report:  # no groups: a topic per clash
        return [PreviousTopic(topic_guid(k), n, "active", {k: n})
                for k, n in zip(keys, names, strict=True)]
    out = [PreviousTopic(g["guid"], g.get("title", ""), "active",
                         {keys[i]: names[i] for i in g["clashes"]}) for g in report["groups"]]
    for g in report.get("resolved_groups", []):
        out.append(PreviousTopic(g["guid"], g.get("title", ""), "resolved",
                                 {pair_key(*p): "" for p in g["pairs"]}))
    return out


def read_previous(path: str | os.PathLike[str]) -> list[PreviousTopic]:
    """The topics of a previous run, from its BCF file (``.bcf``, written by
    :func:`pycinder.bim.bcf.write_bcf`) or its ``pycinder check --json`` output (``.json``).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    list of PreviousTopic
        In the file's order. A BCF topic without pycinder's clash lines in its description
        (another tool's) is left out.

    Raises
    ------
    ValueError
        A file that is neither ``.bcf`` nor ``.json``, or not one pycinder wrote (naming it).
    OSError
        A file that cannot be read.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".bcf" or suffix == ".bcfzip":
        try:
            return _read_bcf(path)
        except zipfile.BadZipFile:
            raise ValueError(f"{path.name}: not a BCF file (not a zip archive)") from None
    if suffix == ".json":
        return _read_json(path)
    raise ValueError(f"{path.name}: a previous run is read from its .bcf or .json file")


def track(groups: Sequence[ClashGroup], previous: Sequence[PreviousTopic],
          source: str = "") -> Tracking:
    """Mark ``groups`` and their clashes against a previous run's topics, in place.

    Each clash is ``"active"`` where one of the previous run's open topics holds its pair,
    else ``"new"``; each group ``"active"`` where one of its clashes is. A group continues the
    open previous topic with which it shares most clashes (the earlier topic on a tie; each
    topic continued once) and takes its GUID; its :attr:`~ClashGroup.resolved` lists that
    topic's clashes that are gone. Other groups keep :func:`~pycinder.bim.groups.topic_guid`
    of their key (salted where a previous topic has it already).

    Parameters
    ----------
    groups : sequence of ClashGroup
        From :func:`~pycinder.bim.groups.group_clashes` (their ``status``, ``guid`` and
        ``resolved`` are set).
    previous : sequence of PreviousTopic
        From :func:`read_previous`.
    source : str
        The previous run's file, for reports.

    Returns
    -------
    Tracking
    """
    opened = [t for t in previous if t.status != "resolved"]
    was_open: dict[tuple[str, str], str] = {}
    for t in opened:
        was_open.update(t.pairs)
    out = Tracking(source=source)
    now: set[tuple[str, str]] = set()
    for g in groups:
        for c in g.clashes:
            key = pair_key(c.a.global_id, c.b.global_id)
            now.add(key)
            out.clashes[key] = "active" if key in was_open else "new"
    out.resolved = {k: v for k, v in was_open.items() if k not in now}
    taken: set[int] = set()
    used = {t.guid for t in previous}
    for g in groups:
        keys = {pair_key(c.a.global_id, c.b.global_id) for c in g.clashes}
        g.status = "active" if any(out.clashes[k] == "active" for k in keys) else "new"
        shared = [(len(keys & t.pairs.keys()), -k) for k, t in enumerate(opened)
                  if k not in taken]
        best = max(shared, default=(0, 0))
        if best[0] > 0:
            k = -best[1]
            taken.add(k)
            g.guid = opened[k].guid
            g.resolved = sorted(p for p in opened[k].pairs if p not in now)
        else:
            salt, n = "", 1
            while g.guid in used:
                n += 1
                salt = f"#{n}"
                g.guid = topic_guid(g.key, salt)
        used.add(g.guid)
    for k, t in enumerate(opened):
        if k not in taken:
            out.closed.append(PreviousTopic(t.guid, t.title, "resolved",
                                            {p: d for p, d in t.pairs.items() if p not in now}))
    return out


"""A clash run's report: clashes grouped (:mod:`.groups`), tracked against a previous run
(:mod:`.tracking`), pictured (:mod:`.snapshot`) and written as BCF (:mod:`.bcf`), as text and
as ``pycinder check --json``'s fields. :func:`clash_report` does every step that was asked
for; the command line prints what it returns.
"""

from __future__ import annotations

import argparse
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .groups import (DEFAULT_GROUP_DISTANCE, GROUP_BY, ClashGroup, check_group_distance,
                     group_clashes, pair_key)
from .rules import RULES, ClashRules
from .tracking import Tracking, read_previous, track

__all__ = ["ClashReport", "clash_report", "add_arguments", "report_options", "verbose_lines"]

Progress = Callable[[int, int, str], None]


@dataclass
class ClashReport:
    """The clashes of a run with their groups, statuses and pictures.

    Attributes
    ----------
    clashes : list of Clash
    groups : list of ClashGroup
    tracking : Tracking or None
        Against the previous run, where one was given.
    snapshots : dict
        Group index to the PNG file written for it (with a snapshot folder).
    group_distance : float or None
        The grouping distance in metres (None: a group per clash).
    group_by : str
        How the clashes were grouped (:data:`~pycinder.bim.groups.GROUP_BY`).
    set_aside : SetAside or None
        What the clash rules set aside (:mod:`pycinder.bim.rules`), where known.
    model : IfcModel or None
        The model the clashes are of.
    """

    clashes: list[Any]
    groups: list[ClashGroup]
    tracking: Tracking | None = None
    snapshots: dict[int, str] = field(default_factory=dict)
    group_distance: float | None = None
    group_by: str = "distance"
    set_aside: Any = None
    model: Any = None

    @property
    def topics(self) -> int:
        """The BCF topics written: a group each, and each closed topic of the previous run."""
        return len(self.groups) + (len(self.tracking.closed) if self.tracking else 0)

    def status(self, c: Any) -> str:
        """A clash's status: ``"new"`` or ``"active"`` (``"new"`` with no previous run)."""
        key = pair_key(c.a.global_id, c.b.global_id)
        return "new" if self.tracking is None else self.tracking.clashes.get(key, "new")

    def as_json(self) -> dict[str, Any]:
        """``pycinder check --json``'s fields for the clashes: ``pairs`` (each clash's
        :meth:`~pycinder.bim.ifc.Clash.as_dict` with its ``group``, ``status`` and ``guid``),
        ``groups``, ``resolved`` (the previous run's clashes that are gone),
        ``resolved_groups`` (its topics that no group continues), ``group_distance``,
        ``group_by`` and ``against``."""
        from .groups import topic_guid

        group_of = {id(c): g.index for g in self.groups for c in g.clashes}
        index = {id(c): k for k, c in enumerate(self.clashes)}
        pairs = []
        for c in self.clashes:
            key = pair_key(c.a.global_id, c.b.global_id)
            pairs.append({**c.as_dict(), "group": group_of[id(c)], "status": self.status(c),
                          "guid": topic_guid(key)})
        groups = [{"id": g.index, "guid": g.guid, "title": g.title(), "status": g.status,
                   "clashes": [index[id(c)] for c in g.clashes],
                   "elements": [b.global_id for b in g.elements],
                   "point": [round(float(x), 6) for x in g.point],
                   "resolved": [list(p) for p in g.resolved],
                   "snapshot": self.snapshots.get(g.index)} for g in self.groups]
        t = self.tracking
        return {"pairs": pairs, "groups": groups,
                "resolved": [] if t is None else [
                    {"a_global_id": a, "b_global_id": b, "description": what,
                     "guid": topic_guid((a, b))} for (a, b), what in t.resolved.items()],
                "resolved_groups": [] if t is None else [
                    {"guid": x.guid, "title": x.title, "pairs": [list(p) for p in x.pairs]}
                    for x in t.closed],
                "group_distance": self.group_distance, "group_by": self.group_by,
                "against": None if t is None else t.source,
                **(self.set_aside.as_json(self.model) if self.set_aside is not None
                   else {"rules": None, "duplicates": []})}

    def text(self) -> list[str]:
        """The report's lines: a clash a line, prefixed with its group (``[2]``, and its
        status with a previous run: ``[2 new]``), then the resolved clashes."""
        lines = []
        for g in self.groups:
            for c in g.clashes:
                figure = (f"  depth {c.depth:.4g} m" if c.depth is not None else
                          f"  distance {c.distance:.4g} m" if c.distance is not None else "")
                tag = f"{g.index} {self.status(c)}" if self.tracking is not None else g.index
                lines.append(f"[{tag}] {c.a.name} ({c.a.ifc_class})  <->  {c.b.name} "
                             f"({c.b.ifc_class}){figure}")
        if self.tracking is not None:
            for (a, b), what in self.tracking.resolved.items():
                lines.append(f"[resolved] {a} <-> {b}" + (f": {what}" if what else ""))
        return lines

    def summary(self) -> str:
        """One line: how many clashes, groups and, with a previous run, of each status, and
        what the clash rules set aside (where they set pairs aside)."""
        n, g = len(self.clashes), len(self.groups)
        text = (f"{n} clash{'es' if n != 1 else ''} in {g} group{'s' if g != 1 else ''}")
        if self.set_aside is not None and len(self.set_aside.pairs):
            text += f"; {self.set_aside.summary()}"
            if self.set_aside.duplicates:
                text += (f"; {len(self.set_aside.duplicates)} GlobalIds in more than one file "
                         "reported apart")
        if self.tracking is not None:
            counts = self.tracking.counts()
            text += (f"; against {self.tracking.source}: {counts['new']} new, "
                     f"{counts['active']} active, {counts['resolved']} resolved")
        return text


def _group_distance(text: str) -> float:
    """``--group-distance``: 0 or a positive distance in metres."""
    try:
        return float(check_group_distance(float(text)) or 0.0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not 0 or a positive distance") from None


def _rules(text: str) -> ClashRules:
    """``--rules``: :meth:`ClashRules.parse`'s list."""
    try:
        return ClashRules.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def verbose_lines(report: ClashReport, notes: Sequence[dict[str, Any]]) -> list[str]:
    """``--verbose``'s lines: every body each warning names, and every duplicated GlobalId's
    elements and files."""
    lines = []
    for note in notes:
        for body, detail in zip(note.get("bodies", []), note.get("details", [])):
            lines.append(f"  {note['category']}: {body}: {detail}")
    model = report.model
    for group in report.set_aside.duplicates if report.set_aside is not None else []:
        lines.append(f"  duplicate: {model.bodies[group[0]].global_id} in "
                     + ", ".join(f"{model.bodies[k].file} ({model.bodies[k].name})"
                                 for k in group))
    return lines


def add_arguments(group: Any) -> None:
    """Add the report's options to ``pycinder check``'s IFC options (an argparse argument
    group): ``--group-distance D`` or ``--no-groups``, ``--snapshots DIR`` or
    ``--no-snapshots``, and ``--against PREVIOUS`` (read back by :func:`report_options`)."""
    grouping = group.add_mutually_exclusive_group()
    grouping.add_argument("--group-distance", type=_group_distance, default=DEFAULT_GROUP_DISTANCE,
                          metavar="D", help="clashes within D metres of each other form a group, "
                          "a BCF topic: no two of a group lie farther apart (default 3, "
                          "IfcClash's; 0: by element)")
    grouping.add_argument("--no-groups", action="store_true", help="a group (a topic) per clash")
    group.add_argument("--group-by", choices=GROUP_BY, default="distance",
                       help="group clashes by distance (default), by element (an element's "
                            "clashes), by storey, or by the pair of IFC classes")
    pictures = group.add_mutually_exclusive_group()
    pictures.add_argument("--snapshots", default=None, metavar="DIR",
                          help="write a picture of each group here, group-N.png (with --bcf, "
                               "each topic carries its group's picture anyway)")
    pictures.add_argument("--no-snapshots", action="store_true",
                          help="render no pictures: BCF topics without them")
    group.add_argument("--against", default=None, metavar="PREVIOUS",
                       help="a previous run's .bcf or --json output: mark clashes new, active "
                            "or resolved, and keep its topics' GUIDs")
    group.add_argument("--rules", default=ClashRules(), type=_rules, metavar="RULES",
                       help="clash rules that set pairs aside, by what the files say: "
                            "comma-separated among " + ", ".join(RULES) + "; default (all but "
                            "system), all, none; -NAME turns one off (default: default)")
    group.add_argument("--verbose", action="store_true",
                       help="list every element a warning or the duplicates rule names")


def report_options(args: argparse.Namespace) -> dict[str, Any]:
    """:func:`clash_report`'s options from the command line's (see :func:`add_arguments`). The
    previous run (``--against``) is read here, before the model is read and checked, so that a
    bad file is said at once."""
    return {"group_distance": None if args.no_groups else args.group_distance,
            "group_by": args.group_by, "against": args.against, "snapshots": args.snapshots,
            "pictures": not args.no_snapshots,
            "previous": read_previous(args.against) if args.against is not None else None}


def clash_report(model: Any, clashes: Sequence[Any], *,
                 group_distance: float | None = DEFAULT_GROUP_DISTANCE, group_by: str = "distance",
                 against: str | os.PathLike[str] | None = None,
                 snapshots: str | os.PathLike[str] | None = None, pictures: bool = True,
                 bcf: str | os.PathLike[str] | None = None, project: str = "pycinder clashes",
                 picture_size: tuple[int, int] = (640, 480),
                 progress: Progress | None = None, previous: Any = None) -> ClashReport:
    """Group, track, picture and write a run's clashes.

    Parameters
    ----------
    model : IfcModel
        The model the clashes are of (the pictures' surroundings).
    clashes : sequence of Clash
        From :func:`pycinder.bim.ifc.find_clashes`.
    group_distance : float or None
        Metres (:func:`~pycinder.bim.groups.group_clashes`); None: a group per clash.
    group_by : {"distance", "element", "storey", "classes"}
        How to group them (:func:`~pycinder.bim.groups.group_clashes`).
    against : path, optional
        The previous run's ``.bcf`` or ``.json`` (:func:`~pycinder.bim.tracking.read_previous`).
    snapshots : path, optional
        A folder (created) for a PNG per group, ``group-<index>.png``.
    pictures : bool
        Render each group's picture for the BCF file (with ``snapshots``, always).
    bcf : path, optional
        A BCF file to write, a topic per group with its picture.
    project : str
        The BCF project's name.
    picture_size : (int, int)
        The pictures' width and height in pixels.
    progress : callable, optional
        Called as ``progress(done, total, text)`` while pictures are rendered.
    previous : optional
        ``against`` as :func:`~pycinder.bim.tracking.read_previous` read it already.

    Returns
    -------
    ClashReport

    Raises
    ------
    ValueError
        A negative grouping distance, a previous run that is not a pycinder BCF or JSON file,
        a snapshot folder that is a file.
    """
    distance = check_group_distance(group_distance)
    clashes_given = clashes
    if previous is None and against is not None:
        previous = read_previous(against)
    if snapshots is not None and Path(snapshots).exists() and not Path(snapshots).is_dir():
        raise ValueError(f"{os.fspath(snapshots)}: the snapshot folder is a file")
    clashes = list(clashes)
    groups = group_clashes(clashes, distance, by=group_by)
    tracking = (track(groups, previous, source=Path(against).name)
                if previous is not None and against is not None else None)
    report = ClashReport(clashes, groups, tracking, group_distance=distance, group_by=group_by,
                         set_aside=getattr(clashes_given, "set_aside", None), model=model)
    shots: dict[int, Any] = {}
    if (snapshots is not None or (bcf is not None and pictures)) and groups:
        try:
            shots = _pictures(model, groups, report, snapshots, picture_size, progress)
        except Exception as exc:  # pygfx, rendercanvas and the adapter fail in their own ways
            if snapshots is not None:  # asked for: an error
                raise
            # the BCF file's pictures are a bonus: its topics are written without them
            warnings.warn(f"clash pictures could not be rendered, so the BCF topics have none "
                          f"({type(exc).__name__}: {exc}); --no-snapshots skips them",
                          stacklevel=2)
            shots = {}
    if bcf is not None:
        from .bcf import write_bcf

        notes = ([f"Clash rules ({', '.join(report.set_aside.rules.on()) or 'none'}): "
                  f"{report.set_aside.summary()}"] if report.set_aside is not None else [])
        write_bcf(clashes, bcf, groups=groups, tracking=tracking, snapshots=shots,
                  project=project, notes=notes)
    return report


def _pictures(model: Any, groups: Sequence[ClashGroup], report: ClashReport,
              snapshots: str | os.PathLike[str] | None, size: tuple[int, int],
              progress: Progress | None) -> dict[int, Any]:
    """Each group's picture and camera, by group index; written to ``snapshots`` too."""
    from .snapshot import Snapshotter

    shooter = Snapshotter(model.bodies, size)
    folder = Path(snapshots) if snapshots is not None else None
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
    shots: dict[int, Any] = {}
    for k, g in enumerate(groups):
        if progress:
            progress(k, len(groups), f"picturing group {g.index} of {len(groups)}")
        shots[g.index] = shooter.group(g)
        if folder is not None:
            out = folder / f"group-{g.index}.png"
            out.write_bytes(shots[g.index][0])
            report.snapshots[g.index] = str(out)
    return shots

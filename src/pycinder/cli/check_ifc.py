"""``pycinder check A.ifc [B.ifc ...]``: the clashing elements of IFC files.

    pycinder check A.ifc [B.ifc ...] [--a SELECTOR] [--a-file FILE] [--b SELECTOR]
                   [--b-file FILE] [--bcf OUT.bcf] [--json] [--min-depth D | --clearance C]
                   [--group-distance D | --no-groups] [--snapshots DIR | --no-snapshots]
                   [--against PREVIOUS]

``check`` (:mod:`pycinder.cli.check`) hands its files here when they are IFC files; the options
of this module's group (:func:`add_ifc_arguments`) apply to them alone.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from typing import Any

from ..files import display_name
from ..util.text import plural
from .common import ERRORS, error_messages, fail, file_limits, progress, query_mode, \
    warning_entry

IFC_HELP = """\
IFC files (IFC2X3, IFC4) give one body per element (IfcElement other than IfcFeatureElement),
named 'Name [GlobalId]', tessellated in metres with openings applied, and cached per file by
content (a re-check after a change in one file re-tessellates only that file). Several files
form one model. A clash set tests group A against group B (--a/--a-file against
--b/--b-file), or A against itself (--a alone); default: every element against every other.
--json gives for each pair both names, GlobalIds, classes and files, the mode, and the depth
or distance where the mode gives one, with the bound on its error, its group, status and GUID;
and the groups, and with --against the resolved clashes (see the guide's Buildings page)."""


def add_ifc_arguments(p: argparse.ArgumentParser) -> None:
    """Add ``check``'s group of options for IFC files: clash sets, BCF, grouping, pictures,
    tracking and the tessellation cache."""
    ifc = p.add_argument_group("IFC files (pip install 'pycinder[bim]')", IFC_HELP)
    for side, other in (("a", "B"), ("b", "A")):
        ifc.add_argument(f"--{side}", default=None, metavar="SELECTOR",
                         help=f"clash set: group {side.upper()}'s elements, by IFC class or an "
                              "IfcClash-style selector, e.g. 'IfcPipeSegment, IfcDuctSegment'")
        ifc.add_argument(f"--{side}-file", action="append", default=None, metavar="FILE",
                         help=f"clash set: group {side.upper()} holds this file's elements "
                              "(repeat for several)")
        ifc.add_argument(f"--{side}-exclude", default=None, metavar="SELECTOR",
                         help=f"clash set: leave these elements out of group {side.upper()}")
    ifc.add_argument("--bcf", default=None, metavar="OUT.bcf",
                     help="write the clashes as a BCF 2.1 file: a topic per group, its "
                          "elements as components, a viewpoint with its picture and camera")
    from ..bim.report import add_arguments as add_report_arguments

    add_report_arguments(ifc)  # grouping, pictures, tracking
    ifc.add_argument("--cache-dir", default=None, metavar="DIR",
                     help="folder of the tessellation cache (default: $PYCINDER_CACHE_DIR/ifc "
                          "or the user's cache folder, pycinder/ifc)")
    ifc.add_argument("--no-cache", action="store_true",
                     help="tessellate every file, and cache nothing")


_IFC_ONLY = (("a", "--a"), ("b", "--b"), ("a_file", "--a-file"), ("b_file", "--b-file"),
             ("a_exclude", "--a-exclude"), ("b_exclude", "--b-exclude"), ("bcf", "--bcf"),
             ("snapshots", "--snapshots"), ("no_snapshots", "--no-snapshots"),
             ("against", "--against"))


def no_ifc_options(args: argparse.Namespace) -> None:
    """A ValueError for IFC's options (clash sets, --bcf) given with mesh files."""
    given = [flag for name, flag in _IFC_ONLY if getattr(args, name, None)]
    if given:
        raise ValueError(f"{', '.join(given)} applies to IFC files (.ifc): clash sets and BCF "
                         "need elements with GlobalIds")


def _groups(args: argparse.Namespace) -> tuple[Any, Any]:
    """``check``'s clash set: groups A and B (:class:`pycinder.bim.ifc.Group`, or None)."""
    from ..bim.ifc import Group

    def group(side: str) -> Any:
        selector = getattr(args, side)
        files = getattr(args, f"{side}_file")
        exclude = getattr(args, f"{side}_exclude")
        if selector is None and not files and exclude is None:
            return None
        return Group(files=files or None, selector=selector, exclude=exclude)

    a, b = group("a"), group("b")
    if a is None and b is not None:
        raise ValueError("--b needs --a (or --a-file): group B is tested against group A")
    return a, b


def cmd_check_ifc(args: argparse.Namespace, mixed: bool = False) -> int:
    """``check`` on IFC files: one body per element, a clash set, the mode's pairs as text or
    JSON, and a BCF file with --bcf; returns 0 (no clash), 1 (clashes) or 2 (an error)."""
    from ..bim.ifc import find_clashes, make_detector, read_ifc
    from ..bim.report import clash_report, report_options, verbose_lines

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            if mixed:
                raise ValueError("IFC files (.ifc) are checked on their own: give IFC files "
                                 "alone, or mesh files alone")
            if args.split:
                raise ValueError("--split applies to mesh files: each IFC element is a body "
                                 "already")
            if args.strategy != "focused":
                raise ValueError("IFC files are checked with --strategy focused")
            mode, extra = query_mode(args)
            a, b = _groups(args)
            options = report_options(args)  # reads --against now: a bad file is said at once
            det = make_detector(strict=args.strict, tolerance=args.tolerance, **extra)
            with progress(args.progress, "reading IFC") as update:
                model = read_ifc(args.files, cache=False if args.no_cache else args.cache_dir,
                                 progress=update, limits=file_limits(args))
                update(0, 0, f"checking {plural(len(model.bodies), 'element')}")  # pulses
                clashes = find_clashes(model, a, b, detector=det, rules=args.rules)
                report = clash_report(model, clashes, **options, bcf=args.bcf,
                                      project=", ".join(model.files), progress=update)
        except ERRORS as exc:
            return fail(args, error_messages(exc), caught)
    notes = [warning_entry(w, args.strict) for w in caught]
    if args.json:
        data: dict[str, Any] = {
            "collision": bool(clashes), **report.as_json(),
            "bodies": model.names,
            "files": model.files,
            "clash_set": {"a": a.describe() if a else "every element",
                          "b": b.describe() if b else None},
            "mode": mode,
            "min_depth": args.min_depth, "clearance": args.clearance,
            "tolerance": args.tolerance,
            "tessellated": model.tessellated,
            "bcf": str(args.bcf) if args.bcf else None,
            "strategy": "focused",
            "adapter": det.gpu.description,
            "warnings": notes, "errors": []}
        print(json.dumps(data, indent=2))
    else:
        for note in notes:  # mesh warnings in a line each, their elements with --verbose
            print(f"warning: {note.get('summary', note['message'])}", file=sys.stderr)
        for line in verbose_lines(report, notes) if args.verbose else []:
            print(line, file=sys.stderr)
        for line in report.text():
            print(line)
        if not clashes:
            print("no clashes")
        print(report.summary(), file=sys.stderr)
        if args.bcf:
            print(f"wrote {display_name(args.bcf)} ({plural(report.topics, 'topic')})",
                  file=sys.stderr)
    return 1 if clashes else 0

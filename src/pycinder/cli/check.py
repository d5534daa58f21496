"""``pycinder check FILE...``: the pairs of bodies that collide among mesh files.

    pycinder check FILE... [--tolerance T] [--strict] [--json] [--split] [--max-file-size SIZE]
                   [--max-triangles N] [--strategy scene [--resolution N]]
                   [--min-depth D | --clearance C]

IFC files go to :mod:`pycinder.cli.check_ifc`. ``check`` exits 0 when nothing collides, 1 when
something does and 2 on an error; ``--json`` prints :meth:`pycinder.CollisionResult.report`
(described in :data:`CHECK_EPILOG`).
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from typing import Any

import numpy as np

from ..request import CollisionRequest
from ..util.text import plural
from .check_ifc import add_ifc_arguments, cmd_check_ifc, no_ifc_options
from .common import (ERRORS, add_file_limits, add_progress, error_messages, fail, load_files,
                     positive_distance, progress, query_mode, warning_entry)

CHECK_EPILOG = """\
exit status: 0 no collision, 1 collisions, 2 error. Every file is read before an error is
reported, so one run names every bad file; when any file cannot be used, nothing is checked
and the exit status is 2.

Closed meshes are tested as solids (one inside another collides), open ones as surfaces.
Files are checked before they are loaded: at most --max-file-size bytes (also what a 3MF
package unpacks to, or a glTF file's buffers) and --max-triangles triangles (as a header claims
them). Coordinates are used as they are in each file: no unit conversion; --tolerance is in the
files' units.

bodies are named after their files: FILE; FILE:NODE for the parts of a scene file (glTF, 3MF,
OBJ objects); FILE#1, FILE#2 for a file given twice; FILE[0], FILE[1] for the disconnected
components of a body with --split. One body is never tested against itself: without --split,
a body whose components overlap each other gets an OverlappingComponentsWarning.

--json prints one object:
  collision   true or false; null after an error
  pairs       the colliding pairs, [{"a": BODY, "b": BODY, "samples": N}]; samples: the
              records of interfering edge samples read back for the pair; with --min-depth,
              also "depth" (the penetration depth) and "depth_error" (its bound); with
              --clearance, "distance" (0 where the bodies overlap) and "distance_error"
  mode        with --min-depth or --clearance: "min_depth" or "clearance"
  bodies      the bodies' names, in order
  strategy    "focused" or "scene"
  tolerance   focused only: [smallest, largest] tolerance in world units over the candidate
              pairs; with no candidate pair, what the pairs would have had (--tolerance, or 1%
              of the smaller body's size); null with fewer than two bodies, and with
              --min-depth (hard clashes are measured with no pixels)
  candidates  focused only: the pairs the broad phase passed on to the image test
  resolution  scene only: the image's width and height in pixels
  adapter     the GPU adapter that ran the query
  warnings    [{"category": CLASS, "message": TEXT}], e.g. OpenMeshWarning,
              OverlappingComponentsWarning
  errors      [TEXT], one per bad file or other error; [] when the check ran
After an error, only collision (null), pairs ([]), warnings and errors are there.
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``check`` command to the ``pycinder`` command's subparsers."""
    p = subparsers.add_parser(
        "check", help="print the pairs of bodies that collide among mesh files (exit 0: none, "
                      "1: some, 2: error); scene files give one body per part, named FILE:NODE",
        description="Print the pairs of bodies that collide among mesh files (STL, OBJ, PLY, "
                    "OFF, glTF/GLB, 3MF), or the clashing elements of IFC files.",
        epilog=CHECK_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="meshes in world coordinates; scene files give one body per part")
    p.add_argument("--tolerance", type=float, default=None, metavar="T",
                   help="world units: pairs T apart are never reported, pairs overlapping by 2T "
                        "always are (default: 1%% of the smaller body's size, per pair)")
    p.add_argument("--strategy", choices=["focused", "scene"], default="focused",
                   help="focused (default): a tile per candidate pair; scene: the paper's "
                        "whole-scene image")
    p.add_argument("--resolution", type=int, default=None,
                   help="image size of --strategy scene (default 1024)")
    p.add_argument("--json", action="store_true",
                   help="print JSON on stdout, warnings and errors included")
    p.add_argument("--strict", action="store_true",
                   help="open, inside-out and zero-area meshes are errors")
    p.add_argument("--split", action="store_true",
                   help="test each body's disconnected components (two boxes in one STL) as "
                        "bodies of their own, named FILE[0], FILE[1], ...")
    modes = p.add_mutually_exclusive_group()
    modes.add_argument("--min-depth", type=positive_distance, default=None, metavar="D",
                       help="hard clashes: report pairs deeper than D (world units; metres "
                            "for IFC), never convex pairs at most D/2 deep, touching pairs "
                            "included, each with its depth")
    modes.add_argument("--clearance", type=positive_distance, default=None, metavar="C",
                       help="clearance: report pairs closer than C (world units; metres for "
                            "IFC), touching and overlapping pairs included, none farther than "
                            "9C/8, each with its distance")
    add_ifc_arguments(p)
    add_file_limits(p)
    add_progress(p)
    p.set_defaults(func=cmd_check)
    return p


def _request(args: argparse.Namespace) -> CollisionRequest:
    """``pycinder check``'s options as a request, checked (before any file is read) by
    :class:`~pycinder.CollisionRequest`, whose messages :func:`~.common.cli_words` puts in the
    command line's words."""
    options = dict(strict=args.strict, strategy=args.strategy, tolerance=args.tolerance,
                   resolution=args.resolution)
    _, extra = query_mode(args)
    return CollisionRequest(**options, **extra)


def request_mode(args: argparse.Namespace) -> str:
    """``check``'s mode: "min_depth", "clearance" or "default"."""
    if getattr(args, "min_depth", None) is not None:
        return "min_depth"
    return "clearance" if getattr(args, "clearance", None) is not None else "default"


def cmd_check(args: argparse.Namespace) -> int:
    """Check the files' bodies for collisions; print the pairs (or JSON) and return 0 (none),
    1 (some) or 2 (an error)."""
    from ..detector import Detector
    from ..files import tolerance_range, warn_overlapping_components

    ifc_files = [str(f).lower().endswith(".ifc") for f in args.files]
    if any(ifc_files):
        return cmd_check_ifc(args, mixed=not all(ifc_files))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            no_ifc_options(args)
            request = _request(args)
            with progress(args.progress, "loading") as update:
                bodies = load_files(args, update)
                names = [b.name for b in bodies]
                update(len(args.files), len(args.files) + 1,
                       f"checking {plural(len(bodies), 'body')}")
                det = Detector(request)
                result = det.find_collisions([b.mesh for b in bodies],
                                             np.array([b.transform for b in bodies]),
                                             names=names)
                if not args.split:
                    warn_overlapping_components(bodies, det)
        except ERRORS as exc:
            return fail(args, error_messages(exc), caught)
    notes = [warning_entry(w, args.strict) for w in caught]
    pairs = [(names[i], names[j]) for i, j in result.pairs.tolist()]
    if args.json:
        # A hard-clash query has no tolerance: it measures depths with no pixels.
        pixels = None if result.stats.strategy != "focused" or \
            request.min_depth is not None else \
            tolerance_range(bodies, result.stats, request.tolerance)
        report = result.report(names, mode=request_mode(args), tolerance_range=pixels,
                               warnings=notes)
        print(json.dumps(report, indent=2))
    else:
        for note in notes:
            print(f"warning: {note['message']}", file=sys.stderr)
        if pairs:
            for k, (a, b) in enumerate(pairs):
                print(f"{a}  <->  {b}{_figure(result, k)}")
        else:
            print("no collisions")
    return 1 if pairs else 0


def _figure(result: Any, k: int) -> str:
    """Pair ``k``'s figure for ``check``'s text: its depth (--min-depth) or distance
    (--clearance), in world units; "" in the default mode."""
    if result.depths is not None:
        return f"  depth {result.depths[k]:.4g}"
    if result.distances is not None:
        return f"  distance {result.distances[k]:.4g}"
    return ""

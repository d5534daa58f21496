"""The ``pycinder`` command (also ``python -m pycinder``).

    pycinder check FILE... [--tolerance T] [--strict] [--json] [--split] [--max-file-size SIZE]
                   [--max-triangles N] [--strategy scene [--resolution N]]
                   [--min-depth D | --clearance C]
    pycinder check A.ifc [B.ifc ...] [--a SELECTOR] [--a-file FILE] [--b SELECTOR]
                   [--b-file FILE] [--bcf OUT.bcf] [--json] [--min-depth D | --clearance C]
                   [--group-distance D | --no-groups] [--snapshots DIR | --no-snapshots]
                   [--against PREVIOUS]
    pycinder debug-buffers [FILE...] --out DIR [--resolution N] [--self-interference MODE]
    pycinder demo {stairs,snow-bunny,normals} [--frames N] [--out FILE.mp4|FILE.gif|DIR]
    pycinder bench [SCENE...] [--repeat N] [--peers ...] [--out DIR]
    pycinder example [--out DIR] [--resolution N]

Closed meshes are tested as solids (one inside another collides), open ones as surfaces.

``check`` exits 0 when nothing collides, 1 when something does and 2 on an error. Every file is
read before an error is reported, so that one run names every bad file (each message names the
file or body and what is wrong with it); when any file cannot be used nothing is checked and the
exit status is 2. ``check --json`` prints one object, described in :data:`CHECK_EPILOG`.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import sys
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from .files import (DEFAULT_MAX_BYTES, DEFAULT_MAX_TRIANGLES, FileBody, Limits, display_name,
                    human_bytes, parse_size)
from .request import CollisionRequest
from .util.text import plural

DESCRIPTION = f"""\
pycinder {__version__}: collision detection on the GPU for triangle meshes: closed meshes are
tested as solids, open ones as surfaces (CInDeR, an image-space interference test, on WebGPU)."""

EPILOG = "Run 'pycinder COMMAND --help' for a command's options."

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


IFC_HELP = """\
IFC files (IFC2X3, IFC4) give one body per element (IfcElement other than IfcFeatureElement),
named 'Name [GlobalId]', tessellated in metres with openings applied, and cached per file by
content (a re-check after a change in one file re-tessellates only that file). Several files
form one model. A clash set tests group A against group B (--a/--a-file against
--b/--b-file), or A against itself (--a alone); default: every element against every other.
--json gives for each pair both names, GlobalIds, classes and files, the mode, and the depth
or distance where the mode gives one, with the bound on its error, its group, status and GUID;
and the groups, and with --against the resolved clashes (see the guide's Buildings page)."""


def _cli_words(message: str, strict: bool) -> str:
    """Library messages name the library's options; on the command line they are flags
    (--strategy, --tolerance, --resolution, --min-depth, --clearance, --strict), and under
    --strict the advice to pass it is dropped."""
    message = re.sub(r"\bstrategy='(\w+)'", r"--strategy \1", message)
    message = re.sub(r"^(tolerance|resolution|clearance)\b", r"--\1", message)
    message = re.sub(r"\bmin_depth\b", "--min-depth", message)
    if strict:
        return re.sub(r",?\s*or ask for strict checking to make this an error", "", message)
    return message.replace("ask for strict checking", "pass --strict")


def _warning_entry(w: warnings.WarningMessage, strict: bool) -> dict[str, Any]:
    return {"category": w.category.__name__, "message": _cli_words(str(w.message), strict),
            **{k: getattr(w.message, k) for k in ("bodies", "details", "summary")
               if hasattr(w.message, k)}}


@contextlib.contextmanager
def _progress(enabled: bool | None, description: str
              ) -> Iterator[Callable[[float, int, str], None]]:
    """A rich progress bar on stderr (transient) while the block runs, shown when ``enabled``
    (default: when stderr is a terminal and rich is installed). Yields ``update(done, total,
    text)``; a total of 0 makes the bar pulse (a step of unknown length)."""
    if enabled is None:
        enabled = sys.stderr.isatty()
    try:
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
    except ImportError:  # rich comes with the demo and bench extras
        enabled = False
    if not enabled:
        yield lambda done, total, text: None
        return
    console = Console(file=sys.stderr, force_terminal=True)
    with Progress(TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn(),
                  console=console, transient=True) as bar:
        task = bar.add_task(description, total=None)

        def update(done: float, total: int, text: str) -> None:
            bar.update(task, completed=done, total=total or None, description=text)

        yield update


def _limits(args: argparse.Namespace) -> Limits:
    return Limits(max_bytes=args.max_file_size, max_triangles=args.max_triangles)


def _load(args: argparse.Namespace, update: Callable[[int, int, str], None]) -> list[FileBody]:
    """The files' bodies; with ``--split`` each body's disconnected components as bodies."""
    from .files import load_bodies, split_components

    steps = len(args.files) + 1
    bodies = load_bodies(args.files, _limits(args),
                         progress=lambda k, n, label: update(k, steps, f"loading {label}"))
    return split_components(bodies) if getattr(args, "split", False) else bodies


def _request(args: argparse.Namespace) -> CollisionRequest:
    """``pycinder check``'s options as a request, checked (before any file is read) by
    :class:`~pycinder.CollisionRequest`, whose messages :func:`_cli_words` puts in the command
    line's words."""
    options = dict(strict=args.strict, strategy=args.strategy, tolerance=args.tolerance,
                   resolution=args.resolution)
    _, extra = _mode(args)
    return CollisionRequest(**options, **extra)


_MODE_FLAGS = {"min_depth": "--min-depth", "clearance": "--clearance"}


def _mode(args: argparse.Namespace) -> tuple[str, dict[str, float]]:
    """``check``'s query mode ("default", "min_depth", "clearance") and the options that ask
    for it (:func:`pycinder.bim.ifc.mode_options`, in the command line's words)."""
    from .bim.ifc import mode_options

    try:
        return mode_options(getattr(args, "min_depth", None), getattr(args, "clearance", None))
    except ValueError as exc:
        message = str(exc).replace("min_depth and clearance", "--min-depth and --clearance")
        for name, flag in _MODE_FLAGS.items():
            message = message.replace(f"{name} must", f"{flag} must")
        raise ValueError(message) from None


_ERRORS = (ValueError, RuntimeError, OSError, TypeError, ImportError, MemoryError)
"""What a command reports as an error (exit status 2) rather than a traceback."""


def _messages(exc: BaseException) -> list[str]:
    """An error's messages: one per bad file for :class:`~pycinder.files.FileErrors`."""
    return list(getattr(exc, "messages", None) or [str(exc) or type(exc).__name__])


def cmd_check(args: argparse.Namespace) -> int:
    """Check the files' bodies for collisions; print the pairs (or JSON) and return 0 (none),
    1 (some) or 2 (an error)."""
    from .detector import Detector
    from .records import pair_keys

    ifc_files = [str(f).lower().endswith(".ifc") for f in args.files]
    if any(ifc_files):
        return cmd_check_ifc(args, mixed=not all(ifc_files))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            _no_ifc_options(args)
            request = _request(args)
            with _progress(args.progress, "loading") as update:
                bodies = _load(args, update)
                names = [b.name for b in bodies]
                update(len(args.files), len(args.files) + 1,
                       f"checking {plural(len(bodies), 'body')}")
                det = Detector(request)
                result = det.find_collisions([b.mesh for b in bodies],
                                             np.array([b.transform for b in bodies]),
                                             names=names)
                if not args.split:
                    _warn_overlapping_components(bodies, det)
        except _ERRORS as exc:
            return _fail(args, _messages(exc), caught)
    notes = [_warning_entry(w, args.strict) for w in caught]
    pairs = [(names[i], names[j]) for i, j in result.pairs.tolist()]
    st = result.stats
    if args.json:
        rec = result.records
        keys, counts = np.unique(pair_keys(rec["penetrating"], rec["penetrated"]),
                                 return_counts=True)
        per_pair = dict(zip(keys.tolist(), counts.tolist()))
        report: dict[str, Any] = {
            "collision": bool(pairs),
            "pairs": [{"a": names[i], "b": names[j], "samples": per_pair.get(i << 32 | j, 0)}
                      for i, j in result.pairs.tolist()],
            "bodies": names,
            "strategy": st.strategy,
        }
        for figures, bounds, name in ((result.depths, result.depth_errors, "depth"),
                                      (result.distances, result.distance_errors, "distance")):
            if figures is not None:
                for pair, d, e in zip(report["pairs"], figures.tolist(), bounds.tolist()):
                    pair[name], pair[f"{name}_error"] = d, e
        if st.strategy == "focused":
            # A hard-clash query has no tolerance: it measures depths with no pixels.
            report["tolerance"] = None if request.min_depth is not None else \
                _tolerance_range(bodies, st, request)
            report["candidates"] = st.candidates
        else:
            report["resolution"] = st.resolution[0]
        if request_mode(args) != "default":
            report["mode"] = request_mode(args)
        report.update(adapter=st.adapter, warnings=notes, errors=[])
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


def request_mode(args: argparse.Namespace) -> str:
    """``check``'s mode: "min_depth", "clearance" or "default"."""
    if getattr(args, "min_depth", None) is not None:
        return "min_depth"
    return "clearance" if getattr(args, "clearance", None) is not None else "default"


_IFC_ONLY = (("a", "--a"), ("b", "--b"), ("a_file", "--a-file"), ("b_file", "--b-file"),
             ("a_exclude", "--a-exclude"), ("b_exclude", "--b-exclude"), ("bcf", "--bcf"),
             ("snapshots", "--snapshots"), ("no_snapshots", "--no-snapshots"),
             ("against", "--against"))


def _no_ifc_options(args: argparse.Namespace) -> None:
    """A ValueError for IFC's options (clash sets, --bcf) given with mesh files."""
    given = [flag for name, flag in _IFC_ONLY if getattr(args, name, None)]
    if given:
        raise ValueError(f"{', '.join(given)} applies to IFC files (.ifc): clash sets and BCF "
                         "need elements with GlobalIds")


def _groups(args: argparse.Namespace) -> tuple[Any, Any]:
    """``check``'s clash set: groups A and B (:class:`pycinder.bim.ifc.Group`, or None)."""
    from .bim.ifc import Group

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
    from .bim.ifc import find_clashes, make_detector, read_ifc
    from .bim.report import clash_report, report_options, verbose_lines

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
            mode, extra = _mode(args)
            a, b = _groups(args)
            options = report_options(args)  # reads --against now: a bad file is said at once
            det = make_detector(strict=args.strict, tolerance=args.tolerance, **extra)
            with _progress(args.progress, "reading IFC") as update:
                model = read_ifc(args.files, cache=False if args.no_cache else args.cache_dir,
                                 progress=update, limits=_limits(args))
                update(0, 0, f"checking {plural(len(model.bodies), 'element')}")  # pulses
                clashes = find_clashes(model, a, b, detector=det, rules=args.rules)
                report = clash_report(model, clashes, **options, bcf=args.bcf,
                                      project=", ".join(model.files), progress=update)
        except _ERRORS as exc:
            return _fail(args, _messages(exc), caught)
    notes = [_warning_entry(w, args.strict) for w in caught]
    if args.json:
        report: dict[str, Any] = {
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
        print(json.dumps(report, indent=2))
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


def _tolerance_range(bodies: Sequence[FileBody], st: Any, request: CollisionRequest
                     ) -> list[float] | None:
    """``check --json``'s ``tolerance``: [smallest, largest] over the candidate pairs; with no
    candidate pair, what any pair of the bodies would have had; None with fewer than two."""
    from .tolerance import body_sizes, pair_tolerance

    if st.candidates:
        return [float(t) for t in st.tolerance]
    if len(bodies) < 2:
        return None
    lo = np.array([b.mesh.bounds[0] for b in bodies])
    hi = np.array([b.mesh.bounds[1] for b in bodies])
    size = np.sort(body_sizes(lo, hi, np.array([b.transform for b in bodies])))
    # A pair's default tolerance follows its smaller body: the smallest over all pairs is the
    # smallest body's, the largest the second largest body's.
    tol = pair_tolerance(size[[0, -2]], size[[1, -1]], request.tolerance)
    return [float(t) for t in tol]


def _boxes_meeting(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(n,) whether each of the boxes ``lo``, ``hi`` ((n, 3) corners) meets another one (the
    broad phase's sweep, touching included)."""
    from .focused.broad.prune import sweep_and_prune

    meets = np.zeros(len(lo), dtype=bool)
    meets[sweep_and_prune(lo, hi).ravel()] = True
    return meets


def _warn_overlapping_components(bodies: Sequence[FileBody], det: Any) -> None:
    """Warn (:class:`~pycinder.files.OverlappingComponentsWarning`) about each body whose
    disconnected components overlap each other, which one query cannot report: one body is
    never tested against itself.

    Components whose bounding boxes meet are tested as bodies of their own by ``det`` (the
    query's :class:`~pycinder.Detector`), in one query; inside-out closed components (cavities of
    a hollow body) are left out.
    """
    from .files import OverlappingComponentsWarning, body_components

    parts: list[Any] = []
    transforms: list[np.ndarray] = []
    labels: list[tuple[int, int]] = []  # (body, component) of each part tested
    split = body_components(bodies)
    for b, (body, pieces) in enumerate(zip(bodies, split)):
        keep = [k for k, piece in enumerate(pieces)
                if len(pieces) > 1 and not (piece.is_watertight and piece.volume < 0)]
        lo = np.array([pieces[k].bounds[0] for k in keep]).reshape(-1, 3)
        hi = np.array([pieces[k].bounds[1] for k in keep]).reshape(-1, 3)
        touching = [k for k, meets in zip(keep, _boxes_meeting(lo, hi)) if meets]
        parts += [pieces[k] for k in touching]
        transforms += [body.transform] * len(touching)
        labels += [(b, k) for k in touching]
    if not parts:
        return
    try:
        with warnings.catch_warnings():  # the bodies' own warnings are given already
            warnings.simplefilter("ignore")
            found = det.find_collisions(parts, np.array(transforms)).pairs
    except _ERRORS as exc:
        for b in sorted({b for b, _ in labels}):
            warnings.warn(f"{bodies[b].name}: its disconnected components could not be tested "
                          f"against each other ({exc}); pass --split to test them as bodies",
                          OverlappingComponentsWarning, stacklevel=2)
        return
    overlaps: dict[int, list[str]] = {}
    for i, j in found.tolist():
        (b, k), (c, m) = labels[i], labels[j]
        if b == c:
            overlaps.setdefault(b, []).append(f"[{min(k, m)}] and [{max(k, m)}]")
    for b, which in sorted(overlaps.items()):
        name, count = bodies[b].name, len(split[b])
        shown = ", ".join(sorted(which)[:5]) + (", ..." if len(which) > 5 else "")
        warnings.warn(
            f"{name}: {plural(count, 'disconnected component')}, of which "
            f"{plural(len(which), 'pair overlaps', 'pairs overlap')} ({shown}); a body is not "
            "tested against itself, so this is not reported as a collision: pass --split to "
            f"test each component as a body of its own ({name}[0], {name}[1], ...)",
            OverlappingComponentsWarning, stacklevel=2)


def _fail(args: argparse.Namespace, messages: Sequence[str], caught: list) -> int:
    """Report errors, one per bad file or problem (with the warnings before them), and return
    exit status 2."""
    errors = [_cli_words(m, args.strict) for m in messages]
    notes = [_warning_entry(w, args.strict) for w in caught]
    if args.json:
        print(json.dumps({"collision": None, "pairs": [], "warnings": notes,
                          "errors": errors}, indent=2))
    else:
        for note in notes:
            print(f"warning: {note['message']}", file=sys.stderr)
        for message in errors:
            print(f"pycinder: error: {message}", file=sys.stderr)
    return 2


def cmd_debug_buffers(args: argparse.Namespace) -> int:
    from .debug.buffers import write_debug_buffers

    bodies, transforms = None, None
    if args.files:
        with _progress(args.progress, "loading") as update:
            loaded = _load(args, update)
        bodies = [b.mesh for b in loaded]
        transforms = np.array([b.transform for b in loaded])
    paths = write_debug_buffers(bodies, args.out, resolution=args.resolution,
                                self_interference=args.self_interference, transforms=transforms)
    for p in paths:
        print(p)
    return 0


def cmd_example(args: argparse.Namespace) -> int:
    """Check the paper's three-box scene, write its debug buffers and their montage."""
    from .debug.buffers import three_boxes, write_debug_buffers
    from .detector import Detector
    from .debug.montage import pillow, write_montage

    pillow()  # the montage needs it: say so before writing anything
    boxes, names, view = three_boxes()
    with _progress(args.progress, "example") as update:
        update(0, 3, "checking the three boxes")
        result = Detector().find_collisions(boxes, names=names)
        update(1, 3, "capturing the buffers")
        paths = write_debug_buffers(None, args.out, resolution=args.resolution)
        update(2, 3, "drawing the montage")
        montage = write_montage(Path(args.out) / "montage.png", resolution=args.resolution)
    print(f"three boxes ({', '.join(names)}), {result.stats.adapter}")
    for i, j in result.pairs.tolist():
        print(f"  {names[i]} <-> {names[j]}")
    st = result.stats
    print(f"  focused: {plural(st.candidates, 'candidate pair')}, {plural(st.tiles, 'tile')}, "
          f"{plural(st.pixels, 'pixel')}, tolerance {st.tolerance[0]:.3g}, "
          f"{plural(st.bytes_read, 'byte')} read back, {st.wall_ms['total']:.1f} ms")
    for p in paths:
        print(f"  wrote {p}")
    print(f"  wrote {montage} (Figures 9-13 with a legend)")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from .benchmarks import report, runner

    scenes = args.scenes or runner.DEFAULT_SCENES
    report.require_matplotlib()  # before a long run, not after it
    options = {"repeat": args.repeat, "peers": args.peers, "soak_frames": args.soak_frames}
    enabled = args.progress
    with _progress(enabled, "benchmarks") as update:
        shown = enabled if enabled is not None else sys.stderr.isatty()

        def note(msg: str) -> None:
            update(0, 0, msg)
            if not shown:
                print(msg, flush=True)

        results = runner.run(scenes, **options, progress=note)
    for p in report.write(results, args.out, stem=args.stem):
        print(f"wrote {p}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """Run a demo: headless for ``--frames`` frames (default 120), or in a window until it is
    closed (or for ``--frames`` frames when given)."""
    from .demos.run import run

    options = {"out": args.out, "window": args.window, "tolerance": args.tolerance,
               "seed": args.seed, "spheres": args.spheres, "scan": args.scan,
               "close_holes": args.close_holes}
    if args.window:
        run(args.name, frames=args.frames, **options)
        return 0
    frames = args.frames or 120
    enabled = args.progress if args.progress is not None else sys.stderr.isatty()
    if enabled:
        with _progress(True, args.name) as update:
            run(args.name, frames=frames, progress=lambda k, n: update(k, n, args.name),
                **options)
    else:
        run(args.name, frames=frames, progress=_printed_progress(args.name), **options)
    return 0


def _printed_progress(name: str) -> Callable[[int, int], None]:
    """Progress as a line on stdout about every tenth of the frames (for logs and pipes)."""
    import time

    start = time.perf_counter()

    def progress(done: int, total: int) -> None:
        step = max(total // 10, 1)
        if done == 1 or done % step == 0 or done == total:
            print(f"{name}: frame {done}/{total}, {time.perf_counter() - start:.0f} s",
                  flush=True)

    return progress


def _size(text: str) -> int:
    try:
        return parse_size(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _distance(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not np.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a positive distance")
    return value


def _count(text: str) -> int:
    try:
        value = int(text.replace("_", "").replace(",", ""))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a positive number")
    return value


def _add_file_limits(p: argparse.ArgumentParser) -> None:
    p.add_argument("--max-file-size", type=_size, default=DEFAULT_MAX_BYTES, metavar="SIZE",
                   help="largest file (and 3MF contents, glTF buffers) to load, e.g. 2G "
                        f"(default {human_bytes(DEFAULT_MAX_BYTES)})")
    p.add_argument("--max-triangles", type=_count, default=DEFAULT_MAX_TRIANGLES, metavar="N",
                   help=f"most triangles a file may hold (default {DEFAULT_MAX_TRIANGLES:,})")


def _add_buffer_resolution(p: argparse.ArgumentParser) -> None:
    p.add_argument("--resolution", type=_count, default=512, metavar="N",
                   help="width and height in pixels of the scene strategy's image whose buffers "
                        "are written (default 512)")


def _frames_out(text: str) -> str:
    """``demo --out``: a video or a folder (see :func:`~pycinder.demos.output.output_kind`)."""
    from .demos.output import output_kind

    try:
        output_kind(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _add_progress(p: argparse.ArgumentParser) -> None:
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="show a progress bar on stderr (default: when it is a terminal)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="pycinder", description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"pycinder {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                title="commands")

    p = sub.add_parser("check", help="print the pairs of bodies that collide among mesh files "
                                     "(exit 0: none, 1: some, 2: error); scene files give one "
                                     "body per part, named FILE:NODE",
                       description="Print the pairs of bodies that collide among mesh files "
                                   "(STL, OBJ, PLY, OFF, glTF/GLB, 3MF), or the clashing "
                                   "elements of IFC files.",
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
    modes.add_argument("--min-depth", type=_distance, default=None, metavar="D",
                       help="hard clashes: report pairs deeper than D (world units; metres "
                            "for IFC), never convex pairs at most D/2 deep, touching pairs "
                            "included, each with its depth")
    modes.add_argument("--clearance", type=_distance, default=None, metavar="C",
                       help="clearance: report pairs closer than C (world units; metres for "
                            "IFC), touching and overlapping pairs included, none farther than "
                            "9C/8, each with its distance")
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
    from .bim.report import add_arguments as add_report_arguments

    add_report_arguments(ifc)  # grouping, pictures, tracking
    ifc.add_argument("--cache-dir", default=None, metavar="DIR",
                     help="folder of the tessellation cache (default: $PYCINDER_CACHE_DIR/ifc "
                          "or the user's cache folder, pycinder/ifc)")
    ifc.add_argument("--no-cache", action="store_true",
                     help="tessellate every file, and cache nothing")
    _add_file_limits(p)
    _add_progress(p)
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("debug-buffers", help="write PNGs of the buffers after the paper's "
                                             "passes 1-7 (three boxes, or your files)")
    p.add_argument("files", nargs="*", metavar="FILE",
                   help="meshes (default: the paper's three boxes, Figure 7)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder for the PNGs (created; files of the same names are replaced)")
    _add_buffer_resolution(p)
    p.add_argument("--self-interference", default="filter",
                   choices=["filter", "prevent", "offset"],
                   help="how a body's edges are kept from registering against its own faces "
                        "(paper 4.3.1): filter (default) lets them, then blanks those pixels "
                        "before readback; prevent never counts a body's faces in front of its own "
                        "edges; offset moves edges outwards along their normals by half a pixel")
    _add_file_limits(p)
    _add_progress(p)
    p.set_defaults(func=cmd_debug_buffers, strict=False, json=False)

    p = sub.add_parser("demo", help="the paper's demos, as a video or in a window: stairs, "
                                    "snow-bunny, normals")
    p.add_argument("name", choices=["stairs", "snow-bunny", "normals"],
                   help="stairs: spheres bounce down stairs (paper 5.1); snow-bunny: snowflakes "
                        "fall on the Stanford bunny (5.2); normals: spheres bounce off the bunny "
                        "by the normals read from the collision records (5.3)")
    p.add_argument("--frames", type=int, default=None,
                   help="frames to run (default 120 headless; a window runs until closed)")
    p.add_argument("--out", metavar="FILE.mp4|FILE.gif|DIR", type=_frames_out,
                   help="write the frames here: an MP4 or GIF video, or a folder of PNGs (a "
                        "path with no suffix, ending in /, or a folder already)")
    p.add_argument("--window", action="store_true",
                   help="open an interactive window (drag to orbit, scroll to zoom)")
    p.add_argument("--tolerance", type=float, default=None,
                   help="detection tolerance in world units (default: 1%% of the smaller body of "
                        "each pair)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the demo's random placements (default 0)")
    p.add_argument("--spheres", type=int, help="spheres (stairs, normals) or flakes (snow-bunny)")
    p.add_argument("--scan", action="store_true",
                   help="snow-bunny: use the scanned bunny, which is open at the bottom "
                        "(needs pymeshlab: pip install 'pycinder[scan]')")
    p.add_argument("--close-holes", action="store_true",
                   help="snow-bunny with --scan: repair the holes first")
    _add_progress(p)
    p.set_defaults(func=cmd_demo, strict=False, json=False)

    p = sub.add_parser("bench", help="time pycinder against python-fcl, coal, trimesh and Warp")
    p.add_argument("scenes", nargs="*", metavar="SCENE",
                   help="floor, stairs, many, deforming, narrow, sweep-extent, sweep-bodies, "
                        "sweep-triangles, sweep-tolerance, manager, contacts, contract, modes, "
                        "batch, broadphase, hostcpu, soak, building, building-small "
                        "(default: all but the building benchmarks, which need "
                        "'pycinder[bim]'; the soak alone takes several minutes)")
    p.add_argument("--repeat", type=int, default=5, help="frames timed per scene")
    p.add_argument("--peers", nargs="*", default=["python-fcl", "coal", "trimesh", "warp"],
                   help="systems to compare (default: python-fcl coal trimesh warp); one that "
                        "is not installed is left out and named")
    p.add_argument("--soak-frames", type=int, default=100_000,
                   help="frames of the memory soak (scene 'soak')")
    p.add_argument("--out", default="benchmarks/results", metavar="DIR",
                   help="folder for the results' JSON, Markdown and plots (default "
                        "benchmarks/results)")
    p.add_argument("--stem", default="results", help="file name stem of the JSON and Markdown")
    _add_progress(p)
    p.set_defaults(func=cmd_bench, strict=False, json=False)

    p = sub.add_parser("example", help="check the built-in three-box scene and write its buffers "
                                       "and a labelled montage of them (montage.png)")
    p.add_argument("--out", default="out/buffers", metavar="DIR",
                   help="folder for the buffers' PNGs and montage.png (created; default "
                        "out/buffers)")
    _add_buffer_resolution(p)
    _add_progress(p)
    p.set_defaults(func=cmd_example, strict=False, json=False)
    from .batch.command import add_parser as add_batch_parser

    add_batch_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    np.set_printoptions(suppress=True)
    try:
        return args.func(args)
    except BrokenPipeError:  # the reader went away (``pycinder check ... | head``)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except _ERRORS as exc:
        return _fail(args, _messages(exc), [])


if __name__ == "__main__":
    sys.exit(main())

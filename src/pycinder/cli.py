"""The ``pycinder`` command (also ``python -m pycinder``).

    pycinder check FILE... [--tolerance T] [--strict] [--json] [--max-file-size SIZE]
                   [--max-triangles N] [--strategy scene [--resolution N]]
    pycinder debug-buffers [FILE...] --out DIR
    pycinder demo {stairs,snow-bunny,normals} [--frames N] [--out FILE.mp4|FILE.gif|DIR]
    pycinder bench [SCENE...] [--repeat N] [--peers ...] [--out DIR]
    pycinder example [--out DIR]

``check`` exits 0 when nothing collides, 1 when something does and 2 on an error; every error
names the file or body and what is wrong with it.
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
from .files import DEFAULT_MAX_BYTES, DEFAULT_MAX_TRIANGLES, Limits, human_bytes, parse_size
from .request import CollisionRequest

DESCRIPTION = f"""\
pycinder {__version__}: collision detection on the GPU for closed triangle meshes
(CInDeR, an image-space interference test, on WebGPU)."""

EPILOG = "Run 'pycinder COMMAND --help' for a command's options."

CHECK_EPILOG = """\
exit status: 0 no collision, 1 collisions, 2 error.
Files are checked before they are loaded: at most --max-file-size bytes (also what a 3MF
package unpacks to, or a glTF file's buffers) and --max-triangles triangles (as a header claims
them). Coordinates are used as they are in each file: no unit conversion; --tolerance is in the
files' units.
"""


def _cli_words(message: str, strict: bool) -> str:
    """Library messages name the library's options; on the command line they are flags
    (--strategy, --tolerance, --resolution, --strict), and under --strict the advice to pass it
    is dropped."""
    message = re.sub(r"\bstrategy='(\w+)'", r"--strategy \1", message)
    message = re.sub(r"^(tolerance|resolution)\b", r"--\1", message)
    if strict:
        return re.sub(r",?\s*or ask for strict checking to make this an error", "", message)
    return message.replace("ask for strict checking", "pass --strict")


def _warning_entry(w: warnings.WarningMessage, strict: bool) -> dict[str, str]:
    return {"category": w.category.__name__, "message": _cli_words(str(w.message), strict)}


@contextlib.contextmanager
def _progress(enabled: bool | None, description: str
              ) -> Iterator[Callable[[int, int, str], None]]:
    """A rich progress bar on stderr (transient) while the block runs, shown when ``enabled``
    (default: when stderr is a terminal and rich is installed). Yields ``update(done, total,
    text)``."""
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

        def update(done: int, total: int, text: str) -> None:
            bar.update(task, completed=done, total=total, description=text)

        yield update


def _limits(args: argparse.Namespace) -> Limits:
    return Limits(max_bytes=args.max_file_size, max_triangles=args.max_triangles)


def _load(args: argparse.Namespace, update: Callable[[int, int, str], None]) -> list:
    from .files import load_bodies

    steps = len(args.files) + 1
    return load_bodies(args.files, _limits(args),
                       progress=lambda k, n, label: update(k, steps, f"loading {label}"))


def _request(args: argparse.Namespace) -> CollisionRequest:
    """``pycinder check``'s options as a request, checked (before any file is read) by
    :class:`~pycinder.CollisionRequest`, whose messages :func:`_cli_words` puts in the command
    line's words."""
    return CollisionRequest(strict=args.strict, strategy=args.strategy,
                            tolerance=args.tolerance, resolution=args.resolution)


def cmd_check(args: argparse.Namespace) -> int:
    from .detector import Detector
    from .records import pair_keys

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            request = _request(args)
            with _progress(args.progress, "loading") as update:
                bodies = _load(args, update)
                names = [b.name for b in bodies]
                update(len(args.files), len(args.files) + 1,
                       f"checking {len(bodies)} bodies")
                det = Detector(request)
                result = det.find_collisions([b.mesh for b in bodies],
                                             np.array([b.transform for b in bodies]),
                                             names=names)
        except (ValueError, RuntimeError, OSError, TypeError, ImportError, MemoryError) as exc:
            return _fail(args, str(exc), caught)
    notes = [_warning_entry(w, args.strict) for w in caught]
    pairs = [(names[i], names[j]) for i, j in result.pairs.tolist()]
    st = result.stats
    if args.json:
        rec = result.records
        keys, counts = np.unique(pair_keys(rec["penetrating"], rec["penetrated"]),
                                 return_counts=True)
        per_pair = dict(zip(keys.tolist(), counts.tolist()))
        print(json.dumps({
            "collision": bool(pairs),
            "pairs": [{"a": names[i], "b": names[j], "samples": per_pair.get(i << 32 | j, 0)}
                      for i, j in result.pairs.tolist()],
            "bodies": names,
            "strategy": st.strategy,
            "tolerance": list(st.tolerance) if st.strategy == "focused" else None,
            "resolution": st.resolution[0] if st.strategy == "scene" else None,
            "candidates": st.candidates if st.strategy == "focused" else None,
            "adapter": st.adapter,
            "warnings": notes,
            "errors": [],
        }, indent=2))
    else:
        for note in notes:
            print(f"warning: {note['message']}", file=sys.stderr)
        if pairs:
            for a, b in pairs:
                print(f"{a}  <->  {b}")
        else:
            print("no collisions")
    return 1 if pairs else 0


def _fail(args: argparse.Namespace, message: str, caught: list) -> int:
    """Report an error (with the warnings before it) and return exit status 2."""
    message = _cli_words(message, args.strict)
    notes = [_warning_entry(w, args.strict) for w in caught]
    if args.json:
        print(json.dumps({"collision": None, "pairs": [], "warnings": notes,
                          "errors": [message]}, indent=2))
    else:
        for note in notes:
            print(f"warning: {note['message']}", file=sys.stderr)
        print(f"pycinder: error: {message}", file=sys.stderr)
    return 2


def cmd_debug_buffers(args: argparse.Namespace) -> int:
    from .debug import write_debug_buffers

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
    from .debug import three_boxes, write_debug_buffers
    from .detector import Detector
    from .montage import pillow, write_montage

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
    print(f"  focused: {st.candidates} candidate pairs, {st.tiles} tiles, {st.pixels} pixels, "
          f"tolerance {st.tolerance[0]:.3g}, {st.bytes_read} bytes read back, "
          f"{st.wall_ms['total']:.1f} ms")
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
                                   "(STL, OBJ, PLY, OFF, glTF/GLB, 3MF).",
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
    _add_file_limits(p)
    _add_progress(p)
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("debug-buffers", help="write PNGs of the buffers after the paper's "
                                             "passes 1-7 (three boxes, or your files)")
    p.add_argument("files", nargs="*", metavar="FILE",
                   help="meshes (default: the paper's three boxes, Figure 7)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--resolution", type=int, default=512)
    p.add_argument("--self-interference", default="filter", choices=["filter", "prevent", "offset"])
    _add_file_limits(p)
    _add_progress(p)
    p.set_defaults(func=cmd_debug_buffers, strict=False, json=False)

    p = sub.add_parser("demo", help="the paper's demos, as a video or in a window: stairs, "
                                    "snow-bunny, normals")
    p.add_argument("name", choices=["stairs", "snow-bunny", "normals"])
    p.add_argument("--frames", type=int, default=None,
                   help="frames to run (default 120 headless; a window runs until closed)")
    p.add_argument("--out", metavar="FILE.mp4|FILE.gif|DIR", help="write the frames here")
    p.add_argument("--window", action="store_true",
                   help="open an interactive window (drag to orbit, scroll to zoom)")
    p.add_argument("--tolerance", type=float, default=None,
                   help="detection tolerance in world units (default: 1%% of the smaller body of "
                        "each pair)")
    p.add_argument("--seed", type=int, default=0)
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
                        "batch, broadphase, soak "
                        "(default: all; the soak alone takes several minutes)")
    p.add_argument("--repeat", type=int, default=5, help="frames timed per scene")
    p.add_argument("--peers", nargs="*", default=["python-fcl", "coal", "trimesh", "warp"],
                   help="systems to compare (default: python-fcl coal trimesh warp); one that "
                        "is not installed is left out and named")
    p.add_argument("--soak-frames", type=int, default=100_000,
                   help="frames of the memory soak (scene 'soak')")
    p.add_argument("--out", default="benchmarks/results", metavar="DIR")
    p.add_argument("--stem", default="results", help="file name stem of the JSON and Markdown")
    _add_progress(p)
    p.set_defaults(func=cmd_bench, strict=False, json=False)

    p = sub.add_parser("example", help="check the built-in three-box scene and write its buffers "
                                       "and a labelled montage of them (montage.png)")
    p.add_argument("--out", default="out/buffers", metavar="DIR")
    p.add_argument("--resolution", type=int, default=512)
    _add_progress(p)
    p.set_defaults(func=cmd_example, strict=False, json=False)
    from .batch.cli import add_parser as add_batch_parser

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
    except (ValueError, RuntimeError, OSError, TypeError, ImportError, MemoryError) as exc:
        return _fail(args, str(exc) or type(exc).__name__, [])


if __name__ == "__main__":
    sys.exit(main())

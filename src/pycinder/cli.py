"""The ``pycinder`` command.

    pycinder check FILE... [--tolerance T] [--strict] [--json]
                     [--strategy scene [--resolution N]]   exit 0: no collision, 1: collisions, 2: error
    pycinder debug-buffers [FILE...] --out DIR              PNGs of the buffers after each pass
    pycinder demo {stairs,snow-bunny,normals} [--frames N] [--out FILE.mp4|FILE.gif|DIR] [--window]
    pycinder bench [SCENE...] [--repeat N] [--peers ...] [--out DIR]
                                                            timings against python-fcl, coal,
                                                            trimesh and Warp, scored against
                                                            exact geometry
    pycinder example [--out DIR]                            the paper's three boxes: buffers and
                                                            a labelled montage
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np


def _load_meshes(files: Sequence[str]) -> tuple[list, list[str]]:
    """Meshes from files, with what is wrong with a file named in the error."""
    import trimesh

    formats = set(trimesh.available_formats())
    meshes, names = [], []
    for f in files:
        path = Path(f)
        if not path.exists():
            raise FileNotFoundError(f"{f}: no such file")
        suffixes = "".join(path.suffixes).lower().lstrip(".")
        ext = path.suffix.lower().lstrip(".")
        if ext not in formats and suffixes not in formats:
            raise ValueError(f"{f}: unknown mesh format '.{ext}' (formats read: "
                             f"{', '.join(sorted(formats))})")
        try:
            # process=False keeps vertices trimesh would silently drop (NaN); merge afterwards.
            mesh = trimesh.load(path, force="mesh", process=False)
        except Exception as exc:
            raise ValueError(f"{f}: trimesh could not read it ({exc})") from exc
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise ValueError(f"{f}: no triangles in this file")
        bad = ~np.isfinite(np.asarray(mesh.vertices)).all(axis=1)
        if bad.any():
            raise ValueError(f"{f}: {int(bad.sum())} vertices are NaN or infinite (first: vertex "
                             f"{int(np.flatnonzero(bad)[0])})")
        mesh.merge_vertices()
        meshes.append(mesh)
        names.append(path.name)
    if len(set(names)) < len(names):
        names = [str(f) for f in files]
    return meshes, names


def _detector_options(args: argparse.Namespace) -> dict:
    options: dict = {"strict": args.strict}
    if args.strategy == "scene":
        options.update(strategy="scene", resolution=args.resolution or 1024)
    else:
        if args.resolution is not None:
            raise ValueError("--resolution sets the image of --strategy scene; the focused "
                             "strategy sizes its pixels by --tolerance")
        options["tolerance"] = args.tolerance
    if args.strategy == "scene" and args.tolerance is not None:
        raise ValueError("--tolerance sizes the focused strategy's pixels; --strategy scene "
                         "has one image of --resolution pixels instead")
    return options


def _strict_words(message: str) -> str:
    """Messages name the library's option; on the command line it is --strict."""
    return message.replace("ask for strict checking", "pass --strict")


def cmd_check(args: argparse.Namespace) -> int:
    from .detector import Detector
    from .records import pair_keys

    meshes, names = _load_meshes(args.files)
    det = Detector(**_detector_options(args))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = det.find_collisions(meshes, names=names)
    for w in caught:
        print(f"warning: {_strict_words(str(w.message))}", file=sys.stderr)
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
            "strategy": st.strategy,
            "tolerance": list(st.tolerance) if st.strategy == "focused" else None,
            "resolution": args.resolution if st.strategy == "scene" else None,
            "candidates": st.candidates,
            "adapter": st.adapter,
        }, indent=2))
    else:
        if pairs:
            for a, b in pairs:
                print(f"{a}  <->  {b}")
        else:
            print("no collisions")
    return 1 if pairs else 0


def cmd_debug_buffers(args: argparse.Namespace) -> int:
    from .debug import write_debug_buffers

    bodies = _load_meshes(args.files)[0] if args.files else None
    paths = write_debug_buffers(bodies, args.out, resolution=args.resolution,
                                self_interference=args.self_interference)
    for p in paths:
        print(p)
    return 0


def cmd_example(args: argparse.Namespace) -> int:
    """Check the paper's three-box scene, write its debug buffers and their montage."""
    from .debug import three_boxes, write_debug_buffers
    from .detector import Detector
    from .montage import write_montage

    boxes, names, view = three_boxes()
    result = Detector().find_collisions(boxes, names=names)
    print(f"three boxes ({', '.join(names)}), {result.stats.adapter}")
    for i, j in result.pairs.tolist():
        print(f"  {names[i]} <-> {names[j]}")
    st = result.stats
    print(f"  focused: {st.candidates} candidate pairs, {st.tiles} tiles, {st.pixels} pixels, "
          f"tolerance {st.tolerance[0]:.3g}, {st.bytes_read} bytes read back, "
          f"{st.wall_ms['total']:.1f} ms")
    for p in write_debug_buffers(None, args.out, resolution=args.resolution):
        print(f"  wrote {p}")
    montage = write_montage(Path(args.out) / "montage.png", resolution=args.resolution)
    print(f"  wrote {montage} (Figures 9-13 with a legend)")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from .benchmarks import report, runner

    scenes = args.scenes or runner.DEFAULT_SCENES
    report.require_matplotlib()  # before a long run, not after it
    try:
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
    except ImportError:  # pragma: no cover - rich comes with the bench extra
        Progress = None
    options = {"repeat": args.repeat, "peers": args.peers, "soak_frames": args.soak_frames}
    if Progress is not None:
        with Progress(TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn()) as bar:
            task = bar.add_task("benchmarks", total=None)
            results = runner.run(scenes, **options,
                                 progress=lambda msg: bar.update(task, description=msg))
    else:
        results = runner.run(scenes, **options, progress=lambda msg: print(msg, flush=True))
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
    try:
        from rich.progress import Progress
    except ImportError:  # pragma: no cover - rich comes with the demo extra
        run(args.name, frames=frames, **options)
        return 0
    with Progress(transient=True) as bar:
        task = bar.add_task(args.name, total=frames)
        run(args.name, frames=frames, progress=lambda k, n: bar.update(task, completed=k),
            **options)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="pycinder", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("check", help="print the interfering pairs among mesh files")
    p.add_argument("files", nargs="+", metavar="FILE", help="meshes in world coordinates")
    p.add_argument("--tolerance", type=float, default=None, metavar="T",
                   help="world units: pairs T apart are never reported, pairs overlapping by 2T "
                        "always are (default: 1%% of the smaller body's size, per pair)")
    p.add_argument("--strategy", choices=["focused", "scene"], default="focused",
                   help="focused (default): a tile per candidate pair; scene: the paper's "
                        "whole-scene image")
    p.add_argument("--resolution", type=int, default=None,
                   help="image size of --strategy scene (default 1024)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--strict", action="store_true",
                   help="open, inside-out and zero-area meshes are errors")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("debug-buffers", help="write PNGs of the buffers after each pass")
    p.add_argument("files", nargs="*", metavar="FILE",
                   help="meshes (default: the paper's three boxes, Figure 7)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--resolution", type=int, default=512)
    p.add_argument("--self-interference", default="filter", choices=["filter", "prevent", "offset"])
    p.set_defaults(func=cmd_debug_buffers)

    p = sub.add_parser("demo", help="the paper's demos: stairs, snow-bunny, normals")
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
                   help="snow-bunny: use the scanned bunny, which is open at the bottom")
    p.add_argument("--close-holes", action="store_true",
                   help="snow-bunny with --scan: repair the holes first")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("bench", help="time pycinder against python-fcl, coal, trimesh and Warp")
    p.add_argument("scenes", nargs="*", metavar="SCENE",
                   help="stairs, many, deforming, narrow, sweep-extent, sweep-bodies, "
                        "sweep-triangles, sweep-tolerance, manager, contacts, modes, soak "
                        "(default: all; the soak alone takes several minutes)")
    p.add_argument("--repeat", type=int, default=5, help="frames timed per scene")
    p.add_argument("--peers", nargs="*", default=["python-fcl", "coal", "trimesh", "warp"],
                   help="systems to compare (default: python-fcl coal trimesh warp); one that "
                        "is not installed is left out and named")
    p.add_argument("--soak-frames", type=int, default=100_000,
                   help="frames of the memory soak (scene 'soak')")
    p.add_argument("--out", default="benchmarks/results", metavar="DIR")
    p.add_argument("--stem", default="results", help="file name stem of the JSON and Markdown")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("example", help="check the built-in three-box scene and write its buffers "
                                       "and a labelled montage of them (montage.png)")
    p.add_argument("--out", default="out/buffers", metavar="DIR")
    p.add_argument("--resolution", type=int, default=512)
    p.set_defaults(func=cmd_example)
    from .batch.cli import add_parser as add_batch_parser
    add_batch_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    np.set_printoptions(suppress=True)
    try:
        return args.func(args)
    except (ValueError, RuntimeError, FileNotFoundError, TypeError, ImportError) as exc:
        print(f"pycinder: error: {_strict_words(str(exc))}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

"""``pycinder demo NAME``: the paper's demos (:mod:`pycinder.demos`), as a video, a folder of
PNGs, or in a window."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

from .common import add_progress, progress


def _frames_out(text: str) -> str:
    """``demo --out``: a video or a folder (see :func:`~pycinder.demos.output.output_kind`)."""
    from ..demos.output import output_kind

    try:
        output_kind(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``demo`` command to the ``pycinder`` command's subparsers."""
    p = subparsers.add_parser("demo", help="the paper's demos, as a video or in a window: "
                                           "stairs, snow-bunny, normals")
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
    add_progress(p)
    p.set_defaults(func=cmd_demo, strict=False, json=False)
    return p


def cmd_demo(args: argparse.Namespace) -> int:
    """Run a demo: headless for ``--frames`` frames (default 120), or in a window until it is
    closed (or for ``--frames`` frames when given)."""
    from ..demos.run import run

    options = {"out": args.out, "window": args.window, "tolerance": args.tolerance,
               "seed": args.seed, "spheres": args.spheres, "scan": args.scan,
               "close_holes": args.close_holes}
    if args.window:
        run(args.name, frames=args.frames, **options)
        return 0
    frames = args.frames or 120
    enabled = args.progress if args.progress is not None else sys.stderr.isatty()
    if enabled:
        with progress(True, args.name) as update:
            run(args.name, frames=frames, progress=lambda k, n: update(k, n, args.name),
                **options)
    else:
        run(args.name, frames=frames, progress=_printed_progress(args.name), **options)
    return 0


def _printed_progress(name: str) -> Callable[[int, int], None]:
    """Progress as a line on stdout about every tenth of the frames (for logs and pipes)."""
    import time

    start = time.perf_counter()

    def printed(done: int, total: int) -> None:
        step = max(total // 10, 1)
        if done == 1 or done % step == 0 or done == total:
            print(f"{name}: frame {done}/{total}, {time.perf_counter() - start:.0f} s",
                  flush=True)

    return printed

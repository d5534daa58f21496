"""``pycinder example [--out DIR]``: the paper's three boxes checked, their buffers written, and
a labelled montage of them (Figures 9-13)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..util.text import plural
from .common import add_buffer_resolution, add_progress, progress


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``example`` command to the ``pycinder`` command's subparsers."""
    p = subparsers.add_parser("example", help="check the built-in three-box scene and write its "
                                              "buffers and a labelled montage of them "
                                              "(montage.png)")
    p.add_argument("--out", default="out/buffers", metavar="DIR",
                   help="folder for the buffers' PNGs and montage.png (created; default "
                        "out/buffers)")
    add_buffer_resolution(p)
    add_progress(p)
    p.set_defaults(func=cmd_example, strict=False, json=False)
    return p


def cmd_example(args: argparse.Namespace) -> int:
    """Check the paper's three-box scene, write its debug buffers and their montage."""
    from ..debug.montage import pillow, write_montage
    from ..debug.pass_buffers import three_boxes, write_debug_buffers
    from ..detector import Detector

    pillow()  # the montage needs it: say so before writing anything
    boxes, names, view = three_boxes()
    with progress(args.progress, "example") as update:
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

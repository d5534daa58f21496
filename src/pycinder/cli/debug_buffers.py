"""``pycinder debug-buffers [FILE...] --out DIR``: PNGs of the buffers after the paper's passes
1-7 (:mod:`pycinder.debug.pass_buffers`), of the paper's three boxes or of mesh files."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from .common import add_buffer_resolution, add_file_limits, add_progress, load_files, progress


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``debug-buffers`` command to the ``pycinder`` command's subparsers."""
    p = subparsers.add_parser("debug-buffers", help="write PNGs of the buffers after the paper's "
                                                    "passes 1-7 (three boxes, or your files)")
    p.add_argument("files", nargs="*", metavar="FILE",
                   help="meshes (default: the paper's three boxes, Figure 7)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder for the PNGs (created; files of the same names are replaced)")
    add_buffer_resolution(p)
    p.add_argument("--self-interference", default="filter",
                   choices=["filter", "prevent", "offset"],
                   help="how a body's edges are kept from registering against its own faces "
                        "(paper 4.3.1): filter (default) lets them, then blanks those pixels "
                        "before readback; prevent never counts a body's faces in front of its own "
                        "edges; offset moves edges outwards along their normals by half a pixel")
    add_file_limits(p)
    add_progress(p)
    p.set_defaults(func=cmd_debug_buffers, strict=False, json=False)
    return p


def cmd_debug_buffers(args: argparse.Namespace) -> int:
    """Write the buffers' PNGs of the files' bodies (or the three boxes) and print their paths;
    return 0."""
    from ..debug.pass_buffers import write_debug_buffers

    bodies, transforms = None, None
    if args.files:
        with progress(args.progress, "loading") as update:
            loaded = load_files(args, update)
        bodies = [b.mesh for b in loaded]
        transforms = np.array([b.transform for b in loaded])
    paths = write_debug_buffers(bodies, args.out, resolution=args.resolution,
                                self_interference=args.self_interference, transforms=transforms)
    for p in paths:
        print(p)
    return 0

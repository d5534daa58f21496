"""The ``pycinder`` command (also ``python -m pycinder``): one module per command.

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
    pycinder batch MANIFEST --out OUT [--workers N] ...

Closed meshes are tested as solids (one inside another collides), open ones as surfaces.

``check`` exits 0 when nothing collides, 1 when something does and 2 on an error. Every file is
read before an error is reported, so that one run names every bad file (each message names the
file or body and what is wrong with it); when any file cannot be used nothing is checked and the
exit status is 2. ``check --json`` prints one object, described in
:data:`pycinder.cli.check.CHECK_EPILOG`.

Each command is a module with an ``add_parser(subparsers)`` that adds its parser and sets its
handler: :mod:`.check` (and :mod:`.check_ifc` for IFC files), :mod:`.debug_buffers`,
:mod:`.demo`, :mod:`.bench`, :mod:`.example`, and :mod:`pycinder.batch.command`; what they share
is in :mod:`.common`.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

import numpy as np

from .. import __version__
from ..batch import command as batch
from . import bench, check, debug_buffers, demo, example
from .common import ERRORS, error_messages, fail

DESCRIPTION = f"""\
pycinder {__version__}: collision detection on the GPU for triangle meshes: closed meshes are
tested as solids, open ones as surfaces (CInDeR, an image-space interference test, on WebGPU)."""

EPILOG = "Run 'pycinder COMMAND --help' for a command's options."

COMMANDS = (check, debug_buffers, demo, bench, example, batch)
"""The modules of the commands, in the order ``pycinder --help`` lists them."""


def build_parser() -> argparse.ArgumentParser:
    """The ``pycinder`` command's parser, with each command's (:data:`COMMANDS`)."""
    parser = argparse.ArgumentParser(prog="pycinder", description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"pycinder {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                title="commands")
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``pycinder ARGV`` (default: the process's arguments) and return its exit status."""
    args = build_parser().parse_args(argv)
    np.set_printoptions(suppress=True)
    try:
        return args.func(args)
    except BrokenPipeError:  # the reader went away (``pycinder check ... | head``)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except ERRORS as exc:
        return fail(args, error_messages(exc), [])

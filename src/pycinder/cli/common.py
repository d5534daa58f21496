"""What the commands of ``pycinder`` share: their errors and warnings in the command line's words,
progress bars, the files' limits and loading, and the types and groups of common options."""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import sys
import warnings
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np

from ..files import (DEFAULT_MAX_BYTES, DEFAULT_MAX_TRIANGLES, FileBody, Limits, human_bytes,
                     parse_size)

ERRORS = (ValueError, RuntimeError, OSError, TypeError, ImportError, MemoryError)
"""What a command reports as an error (exit status 2) rather than a traceback."""


def cli_words(message: str, strict: bool) -> str:
    """Library messages name the library's options; on the command line they are flags
    (--strategy, --tolerance, --resolution, --min-depth, --clearance, --strict), and under
    --strict the advice to pass it is dropped."""
    message = re.sub(r"\bstrategy='(\w+)'", r"--strategy \1", message)
    message = re.sub(r"^(tolerance|resolution|clearance)\b", r"--\1", message)
    message = re.sub(r"\bmin_depth\b", "--min-depth", message)
    if strict:
        return re.sub(r",?\s*or ask for strict checking to make this an error", "", message)
    return message.replace("ask for strict checking", "pass --strict")


def warning_entry(w: warnings.WarningMessage, strict: bool) -> dict[str, Any]:
    """A caught warning as an entry of the JSON's ``warnings``: its category and message (in
    the command line's words), and its ``bodies``, ``details`` and ``summary`` where it has
    them."""
    return {"category": w.category.__name__, "message": cli_words(str(w.message), strict),
            **{k: getattr(w.message, k) for k in ("bodies", "details", "summary")
               if hasattr(w.message, k)}}


def error_messages(exc: BaseException) -> list[str]:
    """An error's messages: one per bad file for :class:`~pycinder.files.FileErrors`."""
    return list(getattr(exc, "messages", None) or [str(exc) or type(exc).__name__])


def fail(args: argparse.Namespace, messages: Sequence[str], caught: list) -> int:
    """Report errors, one per bad file or problem (with the warnings before them), and return
    exit status 2."""
    errors = [cli_words(m, args.strict) for m in messages]
    notes = [warning_entry(w, args.strict) for w in caught]
    if args.json:
        print(json.dumps({"collision": None, "pairs": [], "warnings": notes,
                          "errors": errors}, indent=2))
    else:
        for note in notes:
            print(f"warning: {note['message']}", file=sys.stderr)
        for message in errors:
            print(f"pycinder: error: {message}", file=sys.stderr)
    return 2


@contextlib.contextmanager
def progress(enabled: bool | None, description: str
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


def file_limits(args: argparse.Namespace) -> Limits:
    """The files' limits of ``--max-file-size`` and ``--max-triangles``."""
    return Limits(max_bytes=args.max_file_size, max_triangles=args.max_triangles)


def load_files(args: argparse.Namespace, update: Callable[[int, int, str], None]
               ) -> list[FileBody]:
    """The files' bodies; with ``--split`` each body's disconnected components as bodies."""
    from ..files import load_bodies, split_components

    steps = len(args.files) + 1
    bodies = load_bodies(args.files, file_limits(args),
                         progress=lambda k, n, label: update(k, steps, f"loading {label}"))
    return split_components(bodies) if getattr(args, "split", False) else bodies


_MODE_FLAGS = {"min_depth": "--min-depth", "clearance": "--clearance"}


def query_mode(args: argparse.Namespace) -> tuple[str, dict[str, float]]:
    """``check``'s query mode ("default", "min_depth", "clearance") and the options that ask
    for it (:func:`pycinder.bim.ifc.mode_options`, in the command line's words)."""
    from ..bim.ifc import mode_options

    try:
        return mode_options(getattr(args, "min_depth", None), getattr(args, "clearance", None))
    except ValueError as exc:
        message = str(exc).replace("min_depth and clearance", "--min-depth and --clearance")
        for name, flag in _MODE_FLAGS.items():
            message = message.replace(f"{name} must", f"{flag} must")
        raise ValueError(message) from None


# -- option types and groups ----------------------------------------------------------------


def file_size(text: str) -> int:
    """``--max-file-size``: a size in bytes, e.g. ``2G`` (:func:`~pycinder.files.parse_size`)."""
    try:
        return parse_size(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def positive_distance(text: str) -> float:
    """``--min-depth``, ``--clearance``: a finite distance above 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not np.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a positive distance")
    return value


def positive_count(text: str) -> int:
    """A whole number above 0, with ``_`` or ``,`` between its digits allowed (``10_000``)."""
    try:
        value = int(text.replace("_", "").replace(",", ""))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a positive number")
    return value


def add_file_limits(p: argparse.ArgumentParser) -> None:
    """Add ``--max-file-size`` and ``--max-triangles``."""
    p.add_argument("--max-file-size", type=file_size, default=DEFAULT_MAX_BYTES, metavar="SIZE",
                   help="largest file (and 3MF contents, glTF buffers) to load, e.g. 2G "
                        f"(default {human_bytes(DEFAULT_MAX_BYTES)})")
    p.add_argument("--max-triangles", type=positive_count, default=DEFAULT_MAX_TRIANGLES,
                   metavar="N",
                   help=f"most triangles a file may hold (default {DEFAULT_MAX_TRIANGLES:,})")


def add_buffer_resolution(p: argparse.ArgumentParser) -> None:
    """Add ``--resolution`` of the buffers ``debug-buffers`` and ``example`` write."""
    p.add_argument("--resolution", type=positive_count, default=512, metavar="N",
                   help="width and height in pixels of the scene strategy's image whose buffers "
                        "are written (default 512)")


def add_progress(p: argparse.ArgumentParser) -> None:
    """Add ``--progress``/``--no-progress``."""
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="show a progress bar on stderr (default: when it is a terminal)")

"""``pycinder batch MANIFEST --out OUT``: the scenes of a manifest on Ray workers.

    pycinder batch MANIFEST --out OUT [--workers N] [--address ADDR] [--tolerance T]
                   [--batch-size B] [--unordered] [--strict] [--retry-errors]

MANIFEST is JSON lines, one scene a line (:mod:`.manifest`), or a robot manifest: one JSON object
naming a URDF, an SRDF and a configurations file (:mod:`.robot_run`: one row per configuration,
checked in this process, or on Ray workers with ``--workers`` above 1 or ``--address``:
:mod:`.robot_ray`); OUT gets one row a line (the rows
of :func:`pycinder.batch.run`), or Parquet when it ends in ``.parquet`` (:mod:`.sink`). Run again
with the same OUT to resume: the ids already there are skipped. A resumed run does not hide the
errors OUT already holds: it says how many of the manifest's scenes failed before, and its exit
status counts them; ``--retry-errors`` runs those scenes again. The exit status (:data:`EPILOG`):

- 0: every scene of MANIFEST has an ``"ok"`` row in OUT;
- 1: some have error rows in OUT, written by this run or by an earlier one;
- 2: the run could not be made (a bad manifest or option, Ray or pyarrow missing);
- 130: interrupted (the rows so far are in OUT: the same command goes on).
"""

from __future__ import annotations

import argparse
import sys
from contextlib import nullcontext
from pathlib import Path
from typing import Any

from .manifest import id_key, read_manifest

EPILOG = """\
OUT holds one row per scene (JSON lines; in Parquet, one column per key, stats as JSON text):
  checked:  {"id": ID, "status": "ok", "pairs": [[i, j], ...], "names": [[a, b], ...],
             "stats": {"bodies", "attempt", "worker", "query_scenes", "query_ms", ...}}
  failed:   {"id": ID, "status": "error", "error": "Type: message naming the scene and body",
             "error_kind": "input" | "query" | "worker", "attempts": N}
A scene's own bad input (error_kind input: a mesh file missing or unreadable, NaN vertices, a
singular transform) is written at once; a failed query or a dead worker is tried --attempts
times.

exit status:
  0    every scene of MANIFEST has an "ok" row in OUT
  1    some scenes have error rows in OUT: failed in this run, or in an earlier run into the
       same OUT (a resumed run says how many; --retry-errors runs them again)
  2    no run: a bad manifest or option, Ray or pyarrow missing
  130  interrupted: the rows so far are in OUT; the same command goes on"""
"""The ``batch`` command's help after its options: the rows of OUT and the exit status."""


BATCH_SIZE = 64
"""Scenes per GPU query of a scene manifest when ``--batch-size`` is not given."""
ATTEMPTS = 2
"""Tries per scene of a scene manifest when ``--attempts`` is not given."""

SCENE_OPTIONS = {
    "batch_size": "--batch-size (scenes per query: a robot manifest's configurations per query "
                  "are --robot-batch)",
    "attempts": "--attempts (a robot manifest's run stops at a failed query; on Ray a dead "
                "worker's chunk is run again by Ray itself)",
    "unordered": "--unordered (a robot manifest's rows are written in configuration order)",
}
"""Options of a scene manifest's run that a robot manifest refuses, and why."""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``batch`` command to the ``pycinder`` command's subparsers."""
    p = subparsers.add_parser(
        "batch", help="check the scenes of a JSON-lines manifest on Ray workers (local by "
                      "default, a cluster with --address); resumes into the same OUT",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("manifest", metavar="MANIFEST",
                   help='JSON lines: {"id": ..., "tolerance": t, "bodies": [{"mesh": path, '
                        '"transform": 4x4, "name": ...}, ...]}; or a robot manifest (a .json '
                        'object): {"robot": URDF, "srdf": SRDF, "configurations": NPY or '
                        'Parquet, "environment": [...]}; paths relative to its folder')
    p.add_argument("--robot-batch", type=int, default=None, metavar="C",
                   help="a robot manifest's configurations per query (default: sized by "
                        "pycinder.robot)")
    p.add_argument("--out", required=True, metavar="OUT",
                   help="results as JSON lines, or Parquet when OUT ends in .parquet")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes, each with one detector (default: one per GPU, or 1; "
                        "a robot manifest runs in this process unless N is above 1 or "
                        "--address is given)")
    p.add_argument("--address", default=None, metavar="ADDR",
                   help="a Ray cluster to connect to (default: start a local one)")
    p.add_argument("--gpus-per-worker", type=float, default=None, metavar="G",
                   help="GPUs per worker (default: 1 where the cluster has GPUs, else 0)")
    p.add_argument("--tolerance", type=float, default=None, metavar="T",
                   help="world units, for scenes (or a robot manifest) that give none (default: "
                        "1%% of the smaller body of each pair)")
    p.add_argument("--batch-size", type=int, default=None, metavar="B",
                   help=f"scenes per GPU query (default {BATCH_SIZE}; 1: a query per scene); a "
                        "robot manifest's is --robot-batch")
    p.add_argument("--attempts", type=int, default=None,
                   help="tries per scene whose worker died or whose query failed, before its "
                        f"error is written (default {ATTEMPTS}); bad input is written at once")
    p.add_argument("--unordered", action="store_true",
                   help="write results as they complete rather than in manifest order")
    p.add_argument("--strict", action="store_true",
                   help="open, inside-out and zero-area meshes fail their scenes (a robot "
                        "manifest's: fail the run)")
    p.add_argument("--retry-errors", action="store_true",
                   help="run again the scenes whose errors OUT already holds (without it, a "
                        "resumed run keeps them, says so, and exits 1)")
    p.set_defaults(func=cmd_batch, strict=False, json=False)
    return p


def robot_options(args: argparse.Namespace) -> dict[str, Any]:
    """What the command's options ask of a robot manifest's run: every option applies, or is
    refused with a ``ValueError`` naming it (never silently ignored).

    Returns
    -------
    dict
        ``tolerance`` (for a manifest that gives none) and ``strict``, for
        :func:`~pycinder.batch.robot_run.run_robot`.
    """
    given = [why for name, why in SCENE_OPTIONS.items()
             if getattr(args, name) not in (None, False)]
    if given:
        raise ValueError("a robot manifest does not take " + "; ".join(given))
    return {"tolerance": args.tolerance, "strict": args.strict}


def _progress(total: int) -> Any:
    """A rich progress bar for ``total`` scenes, or None without rich."""
    try:
        from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                                   TimeElapsedColumn, TimeRemainingColumn)
    except ImportError:  # pragma: no cover - rich comes with the cluster extra
        return None
    return Progress(TextColumn("batch"), BarColumn(), MofNCompleteColumn(),
                    TextColumn("{task.fields[rate]:.1f} scenes/s, {task.fields[failed]} failed"),
                    TimeElapsedColumn(), TimeRemainingColumn())


def _count(n: int, word: str) -> str:
    """``1 worker``, ``2 workers``."""
    return f"{n} {word}{'' if n == 1 else 's'}"


def cmd_batch(args: argparse.Namespace) -> int:
    """Run ``pycinder batch``: the manifest's scenes not yet in OUT, their rows into OUT.

    Returns
    -------
    int
        The exit status (:data:`EPILOG`): 0 when every scene of the manifest has an ``"ok"`` row
        in OUT, 1 when some have error rows (this run's or an earlier run's that it kept), 130
        when interrupted. A run that cannot be made raises (the ``pycinder`` command exits 2).
    """
    from .ray_run import run
    from .robot_run import is_robot_manifest, run_robot
    from .sink import open_sink

    manifest = Path(args.manifest)
    if is_robot_manifest(manifest):  # one JSON object naming a URDF and its configurations
        return run_robot(manifest, args.out, batch=args.robot_batch,
                         retry_errors=args.retry_errors, workers=args.workers,
                         address=args.address, gpus_per_worker=args.gpus_per_worker,
                         **robot_options(args))
    if args.robot_batch is not None:
        raise ValueError("--robot-batch is a robot manifest's configurations per query; "
                         f"{manifest.name} is a scene manifest (its scenes per query: "
                         "--batch-size)")
    sink = open_sink(args.out, retry_errors=args.retry_errors)
    try:
        total = skipped = earlier = 0
        for entry in read_manifest(manifest):  # every line checked before the run starts
            total += 1
            key = id_key(entry["id"])
            skipped += key in sink.done
            earlier += key in sink.failed
        if sink.repaired:
            print(f"{args.out}: dropped {sink.repaired} torn, repeated or retried lines",
                  file=sys.stderr)
        kept = f"; {earlier} of them failed before" if earlier else ""
        if earlier:
            print(f"{args.out}: {_count(earlier, 'scene')} of the manifest failed in an earlier "
                  "run (their errors are in it); run with --retry-errors to run them again",
                  file=sys.stderr)
        if total == skipped:
            print(f"{args.out}: all {total} scenes already there{kept}, nothing to do")
            return 1 if earlier else 0
        todo = (e for e in read_manifest(manifest) if id_key(e["id"]) not in sink.done)
        bar = _progress(total - skipped)
        with bar if bar is not None else nullcontext():
            task = bar.add_task("batch", total=total - skipped, rate=0.0, failed=0) \
                if bar is not None else None
            with run(todo, workers=args.workers, address=args.address,
                     gpus_per_worker=args.gpus_per_worker, tolerance=args.tolerance,
                     ordered=not args.unordered,
                     batch_size=BATCH_SIZE if args.batch_size is None else args.batch_size,
                     attempts=ATTEMPTS if args.attempts is None else args.attempts,
                     strict=args.strict,
                     base=str(manifest.resolve().parent)) as results:
                for result in results:
                    sink.write(result)
                    if bar is not None:
                        bar.update(task, advance=1, rate=results.summary["scenes_per_s"],
                                   failed=results.summary["failed"])
    except KeyboardInterrupt:
        print(f"interrupted: the results so far are in {args.out}; run the same command again "
              "to go on", file=sys.stderr)
        return 130
    finally:
        sink.close()
    s = results.summary
    print(f"{_count(s['scenes'], 'scene')} in {s['seconds']:.1f} s, wall time "
          f"({s['startup_seconds']:.1f} s of it starting Ray and "
          f"{_count(s['workers'], 'worker')} on {s['adapter']}): {s['scenes_per_s']:.1f} "
          f"scenes/s once ready, {s['batch_size']} per query; {s['failed']} failed, "
          f"{s['retried']} retried, {_count(s['worker_failures'], 'worker failure')}; "
          f"{skipped} already in {args.out}{kept}")
    return 1 if s["failed"] or earlier else 0

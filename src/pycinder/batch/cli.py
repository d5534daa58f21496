"""``pycinder batch MANIFEST --out OUT``: the scenes of a manifest on Ray workers.

    pycinder batch MANIFEST --out OUT [--workers N] [--address ADDR] [--tolerance T]
                   [--batch-size B] [--unordered] [--strict] [--retry-errors]
        exit 0: every scene checked; 1: some scenes failed (their errors are in OUT); 2: error

MANIFEST is JSON lines, one scene a line (:mod:`.manifest`); OUT gets one result a line, or
Parquet when it ends in ``.parquet`` (:mod:`.sink`). Run again with the same OUT to resume: the
ids already there are skipped.
"""

from __future__ import annotations

import argparse
import sys
from contextlib import nullcontext
from pathlib import Path
from typing import Any

from .manifest import id_key, read_manifest


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``batch`` command to the ``pycinder`` command's subparsers."""
    p = subparsers.add_parser(
        "batch", help="check the scenes of a JSON-lines manifest on Ray workers (local by "
                      "default, a cluster with --address); resumes into the same OUT")
    p.add_argument("manifest", metavar="MANIFEST",
                   help='JSON lines: {"id": ..., "tolerance": t, "bodies": [{"mesh": path, '
                        '"transform": 4x4, "name": ...}, ...]}; paths relative to its folder')
    p.add_argument("--out", required=True, metavar="OUT",
                   help="results as JSON lines, or Parquet when OUT ends in .parquet")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes, each with one detector (default: one per GPU, or 1)")
    p.add_argument("--address", default=None, metavar="ADDR",
                   help="a Ray cluster to connect to (default: start a local one)")
    p.add_argument("--gpus-per-worker", type=float, default=None, metavar="G",
                   help="GPUs per worker (default: 1 where the cluster has GPUs, else 0)")
    p.add_argument("--tolerance", type=float, default=None, metavar="T",
                   help="world units, for scenes that give none (default: 1%% of the smaller "
                        "body of each pair)")
    p.add_argument("--batch-size", type=int, default=64, metavar="B",
                   help="scenes per GPU query (default 64; 1: a query per scene)")
    p.add_argument("--attempts", type=int, default=2,
                   help="tries per scene before its error is written (default 2)")
    p.add_argument("--unordered", action="store_true",
                   help="write results as they complete rather than in manifest order")
    p.add_argument("--strict", action="store_true",
                   help="open, inside-out and zero-area meshes fail their scenes")
    p.add_argument("--retry-errors", action="store_true",
                   help="run again the scenes whose errors OUT already holds")
    p.set_defaults(func=cmd_batch, strict=False, json=False)
    return p


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


def cmd_batch(args: argparse.Namespace) -> int:
    from .ray_run import run
    from .sink import open_sink

    manifest = Path(args.manifest)
    sink = open_sink(args.out, retry_errors=args.retry_errors)
    try:
        total = skipped = 0
        for entry in read_manifest(manifest):  # every line checked before the run starts
            total += 1
            skipped += id_key(entry["id"]) in sink.done
        if sink.repaired:
            print(f"{args.out}: dropped {sink.repaired} torn, repeated or retried lines",
                  file=sys.stderr)
        if total == skipped:
            print(f"{args.out}: all {total} scenes already there, nothing to do")
            return 0
        todo = (e for e in read_manifest(manifest) if id_key(e["id"]) not in sink.done)
        bar = _progress(total - skipped)
        with bar if bar is not None else nullcontext():
            task = bar.add_task("batch", total=total - skipped, rate=0.0, failed=0) \
                if bar is not None else None
            with run(todo, workers=args.workers, address=args.address,
                     gpus_per_worker=args.gpus_per_worker, tolerance=args.tolerance,
                     ordered=not args.unordered, batch_size=args.batch_size,
                     attempts=args.attempts, strict=args.strict,
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
    print(f"{s['scenes']} scenes in {s['seconds']:.1f} s: {s['scenes_per_s']:.1f} scenes/s on "
          f"{s['workers']} worker{'s' if s['workers'] != 1 else ''} ({s['adapter']}), {s['batch_size']} scenes per query; "
          f"{s['failed']} failed, {s['retried']} retried, {s['worker_failures']} worker "
          f"failures; {skipped} already in {args.out}")
    return 1 if s["failed"] else 0

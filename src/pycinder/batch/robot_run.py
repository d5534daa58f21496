"""``pycinder batch ROBOT.json --out OUT``: a robot's configurations, one row each, resumable.

ROBOT.json is a robot manifest (:mod:`.robot_manifest`: one JSON object naming a URDF, its
configurations and optionally an SRDF and an environment).

OUT gets one row per configuration, in order, written as each batch of configurations is
checked (:mod:`.sink`: JSON lines, or Parquet when OUT ends in ``.parquet``)::

    {"id": 17, "status": "ok", "collides": true, "names": [["panda_link2", "table"]]}

``id`` is the configuration's row in the configurations file; ``names`` its colliding pairs of
names (links, environment bodies), each pair sorted.

Run again with the same OUT to go on: the configurations already there are skipped. The run is
in this process, on one detector (configurations are batched into queries already), or, with
``--workers N`` (N above 1) or ``--address``, on Ray workers (:mod:`.robot_ray`), each checking
chunks of configurations with the robot loaded once.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from .robot_manifest import (check_rows, is_robot_manifest, load_configurations, load_robot,
                             read_robot_manifest)

CHUNK = 1000
"""Configurations per chunk when no batch is given: rows are written (and a run resumable)
every chunk, and a Ray worker is given one chunk at a time."""


def run_robot(manifest: str | Path, out: str | Path, *, batch: int | None = None,
              retry_errors: bool = False, quiet: bool = False, workers: int | None = None,
              address: str | None = None, gpus_per_worker: float | None = None,
              tolerance: float | None = None, strict: bool = False) -> int:
    """Check every configuration of a robot manifest not yet in ``out``; rows into ``out``.

    In this process, on one detector; on Ray workers (:mod:`.robot_ray`) when ``workers`` is
    more than one or ``address`` names a cluster: each worker (``gpus_per_worker`` GPUs each,
    by default one where the cluster has GPUs) loads the robot once and checks chunks of
    :data:`CHUNK` configurations (or ``batch``, when larger), and the rows are written in order.
    ``tolerance``: the checks' where the manifest gives none; ``strict``: open, inside-out and
    zero-area meshes are errors (as the manifest's ``strict``).

    Returns
    -------
    int
        The exit status of ``pycinder batch``: 0 when every configuration has a row (they are
        all ``"ok"``: a robot manifest's errors are the run's, raised before it starts), 130
        when interrupted.
    """
    from .manifest import id_key
    from .sink import open_sink

    spec = read_robot_manifest(manifest)
    if spec.get("tolerance") is None and tolerance is not None:
        spec["tolerance"] = tolerance
    spec["strict"] = bool(spec.get("strict")) or strict
    robot, env = load_robot(spec, manifest)
    q = load_configurations(spec["configurations"], robot.joint_names)
    on_ray = (workers is not None and workers > 1) or address is not None
    sink = open_sink(out, retry_errors=retry_errors)
    todo = np.array([c for c in range(len(q)) if id_key(c) not in sink.done], dtype=np.int64)
    t0 = time.perf_counter()
    how = "in this process"
    try:
        # Rows are written (and the run resumable) every this many configurations; on Ray,
        # every chunk (at least CHUNK).
        size = batch or CHUNK
        if on_ray and len(todo):
            from .robot_ray import RobotRun

            with RobotRun(spec, q, todo, workers=workers, address=address,
                          gpus_per_worker=gpus_per_worker, chunk=max(size, CHUNK),
                          batch=batch) as run:
                how = f"on {run.workers} Ray workers"
                for row in run:
                    sink.write(row)
        else:
            for start in range(0, len(todo), size):
                which = todo[start:start + size]
                for row in check_rows(robot, env, spec, which, q[which], batch):
                    sink.write(row)
    except KeyboardInterrupt:
        print(f"interrupted: the results so far are in {out}; run the same command again "
              "to go on", file=sys.stderr)
        return 130
    finally:
        sink.close()
    if not quiet:
        seconds = time.perf_counter() - t0
        print(f"{len(todo)} configurations of {robot.name} in {seconds:.1f} s "
              f"({len(todo) / max(seconds, 1e-9):.1f}/s, {how}); {len(q) - len(todo)} already "
              f"in {out}")
    return 0


__all__ = ["CHUNK", "is_robot_manifest", "load_configurations", "read_robot_manifest",
           "run_robot"]

"""``pycinder batch ROBOT.json --out OUT``: a robot's configurations, one row each, resumable.

A robot manifest is one JSON object (a file ending in ``.json``, not JSON lines)::

    {"robot": "panda.urdf", "srdf": "panda.srdf", "configurations": "samples.npy",
     "environment": [{"mesh": "table.stl", "transform": [[1, 0, 0, 0.4], ...], "name": "table"}],
     "tolerance": 0.001, "package_dirs": ["meshes"], "self_collision": true}

``robot`` (a URDF) and ``configurations`` are required: an NPY file of (C, J) joint values, or a
Parquet file with a column per actuated joint (named as the URDF names them) or J numeric
columns in order. ``srdf`` (its ``<disable_collisions>`` pairs are honoured as given),
``environment``, ``tolerance``, ``package_dirs`` and ``self_collision`` are optional; paths are
relative to the manifest's folder.

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

import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from ..util.optional import require

KEYS = {"robot", "srdf", "configurations", "environment", "tolerance", "package_dirs",
        "self_collision"}

CHUNK = 1000
"""Configurations per chunk when no batch is given: rows are written (and a run resumable)
every chunk, and a Ray worker is given one chunk at a time."""


def is_robot_manifest(path: str | Path) -> bool:
    """Whether ``path`` is a robot manifest: a ``.json`` file holding one object with a
    ``robot`` key."""
    path = Path(path)
    if path.suffix != ".json" or not path.is_file():
        return False
    try:
        data = json.loads(path.read_text())
    except ValueError:
        return False
    return isinstance(data, dict) and "robot" in data


def read_robot_manifest(path: str | Path) -> dict[str, Any]:
    """The robot manifest's fields, checked, paths resolved against its folder.

    Raises
    ------
    ValueError
        An unknown key, or a missing or bad one, naming the manifest.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except ValueError as exc:
        raise ValueError(f"{path}: not a JSON object: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a robot manifest is one JSON object")
    unknown = sorted(set(data) - KEYS)
    if unknown:
        raise ValueError(f"{path}: unknown keys {unknown}; a robot manifest has "
                         f"{sorted(KEYS)}")
    for key in ("robot", "configurations"):
        if not isinstance(data.get(key), str):
            raise ValueError(f"{path}: {key!r} must name a file")
    base = path.resolve().parent
    out = dict(data)
    for key in ("robot", "srdf", "configurations"):
        if isinstance(out.get(key), str):
            out[key] = base / out[key]
    dirs = out.get("package_dirs")
    if isinstance(dirs, str):
        out["package_dirs"] = [base / dirs]
    elif isinstance(dirs, list):
        out["package_dirs"] = [base / d for d in dirs]
    elif isinstance(dirs, dict):
        out["package_dirs"] = {k: base / v for k, v in dirs.items()}
    env = out.get("environment") or []
    if not isinstance(env, list):
        raise ValueError(f"{path}: environment must be a list of bodies")
    for k, body in enumerate(env):
        if not isinstance(body, dict) or not isinstance(body.get("mesh"), str):
            raise ValueError(f"{path}: environment body {k} needs a mesh path")
        body["mesh"] = base / body["mesh"]
    out["environment"] = env
    if not isinstance(out.get("self_collision", True), bool):
        raise ValueError(f"{path}: self_collision must be true or false")
    return out


def load_configurations(path: Path, joint_names: list[str]) -> np.ndarray:
    """(C, J) joint values from an NPY or Parquet file (see the module's doc)."""
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such configurations file")
    if path.suffix == ".parquet":
        pq = require("pyarrow.parquet", f"{path.name}: reading Parquet", "cluster", "pyarrow")
        table = pq.read_table(path)
        if all(n in table.column_names for n in joint_names):
            cols = joint_names
        else:
            cols = [n for n, t in zip(table.column_names, table.schema.types)
                    if str(t) in ("double", "float", "int64", "int32")]
        q = np.stack([table.column(c).to_numpy().astype(np.float64) for c in cols], axis=1) \
            if cols else np.zeros((table.num_rows, 0))
    else:
        q = np.load(path, allow_pickle=False)
    q = np.asarray(q, np.float64)
    if q.ndim != 2 or q.shape[1] != len(joint_names):
        raise ValueError(f"{path.name}: configurations must be (C, {len(joint_names)}) joint "
                         f"values ({', '.join(joint_names)}), got shape {q.shape}")
    return q


def load_robot(spec: dict[str, Any], where: str | Path) -> tuple[Any, Any]:
    """The robot and environment (None when it has no bodies) of a checked manifest ``spec``
    (:func:`read_robot_manifest`), loaded from its files; ``where`` names it in errors."""
    from ..robot import Environment, Robot

    robot = Robot.from_urdf(spec["robot"], srdf=spec.get("srdf"),
                            package_dirs=spec.get("package_dirs"),
                            tolerance=spec.get("tolerance"))
    if not spec["environment"]:
        return robot, None
    import trimesh

    env = Environment()
    for k, body in enumerate(spec["environment"]):
        try:
            mesh = trimesh.load(body["mesh"], force="mesh")
        except Exception as exc:
            raise ValueError(f"{where}: environment body {k} ({Path(body['mesh']).name}): "
                             f"{exc}") from None
        env.add(body.get("name") or Path(body["mesh"]).stem, mesh, body.get("transform"))
    return robot, env


def check_rows(robot: Any, environment: Any, spec: dict[str, Any], ids: np.ndarray,
               q: np.ndarray, batch: int | None) -> list[dict[str, Any]]:
    """The rows of configurations ``q`` (C, J), numbered ``ids`` (C,), checked as the manifest
    ``spec`` says (in this process, or in a Ray worker: :mod:`.robot_ray`)."""
    collides, pairs = robot.check(q, environment=environment, return_pairs=True,
                                  self_collision=spec.get("self_collision", True), batch=batch)
    return [{"id": c, "status": "ok", "collides": hit, "names": [list(x) for x in p]}
            for c, hit, p in zip(np.asarray(ids).tolist(), collides.tolist(), pairs)]


def run_robot(manifest: str | Path, out: str | Path, *, batch: int | None = None,
              retry_errors: bool = False, quiet: bool = False, workers: int | None = None,
              address: str | None = None) -> int:
    """Check every configuration of a robot manifest not yet in ``out``; rows into ``out``.

    In this process, on one detector; on Ray workers (:mod:`.robot_ray`) when ``workers`` is
    more than one or ``address`` names a cluster: each worker loads the robot once and checks
    chunks of configurations, and the rows are written in order.

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
    robot, env = load_robot(spec, manifest)
    q = load_configurations(spec["configurations"], robot.joint_names)
    on_ray = (workers is not None and workers > 1) or address is not None
    sink = open_sink(out, retry_errors=retry_errors)
    todo = np.array([c for c in range(len(q)) if id_key(c) not in sink.done], dtype=np.int64)
    t0 = time.perf_counter()
    how = "in this process"
    try:
        size = batch or CHUNK  # rows written (and resumable) every this many configurations
        if on_ray:
            from .robot_ray import RobotRun

            with RobotRun(spec, q, todo, workers=workers, address=address, chunk=size,
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

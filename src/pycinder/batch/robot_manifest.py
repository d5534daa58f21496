"""A robot manifest: its fields, its configurations, its robot and its rows
(:mod:`.robot_run` runs one in this process, :mod:`.robot_ray` on Ray workers).

A robot manifest is one JSON object (a file ending in ``.json``, not JSON lines)::

    {"robot": "panda.urdf", "srdf": "panda.srdf", "configurations": "samples.npy",
     "environment": [{"mesh": "table.stl", "transform": [[1, 0, 0, 0.4], ...], "name": "table"}],
     "tolerance": 0.001, "package_dirs": ["meshes"], "self_collision": true, "strict": false}

``robot`` (a URDF) and ``configurations`` are required: an NPY file of (C, J) joint values, or a
Parquet file with a column per actuated joint (named as the URDF names them) or J numeric
columns in order. ``srdf`` (its ``<disable_collisions>`` pairs are honoured as given),
``environment``, ``tolerance``, ``package_dirs``, ``self_collision`` and ``strict`` (open,
inside-out and zero-area meshes are errors) are optional; paths are relative to the manifest's
folder. ``pycinder batch --tolerance`` gives a manifest without a ``tolerance`` one, and
``--strict`` makes any manifest strict. A row::

    {"id": 17, "status": "ok", "collides": true, "names": [["panda_link2", "table"]]}
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..util.optional import require

KEYS = {"robot", "srdf", "configurations", "environment", "tolerance", "package_dirs",
        "self_collision", "strict"}


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
    for key in ("self_collision", "strict"):
        if not isinstance(out.get(key, key == "self_collision"), bool):
            raise ValueError(f"{path}: {key} must be true or false")
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

    detector = None
    if spec.get("strict"):
        from ..detector import Detector
        from ..robot.robot import CHECK_OPTIONS

        detector = Detector(**CHECK_OPTIONS, strict=True)
    robot = Robot.from_urdf(spec["robot"], srdf=spec.get("srdf"),
                            package_dirs=spec.get("package_dirs"),
                            tolerance=spec.get("tolerance"), detector=detector)
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


__all__ = ["KEYS", "check_rows", "is_robot_manifest", "load_configurations", "load_robot",
           "read_robot_manifest"]

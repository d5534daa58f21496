"""Robots for the robot tests: the benchmark's four robots loaded quietly, MoveIt's adjacent
links allowed, and a Panda manifest for ``pycinder batch``."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import trimesh

from pycinder.testing import robots as R
from pycinder.robot import AllowedCollisionMatrix, Robot

TABLE_PLACE = np.array([[1.0, 0.0, 0.0, 0.35], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, -0.035],
                        [0.0, 0.0, 0.0, 1.0]])
"""Where the manifests' table (a 1.5 x 1.0 x 0.05 box) stands under the Panda."""


def load_robots() -> dict[str, Robot]:
    """The benchmark's four robots (open meshes and yourdfpy's notes on table.urdf unsaid)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {name: R.load(name) for name in R.ROBOTS}


def adjacent_only(robot: Robot) -> AllowedCollisionMatrix:
    """MoveIt's adjacent links of ``robot``, allowed; every other pair checked."""
    return AllowedCollisionMatrix((a, b, "Adjacent") for a, b in robot.adjacent_links())


def write_panda_manifest(folder: Path, panda: Robot, q: np.ndarray) -> tuple[Path, trimesh.Trimesh]:
    """A robot manifest in ``folder``: the Panda with its adjacent links allowed (an SRDF),
    configurations ``q`` (an NPY file) and a table (an STL file at :data:`TABLE_PLACE`);
    returns its path and the table."""
    panda.allowed = adjacent_only(panda)
    panda.write_srdf(folder / "panda.srdf")
    np.save(folder / "q.npy", q)
    table = trimesh.creation.box((1.5, 1.0, 0.05))
    table.export(folder / "table.stl")
    manifest = folder / "robot.json"
    manifest.write_text(json.dumps({
        "robot": str(R.data_path() / R.ROBOTS["panda"]), "srdf": "panda.srdf",
        "configurations": "q.npy",
        "environment": [{"mesh": "table.stl", "transform": TABLE_PLACE.tolist(),
                         "name": "table"}]}))
    return manifest, table

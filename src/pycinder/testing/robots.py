"""Robots of the benchmarks and tests: pybullet_data's arms and a quadruped with their
environments, python-fcl's answers with the same allowed-collision matrix, and exact scoring.

* :func:`load`: the Franka Panda, KUKA iiwa, xArm 6 and Unitree A1 of ``pybullet_data`` (the
  ``bench`` extra brings pybullet) as :class:`pycinder.robot.Robot`, meshes as they are (open
  ones tested as surfaces);
* :func:`environment`: pybullet_data's table (and tray, for the arms) placed around each;
* :func:`with_environment`: both, the robot with MoveIt's matrix from samples where asked;
* :class:`FclRobot`: python-fcl's ``DynamicAABBTreeCollisionManager`` over the same bodies, its
  broad phase's candidates filtered by the same pairs to check before the narrow phase (as
  MoveIt's FCL checker consults its matrix);
* :class:`TrimeshRobot`: trimesh's ``CollisionManager`` over the same bodies, its pairs kept
  where the matrix checks them (it has no matrix of its own);
* :func:`exact_verdict`: where two answers differ, what exact geometry says of the pair in the
  terms of the tolerance contract.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from ..robot import Body, Environment, Robot
from ..robot.robot import _owner
from ..util.optional import require
from . import crosses_deeply, ground_truth, mesh_pair_tolerances, surface_distance

ROBOTS = {
    "panda": "franka_panda/panda.urdf",
    "kuka": "kuka_iiwa/model.urdf",
    "xarm": "xarm/xarm6_robot.urdf",
    "a1": "a1/a1.urdf",
}
"""The benchmark's robots: name -> URDF under ``pybullet_data.getDataPath()``."""

TABLE_TOP = {"panda": -0.01, "kuka": -0.01, "xarm": -0.01, "a1": -0.3}
"""Height of the table's top below each robot's root (the arms stand on it, 1 cm clear; the
quadruped's trunk is held 30 cm above it, its legs reaching down into it)."""


def data_path() -> Path:
    """pybullet_data's folder (the ``bench`` extra)."""
    data = require("pybullet_data", "the robot benchmark's robots", "bench", "pybullet")
    return Path(data.getDataPath())


def load(name: str, **options: Any) -> Robot:
    """One of :data:`ROBOTS` as a :class:`~pycinder.robot.Robot` (``options``: those of
    :meth:`~pycinder.robot.Robot.from_urdf`)."""
    if name not in ROBOTS:
        raise ValueError(f"robot must be one of {', '.join(ROBOTS)}; got {name!r}")
    return Robot.from_urdf(data_path() / ROBOTS[name], **options)


def environment(name: str) -> Environment:
    """pybullet_data's table under robot ``name``, its top :data:`TABLE_TOP` below the root,
    and for the arms its tray on the table 0.55 m in front."""
    data = data_path()
    top = TABLE_TOP[name]
    place = np.eye(4)
    place[:3, 3] = (0.35, 0.0, top - 0.625)  # the table's top is 0.625 above its origin
    env = Environment.from_urdf(data / "table" / "table.urdf", place, prefix="table")
    if name != "a1":
        tray = np.eye(4)
        tray[:3, 3] = (0.55, 0.0, top)
        for b in Environment.from_urdf(data / "tray" / "traybox.urdf", tray,
                                       prefix="tray").bodies:
            env.add(b.name, b.mesh, b.origin)
    return env


def with_environment(name: str, samples: int = 0, seed: int = 0) -> tuple[Robot, Environment]:
    """Robot ``name`` (:func:`load`) and its :func:`environment`; with ``samples``, the robot's
    allowed-collision matrix made MoveIt's way from that many random configurations (seed
    ``seed + 1``), as the benchmarks make it."""
    robot, env = load(name), environment(name)
    if samples:
        robot.allowed = robot.compute_allowed_collisions(samples, seed=seed + 1)
    return robot, env


class FclRobot:
    """python-fcl's answers for a robot: one BVH per body, a dynamic AABB tree manager over the
    robot's bodies and the environment's, transforms set and the tree updated per
    configuration; each candidate pair of the broad phase is checked only when the robot checks
    it (:meth:`~pycinder.robot.Robot.checked_pairs`), with ``fcl.collide``."""

    def __init__(self, robot: Robot, environment: Environment | None = None, *,
                 self_collision: bool = True) -> None:
        fcl = self.fcl = require("fcl", "python-fcl", "bench", "python-fcl")
        self.robot, self.environment = robot, environment
        self.bodies: list[Body] = robot._all_bodies(environment)
        self.owner = [_owner(b) for b in self.bodies]
        pairs = robot._pair_list(environment, self_collision)
        self.checked = np.zeros((len(self.bodies),) * 2, dtype=bool)
        for i, j in pairs:
            self.checked[i, j] = self.checked[j, i] = True
        self.pairs_checked = len(pairs)
        self.geoms, self.objs = [], []
        for b in self.bodies:
            g = fcl.BVHModel()
            g.beginModel(len(b.mesh.vertices), len(b.mesh.faces))
            g.addSubModel(np.asarray(b.mesh.vertices, np.float64),
                          np.asarray(b.mesh.faces, np.int32))
            g.endModel()
            self.geoms.append(g)
            self.objs.append(fcl.CollisionObject(g, fcl.Transform()))
        self.index = {id(g): i for i, g in enumerate(self.geoms)}
        self.request = fcl.CollisionRequest(num_max_contacts=1, enable_contact=False)
        self.manager = fcl.DynamicAABBTreeCollisionManager()
        self.manager.registerObjects(self.objs)
        self.manager.setup()

    def poses(self, qs: np.ndarray) -> np.ndarray:
        """(C, B, 4, 4) every body's pose (robot, attached, environment), as a check poses
        them."""
        return self.robot._check_poses(qs, self.environment)

    def check(self, qs: np.ndarray, poses: np.ndarray | None = None
              ) -> list[set[tuple[str, str]]]:
        """Colliding pairs of names per configuration (names sorted in each pair)."""
        fcl = self.fcl
        poses = self.poses(qs) if poses is None else poses
        out = []
        for pose in poses:
            key: dict[bytes, list[int]] = {}
            for i, (o, t) in enumerate(zip(self.objs, pose)):
                o.setTransform(fcl.Transform(t[:3, :3], t[:3, 3]))
                key.setdefault(_key(o), []).append(i)
            self.manager.update()
            found: set[tuple[str, str]] = set()
            checked, request, index, owner = self.checked, self.request, self.index, self.owner

            def callback(o1: Any, o2: Any, cdata: Any) -> bool:
                a, b = key.get(_key(o1), ()), key.get(_key(o2), ())
                if not any(checked[i, j] for i in a for j in b):
                    return False
                result = fcl.CollisionResult()
                if fcl.collide(o1, o2, request, result):
                    c = result.contacts[0]
                    i, j = index[id(c.o1)], index[id(c.o2)]
                    if checked[i, j]:
                        found.add(tuple(sorted((owner[i], owner[j]))))
                return False

            self.manager.collide(fcl.CollisionData(), callback)
            out.append(found)
        return out


class TrimeshRobot:
    """trimesh's answers for a robot, the way a trimesh user checks one: a
    ``trimesh.collision.CollisionManager`` (python-fcl underneath) holding every body under its
    index, transforms set per configuration, ``in_collision_internal(return_names=True)``, and
    the names kept where the robot checks the pair (:meth:`~pycinder.robot.Robot.checked_pairs`:
    trimesh's manager has no allowed-collision matrix, so every pair it finds is narrow-phased).
    """

    def __init__(self, robot: Robot, environment: Environment | None = None, *,
                 self_collision: bool = True) -> None:
        self.robot, self.environment = robot, environment
        self.bodies: list[Body] = robot._all_bodies(environment)
        self.owner = [_owner(b) for b in self.bodies]
        self.checked = {frozenset(p) for p in robot._pair_list(environment, self_collision)}
        self.manager = trimesh.collision.CollisionManager()
        for i, b in enumerate(self.bodies):
            self.manager.add_object(str(i), b.mesh)

    def check(self, qs: np.ndarray, poses: np.ndarray | None = None
              ) -> list[set[tuple[str, str]]]:
        """Colliding pairs of names per configuration (names sorted in each pair); ``poses``
        (C, B, 4, 4) as :meth:`FclRobot.poses` gives them."""
        if poses is None:
            poses = self.robot._check_poses(qs, self.environment)
        out = []
        for pose in poses:
            for i, t in enumerate(pose):
                self.manager.set_transform(str(i), t)
            _, names = self.manager.in_collision_internal(return_names=True)
            out.append({tuple(sorted((self.owner[int(a)], self.owner[int(b)])))
                        for a, b in names if frozenset((int(a), int(b))) in self.checked})
        return out


def _key(o: Any) -> bytes:
    """A collision object's pose as bytes: which body a broad-phase callback is given (python-fcl
    hands new wrappers to callbacks; bodies at one pose are told apart after the narrow phase)."""
    return o.getTranslation().tobytes() + o.getRotation().tobytes()


def world_meshes(robot: Robot, environment: Environment | None, pose: np.ndarray
                 ) -> dict[str, trimesh.Trimesh]:
    """Each name's bodies (a link's, an attached object's, an environment body's) in world
    coordinates at one configuration's poses (B, 4, 4) (as :meth:`FclRobot.poses` gives them),
    several bodies of one name joined."""
    bodies = robot._all_bodies(environment)
    parts: dict[str, list[trimesh.Trimesh]] = {}
    for b, t in zip(bodies, pose):
        name = _owner(b)
        m = b.mesh.copy()
        m.apply_transform(t)
        parts.setdefault(name, []).append(m)
    return {k: v[0] if len(v) == 1 else trimesh.util.concatenate(v) for k, v in parts.items()}


def exact_verdict(a: trimesh.Trimesh, b: trimesh.Trimesh, tolerance: float | None) -> str:
    """What exact geometry says of two world meshes, in the contract's terms (see
    :mod:`pycinder.request`) for the pair's tolerance (``tolerance``, or the documented default
    of :func:`pycinder.testing.mesh_pair_tolerances`):

    * ``"apart"``: at least one tolerance apart (manifold3d for two solids; python-fcl's surface
      distance where one is open): never to be reported;
    * ``"deep"``: penetrating by two tolerances (a surface point of one 2 t inside the other
      solid; an edge crossing the other's surface with both ends 2 t from its face, where one is
      open): always to be reported;
    * ``"band"``: in between, where either answer keeps the contract.
    """
    t = float(mesh_pair_tolerances([a, b], None, np.array([[0, 1]]), tolerance)[0])
    if a.is_volume and b.is_volume:
        truth = ground_truth([a, b], None, tolerance=t)
        return "deep" if len(truth.overlap) else "apart" if len(truth.separate) else "band"
    d = surface_distance(a, b)
    if d >= t:
        return "apart"
    if d <= 0 and crosses_deeply(a, b, 2 * t):
        return "deep"
    return "band"


def score(robot: Robot, environment: Environment | None, poses: np.ndarray,
          ours: list[set[tuple[str, str]]], theirs: list[set[tuple[str, str]]],
          limit: int | None = None) -> dict[str, Any]:
    """Score every pair on which two answers differ against exact geometry.

    Parameters
    ----------
    poses : (C, B, 4, 4) float
        Every body's pose per configuration (:meth:`FclRobot.poses`).
    ours, theirs : list of set of (str, str)
        Colliding pairs per configuration, of pycinder and of python-fcl.
    limit : int, optional
        Score at most this many differing pairs.

    Returns
    -------
    dict
        ``differing``: pairs that differ; ``scored``; ``missed``: deep pairs pycinder did not
        report; ``false``: apart pairs pycinder reported (both break the contract: 0 expected);
        ``band``: pairs in between; ``fcl_missed``, ``fcl_false``: python-fcl's own (it tests
        surfaces only: a body wholly inside another is apart to it); ``examples``: the
        configuration and pair of each miss and false.
    """
    out = {"differing": 0, "scored": 0, "missed": 0, "false": 0, "band": 0,
           "fcl_missed": 0, "fcl_false": 0, "examples": []}
    for c, (mine, other) in enumerate(zip(ours, theirs)):
        diff = sorted(set(mine) ^ set(other))
        out["differing"] += len(diff)
        if not diff:
            continue
        meshes = world_meshes(robot, environment, poses[c])
        for pair in diff:
            if limit is not None and out["scored"] >= limit:
                continue
            verdict = exact_verdict(meshes[pair[0]], meshes[pair[1]], robot.tolerance)
            out["scored"] += 1
            if verdict == "band":
                out["band"] += 1
            elif pair in mine and verdict == "apart":
                out["false"] += 1
                out["fcl_missed"] += 0
                out["examples"].append((c, pair, "false"))
            elif pair in other and verdict == "deep":
                out["missed"] += 1
                out["examples"].append((c, pair, "missed"))
            elif pair in other and verdict == "apart":
                out["fcl_false"] += 1
            elif pair in mine and verdict == "deep":
                out["fcl_missed"] += 1
    return out


def write_meshes(robot: Robot, folder: str | Path) -> list[str]:
    """Each collision body's mesh as a PLY file in ``folder``; paths in body order (bodies
    sharing a mesh share one file)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths, written = [], {}
    for b in robot.bodies:
        if id(b.mesh) not in written:
            out = folder / f"{robot.name}-{len(written)}-{Path(b.source).stem}.ply"
            b.mesh.export(out)
            written[id(b.mesh)] = str(out)
        paths.append(written[id(b.mesh)])
    return paths

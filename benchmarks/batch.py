"""Robot configurations per second: in-query batching and Ray workers, against python-fcl.

``pycinder bench batch``, on :mod:`pycinder.robot`'s robots (:mod:`.robot`):

* four robots of pybullet_data (Franka Panda, KUKA iiwa, xArm 6, Unitree A1) with their
  environment (table, tray), each with MoveIt's allowed-collision matrix computed by
  :meth:`pycinder.robot.Robot.compute_allowed_collisions`: ``Robot.check`` against python-fcl's
  manager filtered by the same matrix (:class:`.robot.FclRobot`), every differing pair scored by
  exact geometry (:func:`.robot.score`), pairs per configuration before and after the matrix,
  host milliseconds per configuration (:func:`run_robots`);

then, on the Panda alone with every pair of its 11 bodies checked (meshes as they are):

* python-fcl: one ``DynamicAABBTreeCollisionManager``, transforms set per configuration;
* pycinder, one query per configuration (``find_collisions``);
* pycinder, many configurations per query (``find_collisions_batch``), at several batch sizes;
* ``pycinder.batch.run`` on a local Ray with 1, 2 and N workers, with and without batching,
  fed from manifest entries that name the mesh files (read once per worker);
* the driver alone reading and checking the manifest: the data-loading limit of a run.

Answers are compared configuration by configuration, and the pairs where they differ scored
against exact geometry (:func:`.robot.score`).
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pycinder.robot import Robot
from pycinder.testing.robots import (ROBOTS, FclRobot, TrimeshRobot, environment, load, score,
                                     with_environment, write_meshes)
from pycinder.testing.scenes import Scene

from .peers import FCL

CONFIGURATIONS = 10_000
ROBOT_CONFIGURATIONS = 1000
"""Configurations per robot of the four-robot comparison."""
MATRIX_SAMPLES = 1000
"""Random configurations of the allowed-collision matrix (MoveIt's rules)."""
BATCH_SIZES = (1, 10, 100, 1000)
RAY_BATCH = 250
"""Configurations per query in the batched Ray runs (40 chunks of the 10,000)."""
CHECK_SIZES = (1, 4, 16, 64, 256, 1024, 4096, 16384)
"""Configurations per query of :func:`run_check_sweep` (``Robot.check``'s ``batch``)."""


def _rate(count: int, seconds: float) -> float:
    return count / max(seconds, 1e-9)


class Configurations(Scene):
    """A robot's configurations as benchmark frames: frame k is configuration k's poses."""

    def __init__(self, robot: Robot, poses: np.ndarray) -> None:
        meshes = [b.mesh for b in robot.bodies]
        super().__init__(f"{robot.name}-configurations", f"{robot.name}, {len(poses)} poses",
                         [np.asarray(m.faces) for m in meshes],
                         [np.asarray(m.vertices) for m in meshes], len(poses))
        self.poses = poses

    def frame(self, k: int) -> tuple[list[np.ndarray], np.ndarray]:
        return self.rest, self.poses[k]


def fcl_pairs(robot: Robot, poses: np.ndarray) -> tuple[list[set], float]:
    """Colliding pairs per configuration from python-fcl's dynamic AABB tree manager (the
    benchmarks' python-fcl peer: transforms set, tree updated and all pairs collected per
    configuration), and the seconds taken."""
    scene = Configurations(robot, poses)
    peer = FCL()
    peer.prepare(scene)
    t0 = time.perf_counter()
    pairs = [peer.step(scene, k) for k in range(len(poses))]
    seconds = time.perf_counter() - t0
    return [{tuple(p) for p in found.tolist()} for found in pairs], seconds


def manifest_entries(robot: Robot, poses: np.ndarray, paths: Sequence[str]) -> list[dict]:
    """One scene entry per configuration, naming the mesh files (as a manifest line would)."""
    names = [b.link for b in robot.bodies]
    return [{"id": c, "bodies": [{"mesh": p, "transform": t.tolist(), "name": n}
                                 for p, t, n in zip(paths, pose, names)]}
            for c, pose in enumerate(poses)]


def loading_rate(entries: list[dict], folder: Path) -> tuple[float, float]:
    """Scenes per second the driver reads and checks from a manifest file, alone; and the
    manifest's bytes per scene."""
    from pycinder.batch.manifest import normalize, read_manifest

    path = folder / "manifest.jsonl"
    path.write_text("".join(json.dumps(e) + "\n" for e in entries))
    t0 = time.perf_counter()
    n = sum(1 for k, e in enumerate(read_manifest(path)) if normalize(e, k))
    return _rate(n, time.perf_counter() - t0), path.stat().st_size / max(n, 1)


def ray_rates(entries: list[dict], workers: Sequence[int], batch: int, unbatched: int,
              say: Callable[[str], None]) -> list[dict]:
    """Scenes per second of ``pycinder.batch.run`` with each worker count, batched (all
    entries, ``batch`` per query) and not (the first ``unbatched``, one per query)."""
    import ray

    from pycinder.batch import run

    rows = []
    started = not ray.is_initialized()
    if started:
        ray.init(num_cpus=max(workers), include_dashboard=False, log_to_driver=False,
                 logging_level="ERROR")
    try:
        gpus = float(ray.cluster_resources().get("GPU", 0))
        for w in workers:
            for size, todo in ((1, entries[:unbatched]), (batch, entries)):
                say(f"batch: Ray, {w} workers, {size} scenes per query")
                t0 = time.perf_counter()
                results = run(todo, workers=w, batch_size=size,
                              gpus_per_worker=min(1.0, gpus / w) if gpus else 0.0)
                start = time.perf_counter() - t0
                pairs = {r["id"]: r.get("pairs") for r in results}
                s = results.summary
                rows.append({"workers": w, "batch_size": size, "scenes": s["scenes"],
                             "seconds": s["seconds"] - s["startup_seconds"],
                             "scenes_per_s": s["scenes_per_s"],
                             "startup_s": start, "failed": s["failed"],
                             "mesh_loads": s.get("mesh_loads"), "pairs": pairs})
    finally:
        if started:
            ray.shutdown()
    return rows


def run_batch(configurations: int = CONFIGURATIONS, *, batch_sizes: Sequence[int] = BATCH_SIZES,
              sweep: int = 1000, single: int = 1000, truth: int = 20,
              workers: Sequence[int] | None = None, unbatched: int = 1000,
              ray_batch: int = RAY_BATCH, seed: int = 0,
              robots: Sequence[str] = tuple(ROBOTS),
              robot_configurations: int = ROBOT_CONFIGURATIONS,
              matrix_samples: int = MATRIX_SAMPLES,
              check_sizes: Sequence[int] = CHECK_SIZES,
              progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Configurations per second of the Panda arm, every system on the same poses.

    Parameters
    ----------
    configurations : int
        Random configurations (within the joint limits) timed for python-fcl, the largest
        batch size and the batched Ray runs.
    batch_sizes : sequence of int
        Configurations per query in the in-process sweep, over the first ``sweep``.
    single : int
        Configurations timed one query each.
    truth : int
        Differing pairs scored against exact geometry (at most).
    workers : sequence of int, optional
        Ray worker counts (default 1, 2 and the number of CPU cores; empty: no Ray runs).
    unbatched : int
        Configurations of the Ray runs with one scene per query.
    ray_batch : int
        Configurations per query of the batched Ray runs.
    robots : sequence of str
        Robots of :func:`run_robots` (empty: none).
    robot_configurations, matrix_samples : int
        :func:`run_robots`' configurations per robot and matrix samples.
    check_sizes : sequence of int
        Batch sizes of :func:`run_check_sweep` on the Panda (empty: none).
    """
    import pycinder

    say = progress or (lambda msg: None)
    robot = load("panda")
    q = robot.random_configurations(configurations, seed)
    poses = robot.poses(q)
    meshes = [b.mesh for b in robot.bodies]
    out: dict[str, Any] = {
        "robot": robot.name, "bodies": len(meshes),
        "triangles": [len(m.faces) for m in meshes], "pairs_per_configuration":
            len(meshes) * (len(meshes) - 1) // 2, "configurations": configurations,
        "open": [Path(b.source).name for b in robot.bodies if not b.mesh.is_volume],
    }
    say("batch: python-fcl")
    fcl, seconds = fcl_pairs(robot, poses)
    out["python-fcl"] = {"configurations": configurations, "seconds": seconds,
                         "per_s": _rate(configurations, seconds)}
    det = pycinder.Detector(records="none")
    scenes = [(meshes, pose) for pose in poses]
    det.find_collisions_batch(scenes[:max(batch_sizes)])  # warm-up: pipelines, shapes
    say("batch: pycinder, one query per configuration")
    t0 = time.perf_counter()
    alone = [det.find_collisions(meshes, pose).pairs for pose in poses[:single]]
    seconds = time.perf_counter() - t0
    out["pycinder-single"] = {"configurations": single, "seconds": seconds,
                              "per_s": _rate(single, seconds)}
    out["pycinder-batch"] = []
    ours: list[np.ndarray] = []
    for size in batch_sizes:
        count = configurations if size == max(batch_sizes) else min(sweep, configurations)
        say(f"batch: pycinder, {size} configurations per query")
        results = []
        t0 = time.perf_counter()
        for k in range(0, count, size):
            results += det.find_collisions_batch(scenes[k:k + size])
        seconds = time.perf_counter() - t0
        out["pycinder-batch"].append({"batch_size": size, "configurations": count,
                                      "seconds": seconds, "per_s": _rate(count, seconds)})
        if size == max(batch_sizes):
            ours = [r.pairs for r in results]
    # Where the time of a configuration goes, alone and in the largest batch (wall ms per
    # configuration by stage: the host stages bound one worker's rate whatever the GPU).
    size = max(batch_sizes)
    out["ms_per_configuration"] = {
        "single": det.find_collisions(meshes, poses[0]).stats.wall_ms,
        f"batch of {size}": {k: v / size for k, v in
                             det.find_collisions_batch(scenes[:size])[0].stats.wall_ms.items()}}
    same = [{tuple(p) for p in ours[c].tolist()} == fcl[c] for c in range(configurations)]
    out["batch_equals_single"] = [int(sum(np.array_equal(a, b) for a, b in zip(alone, ours))),
                                  len(alone)]
    out["agreement"] = {
        "configurations_equal": int(sum(same)),
        "pairs_pycinder": int(sum(len(p) for p in ours)),
        "pairs_fcl": int(sum(len(f) for f in fcl)),
        "only_pycinder": int(sum(len({tuple(p) for p in ours[c].tolist()} - fcl[c])
                                 for c in range(configurations))),
        "only_fcl": int(sum(len(fcl[c] - {tuple(p) for p in ours[c].tolist()})
                            for c in range(configurations))),
    }
    say("batch: exact geometry where the two disagree")
    names = [b.link for b in robot.bodies]
    as_names = [{tuple(sorted((names[i], names[j]))) for i, j in p} for p in fcl]
    ours_names = [{tuple(sorted((names[i], names[j]))) for i, j in p.tolist()} for p in ours]
    out["agreement"]["scored"] = score(robot, None, poses, ours_names, as_names, limit=truth)
    out["agreement"]["scored"].pop("examples")
    workers = sorted(set((1, 2, os.cpu_count() or 1) if workers is None else workers))
    with tempfile.TemporaryDirectory() as tmp:
        paths = write_meshes(robot, tmp)
        entries = manifest_entries(robot, poses, paths)
        out["loading_per_s"], out["manifest_bytes_per_scene"] = loading_rate(entries, Path(tmp))
        rows = ray_rates(entries, workers, ray_batch, min(unbatched, configurations),
                         say) if workers else []
    for row in rows:
        pairs = row.pop("pairs")
        row["equal_to_in_process"] = all(pairs[c] == ours[c].tolist() for c in pairs)
    out["ray"] = rows
    out["robots"] = run_robots(robot_configurations, robots=robots, samples=matrix_samples,
                               seed=seed, progress=say) if robots else []
    out["check_sweep"] = run_check_sweep("panda", check_sizes, samples=matrix_samples,
                                         seed=seed, progress=say) if check_sizes else None
    return out


def run_robots(configurations: int = ROBOT_CONFIGURATIONS, *,
               robots: Sequence[str] = tuple(ROBOTS), samples: int = MATRIX_SAMPLES,
               seed: int = 0, progress: Callable[[str], None] | None = None
               ) -> list[dict[str, Any]]:
    """Each robot with its environment: MoveIt's matrix, then ``Robot.check`` against python-fcl
    with the same matrix on the same random configurations, differing pairs scored exactly.

    Parameters
    ----------
    configurations : int
        Random configurations per robot (seeded by ``seed``).
    robots : sequence of str
        Names of :data:`.robot.ROBOTS`.
    samples : int
        Random configurations of the allowed-collision matrix (seed ``seed + 1``).
    """
    say = progress or (lambda msg: None)
    rows = []
    for name in robots:
        say(f"batch: {name}, allowed-collision matrix from {samples} samples")
        robot = load(name)
        env = environment(name)
        before = len(robot.checked_pairs(env))
        t0 = time.perf_counter()
        robot.allowed = robot.compute_allowed_collisions(samples, seed=seed + 1)
        matrix_s = time.perf_counter() - t0
        after = len(robot.checked_pairs(env))
        plan, _ = robot._plan(env, True)
        q = robot.random_configurations(configurations, seed)
        robot.check(q[:50], environment=env)  # warm-up: pipelines, shapes
        stages: list[dict[str, float]] = []
        det = robot.detector
        query = det._find_within  # each batch's one query (see Robot.check)

        def timed(*args: Any, **kwargs: Any) -> Any:
            result = query(*args, **kwargs)
            stages.append(dict(result.stats.wall_ms))
            return result

        say(f"batch: {name}, pycinder")
        det._find_within = timed  # type: ignore[method-assign]
        try:
            t0 = time.perf_counter()
            collides, ours = robot.check(q, environment=env, return_pairs=True)
            seconds = time.perf_counter() - t0
        finally:
            del det._find_within
        say(f"batch: {name}, python-fcl")
        fcl = FclRobot(robot, env)
        poses = fcl.poses(q)
        t0 = time.perf_counter()
        theirs = fcl.check(q, poses)
        fcl_seconds = time.perf_counter() - t0
        say(f"batch: {name}, trimesh")
        tm = TrimeshRobot(robot, env)
        t0 = time.perf_counter()
        trimeshes = tm.check(q, poses)
        trimesh_seconds = time.perf_counter() - t0
        say(f"batch: {name}, exact geometry where the two differ")
        scored = score(robot, env, poses, [set(p) for p in ours], theirs)
        ms = {k: sum(s.get(k, 0.0) for s in stages) / configurations
              for k in ("validate", "broad phase", "tiles", "upload", "gpu", "decode", "total")}
        ms["host"] = ms["validate"] + ms["broad phase"] + ms["tiles"]
        ms["check"] = seconds * 1e3 / configurations
        ms["outside query"] = ms["check"] - ms["total"]
        rows.append({
            "robot": name, "urdf": ROBOTS[name], "bodies": len(robot.bodies),
            "environment": len(env), "open": sum(not b.mesh.is_volume for b in robot.bodies),
            "triangles": sum(len(b.mesh.faces) for b in robot.bodies),
            "matrix": {r: len(robot.allowed.pairs(r)) for r in
                       ("Adjacent", "Default", "Always", "Never")},
            "matrix_samples": samples, "matrix_seconds": matrix_s,
            "pairs_before": before, "pairs_after": after,
            "self_pairs_after": len(robot.checked_pairs()),
            "bodies_per_configuration": plan.bodies,
            "configurations": configurations, "colliding": int(collides.sum()),
            "pycinder": {"seconds": seconds, "per_s": _rate(configurations, seconds)},
            "python-fcl": {"seconds": fcl_seconds, "per_s": _rate(configurations, fcl_seconds)},
            "trimesh": {"seconds": trimesh_seconds,
                        "per_s": _rate(configurations, trimesh_seconds),
                        "equal_to_fcl": int(sum(a == b for a, b in zip(trimeshes, theirs)))},
            "configurations_equal": int(sum(set(a) == b for a, b in zip(ours, theirs))),
            "scored": {k: v for k, v in scored.items() if k != "examples"},
            "ms_per_configuration": ms,
        })
    return rows


def run_check_sweep(name: str = "panda", sizes: Sequence[int] = CHECK_SIZES, *,
                    least: int = 64, peers: int = 500, samples: int = MATRIX_SAMPLES,
                    seed: int = 0, progress: Callable[[str], None] | None = None
                    ) -> dict[str, Any]:
    """Configurations per second of ``Robot.check`` against the batch size, beside python-fcl
    and trimesh's ``CollisionManager`` on the same configurations: robot ``name`` with its
    environment and MoveIt's allowed-collision matrix from ``samples`` random configurations (as
    :func:`run_robots` makes it; 0: the matrix the robot loads with).

    Each size checks ``max(size, least)`` configurations in queries of ``size`` (after one
    untimed query of the size: pipelines, buffers), timing the wall and the host CPU (every
    Python thread summed, :func:`benchmarks.hostcpu.python_thread_clocks`). A size the
    device refuses or does not finish in time is recorded as such, and larger ones are not run.
    The peers check ``peers`` configurations one by one (their rate does not depend on a batch).

    Returns
    -------
    dict
        ``robot``, ``python-fcl`` and ``trimesh`` (configurations, seconds, per_s), ``sizes``
        (one row per size: batch_size, configurations, seconds, per_s, host_cpu_ms per
        configuration, or ``error``), and ``overtakes``: the smallest size at which pycinder
        checks more configurations per second than python-fcl (None: at none).
    """
    from pycinder.errors import GpuError
    from .hostcpu import cpu_ms, python_thread_clocks

    say = progress or (lambda msg: None)
    if samples:
        say(f"check sweep: {name}, allowed-collision matrix from {samples} samples")
    robot, env = with_environment(name, samples, seed)
    out: dict[str, Any] = {"robot": name, "matrix_samples": samples,
                           "pairs": len(robot.checked_pairs(env)), "sizes": []}
    most = max(max(sizes), least, peers)
    q = robot.random_configurations(2 * most, seed)
    fcl, tm = FclRobot(robot, env), TrimeshRobot(robot, env)
    poses = fcl.poses(q[:peers])
    for label, system in (("python-fcl", fcl), ("trimesh", tm)):
        say(f"check sweep: {name}, {label}")
        t0 = time.perf_counter()
        system.check(q[:peers], poses)
        seconds = time.perf_counter() - t0
        out[label] = {"configurations": peers, "seconds": seconds,
                      "per_s": _rate(peers, seconds)}
    out["overtakes"] = None
    for size in sizes:
        count = max(size, least)
        say(f"check sweep: {name}, pycinder, {size} per query")
        row: dict[str, Any] = {"batch_size": size, "configurations": count}
        try:
            robot.check(q[most:most + size], environment=env, batch=size)  # warm-up
            before, t0 = python_thread_clocks(), time.perf_counter()
            robot.check(q[:count], environment=env, batch=size)
            seconds = time.perf_counter() - t0
        except GpuError as exc:
            row["error"] = type(exc).__name__
            out["sizes"].append(row)
            break
        row.update(seconds=seconds, per_s=_rate(count, seconds),
                   host_cpu_ms=cpu_ms(before, python_thread_clocks()) / count)
        out["sizes"].append(row)
        if out["overtakes"] is None and row["per_s"] > out["python-fcl"]["per_s"]:
            out["overtakes"] = size
    return out


FRONT_SIZES = (1, 4, 8, 16, 32, 64, 128)
"""Configurations per query of :func:`run_front_sweep`."""


def run_front_sweep(name: str = "panda", sizes: Sequence[int] = FRONT_SIZES, *,
                    rounds: int = 3, samples: int = 300, seed: int = 0,
                    progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Where passes K1 and K2 pay: ``Robot.check`` of robot ``name`` with its environment at
    each batch size, through the host's poses and box test and through passes K1 and K2,
    alternating.

    The path is chosen by setting the module global ``pycinder.robot.robot.GPU_FRONT_FROM``
    (above the size: the host's; 1: K1 and K2), restored afterwards: it holds for every robot
    of the process, so nothing else may check robots meanwhile. Each timed check holds at least
    256 configurations (128 in queries of one), after one untimed check of the size.

    Parameters
    ----------
    name : str
        A robot of :data:`.robots.ROBOTS`.
    sizes : sequence of int
        Configurations per query.
    rounds : int
        Timed checks of each size and path; the best of them is kept.
    samples : int
        Random configurations of the allowed-collision matrix (0: the matrix it loads with).
    seed : int
        Seed of the configurations (the matrix's: ``seed + 1``).
    progress : callable, optional
        Called with a line of text before each size.

    Returns
    -------
    dict
        ``robot``, ``rounds`` and ``sizes``: per size, ``batch_size``, ``configurations`` and,
        for ``host`` and ``gpu``, the best rate (``per_s``), the least host CPU microseconds a
        configuration (``host_cpu_us``, every Python thread summed) and the share of queries
        that ran K1 and K2 (``k1k2``: 0 on the host's path; below 1 on the GPU's where a query's
        joint values or tolerances sent it to the host, see ``Robot._gpu_batch``).
    """
    from pycinder.robot import robot as robot_module
    from .hostcpu import cpu_ms, python_thread_clocks

    if not sizes or min(sizes) < 1 or rounds < 1:
        raise ValueError(f"sizes must be positive configurations per query and rounds at least "
                         f"1, got {tuple(sizes)} and {rounds}")
    say = progress or (lambda msg: None)
    robot, env = with_environment(name, samples, seed)
    q = robot.random_configurations(max(256, 8 * max(sizes)), seed)
    ran: list[bool] = []  # whether each query ran K1 and K2
    real = robot._gpu_batch

    def noted(*args: Any) -> Any:
        front = real(*args)
        ran.append(front is not None)
        return front

    threshold = robot_module.GPU_FRONT_FROM
    robot._gpu_batch = noted  # type: ignore[method-assign]
    out: dict[str, Any] = {"robot": name, "rounds": rounds, "sizes": []}
    try:
        for size in sizes:
            say(f"front sweep: {name}, {size} per query")
            count = max(256, 8 * size) if size > 1 else 128
            best: dict[str, dict[str, float]] = {}
            for _ in range(rounds):
                for path, front in (("host", 2**62), ("gpu", 1)):
                    robot_module.GPU_FRONT_FROM = front
                    robot.check(q[:size], environment=env, batch=size)  # warm-up
                    del ran[:]
                    before, t0 = python_thread_clocks(), time.perf_counter()
                    robot.check(q[:count], environment=env, batch=size)
                    seconds = time.perf_counter() - t0
                    cpu = cpu_ms(before, python_thread_clocks()) * 1e3 / count
                    row = best.setdefault(path, {"per_s": 0.0, "host_cpu_us": float("inf"),
                                                 "k1k2": 1.0})
                    row["per_s"] = max(row["per_s"], _rate(count, seconds))
                    row["host_cpu_us"] = min(row["host_cpu_us"], cpu)
                    row["k1k2"] = min(row["k1k2"], sum(ran) / max(len(ran), 1))
            out["sizes"].append({"batch_size": size, "configurations": count, **best})
    finally:
        robot_module.GPU_FRONT_FROM = threshold
        del robot._gpu_batch
    return out


def front_sweep_markdown(results: Sequence[dict[str, Any]], device: str) -> list[str]:
    """A table of :func:`run_front_sweep`'s results (one per robot) on ``device``: a row per
    robot and size, each path's configurations a second with its host CPU microseconds a
    configuration in brackets; a K1/K2 figure whose queries did not all run K1 and K2 says
    what share did."""

    def cell(r: dict[str, float], path: str) -> str:
        text = f"{r['per_s']:,.0f} ({r['host_cpu_us']:.0f})"
        if path == "gpu" and r["k1k2"] < 1:
            text += f", K1/K2 in {r['k1k2']:.0%} of queries"
        return text

    lines = [f"| robot | configurations per query | {device}: host path / s (host CPU us) | "
             f"{device}: K1, K2 / s (host CPU us) |", "|---|---|---|---|"]
    for r in results:
        for row in r["sizes"]:
            lines.append(f"| {r['robot']} | {row['batch_size']} | {cell(row['host'], 'host')} | "
                         f"{cell(row['gpu'], 'gpu')} |")
    return lines


PACED_CAPS = (12_000, 200_000)
"""Bodies-a-query caps of :func:`run_paced`: a CPU adapter's and a GPU's
(:data:`pycinder.robot.DEFAULT_BODIES_PER_QUERY`, :data:`pycinder.robot.GPU_BODIES_PER_QUERY`)."""


def run_paced(name: str = "panda", configurations: int = 20_000,
              caps: Sequence[int] = PACED_CAPS, *, rounds: int = 2, samples: int = 300,
              seed: int = 0, progress: Callable[[str], None] | None = None
              ) -> list[dict[str, Any]]:
    """``Robot.check(qs, environment=...)`` with no ``batch`` (paced) on ``configurations``
    random configurations of robot ``name``, with each cap of bodies a query in turn, in
    ``rounds`` rounds, after one paced check of 4,096 configurations.

    The cap is set through the module global ``pycinder.robot.robot.GPU_BODIES_PER_QUERY``
    (restored afterwards), so on a CPU adapter, which keeps
    :data:`~pycinder.robot.DEFAULT_BODIES_PER_QUERY`, every cap gives the same queries.

    Returns
    -------
    list of dict
        One per round and cap: ``robot``, ``round``, ``cap``, ``per_s``, ``host_cpu_us`` (every
        Python thread summed, a configuration), ``queries`` and ``largest`` (configurations of
        the largest query).
    """
    from pycinder.robot import robot as robot_module
    from .hostcpu import cpu_ms, python_thread_clocks

    say = progress or (lambda msg: None)
    robot, env = with_environment(name, samples, seed)
    q = robot.random_configurations(configurations, seed)
    robot.check(q[:4096], environment=env)  # warm-up: pipelines, first buffers
    sizes: list[int] = []
    real = robot._batches

    def noted(*args: Any) -> Any:
        for start, stop in real(*args):
            sizes.append(stop - start)
            yield start, stop

    cap_before = robot_module.GPU_BODIES_PER_QUERY
    robot._batches = noted  # type: ignore[method-assign]
    rows = []
    try:
        for k in range(rounds):
            for cap in caps:
                say(f"paced: {name}, round {k + 1}, cap {cap:,} bodies")
                robot_module.GPU_BODIES_PER_QUERY = cap
                del sizes[:]
                before, t0 = python_thread_clocks(), time.perf_counter()
                robot.check(q, environment=env)
                seconds = time.perf_counter() - t0
                rows.append({"robot": name, "round": k + 1, "cap": cap,
                             "per_s": _rate(configurations, seconds),
                             "host_cpu_us": cpu_ms(before, python_thread_clocks()) * 1e3
                             / configurations,
                             "queries": len(sizes), "largest": max(sizes, default=0)})
    finally:
        robot_module.GPU_BODIES_PER_QUERY = cap_before
        del robot._batches
    return rows


def check_sweep_markdown(r: dict[str, Any]) -> list[str]:
    """The report's section for :func:`run_check_sweep`."""
    fcl, tm = r["python-fcl"], r["trimesh"]
    lines = [f"## {r['robot']}: configurations per second against the batch size", "",
             "`Robot.check(qs, environment=..., batch=size)` with the robot's table (and tray), "
             f"{r['pairs']} pairs to check a configuration (MoveIt's allowed-collision matrix "
             f"from {r['matrix_samples']} samples; 0: the matrix it loads with); python-fcl and "
             "trimesh check "
             f"{fcl['configurations']} of the same configurations one by one. Host CPU: every "
             "Python thread summed, per configuration.", "",
             "| configurations per query | configurations | seconds | configurations / s | "
             "/ python-fcl | host CPU ms / configuration |", "|---|---|---|---|---|---|"]
    for row in r["sizes"]:
        if "error" in row:
            lines.append(f"| {row['batch_size']} | {row['configurations']} | "
                         f"{row['error']} | - | - | - |")
            continue
        lines.append(f"| {row['batch_size']} | {row['configurations']} | "
                     f"{row['seconds']:.2f} | {row['per_s']:.0f} | "
                     f"{row['per_s'] / fcl['per_s']:.2f} | {row['host_cpu_ms']:.3f} |")
    overtakes = r["overtakes"]
    lines += ["", f"python-fcl: {fcl['per_s']:.0f} configurations / s; trimesh's "
              f"`CollisionManager`: {tm['per_s']:.0f}. pycinder overtakes python-fcl at "
              + (f"{overtakes} configurations per query." if overtakes is not None
                 else "none of these batch sizes."), ""]
    return lines


def _per_s(system: dict[str, Any] | None) -> str:
    """A system's configurations per second for a table, '-' where it did not run."""
    return "-" if system is None else f"{system['per_s']:.0f}"


def _equal(system: dict[str, Any] | None) -> str:
    """trimesh's configurations equal to python-fcl's, in brackets ('' where it did not run)."""
    return "" if system is None else f" ({system['equal_to_fcl']})"


def robots_markdown(rows: list[dict[str, Any]]) -> list[str]:
    """The report's section on the four robots."""
    lines = [
        "## Robots with their environment and MoveIt's allowed-collision matrix", "",
        "pycinder.robot's `Robot.check` against python-fcl (a DynamicAABBTree manager, each "
        "candidate pair checked only where the same matrix disallows it) and trimesh's "
        "`CollisionManager` (python-fcl underneath, every pair it finds narrow-phased, then "
        "kept where the matrix checks it) on the same random configurations within the joint "
        "limits; the environment is pybullet_data's table (and tray, for the arms). Meshes as "
        "they are: open ones are tested as surfaces. `equal`: configurations whose pairs equal "
        "python-fcl's (pycinder's; trimesh's in brackets).", "",
        "| robot | bodies (open) | triangles | matrix: adjacent / default / always / never "
        "(samples) | pairs / configuration before -> after | configurations | colliding | "
        "pycinder / s | python-fcl / s | trimesh / s | equal | differing: band / missed / "
        "false |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        m, s = r["matrix"], r["scored"]
        lines.append(
            f"| {r['robot']} | {r['bodies']} ({r['open']}) + {r['environment']} | "
            f"{r['triangles']} | {m['Adjacent']} / {m['Default']} / {m['Always']} / "
            f"{m['Never']} ({r['matrix_samples']}) | {r['pairs_before']} -> {r['pairs_after']} "
            f"({r['self_pairs_after']} self) | {r['configurations']} | {r['colliding']} | "
            f"{r['pycinder']['per_s']:.0f} | {r['python-fcl']['per_s']:.0f} | "
            f"{_per_s(r.get('trimesh'))} | {r['configurations_equal']}"
            f"{_equal(r.get('trimesh'))} | {s['band']} / {s['missed']} / {s['false']} |")
    stages = ("validate", "broad phase", "tiles", "upload", "gpu", "decode", "total",
              "outside query", "host")
    lines += ["", "Wall milliseconds per configuration in the batched queries, by stage "
              "(`host` = validate + broad phase + tiles: what bounds one worker's rate whatever "
              "the GPU; `outside query`: forward kinematics, building scenes and splitting "
              "results):", "", "| robot | bodies / configuration | "
              + " | ".join(stages) + " |", "|---|---|" + "---|" * len(stages)]
    for r in rows:
        ms = r["ms_per_configuration"]
        lines.append(f"| {r['robot']} | {r.get('bodies_per_configuration', '')} | "
                     + " | ".join(f"{ms.get(k, 0.0):.3f}" for k in stages) + " |")
    lines.append("")
    return lines


def markdown(r: dict[str, Any]) -> list[str]:
    """The report's section for ``pycinder bench batch``."""
    fcl = r["python-fcl"]["per_s"]
    lines = robots_markdown(r["robots"]) if r.get("robots") else []
    if r.get("check_sweep"):
        lines += check_sweep_markdown(r["check_sweep"])
    lines += [
        f"## Robot configurations: {r['robot']} ({r['bodies']} collision meshes, "
        f"{r['pairs_per_configuration']} pairs each)", "",
        f"{r['configurations']} random configurations within the joint limits, all pairs of "
        "each checked; configurations per second on the same poses. Meshes: "
        f"{', '.join(str(t) for t in r['triangles'])} triangles"
        + (f"; open, tested as surfaces: {', '.join(r['open'])}" if r["open"] else "")
        + ".", "",
        "| system | configurations | seconds | configurations / s | / python-fcl |",
        "|---|---|---|---|---|",
        f"| python-fcl (DynamicAABBTree manager) | {r['python-fcl']['configurations']} | "
        f"{r['python-fcl']['seconds']:.2f} | {fcl:.0f} | 1.00 |",
        f"| pycinder, one query each | {r['pycinder-single']['configurations']} | "
        f"{r['pycinder-single']['seconds']:.2f} | {r['pycinder-single']['per_s']:.0f} | "
        f"{r['pycinder-single']['per_s'] / fcl:.2f} |",
    ]
    for b in r["pycinder-batch"]:
        lines.append(f"| pycinder, {b['batch_size']} per query | {b['configurations']} | "
                     f"{b['seconds']:.2f} | {b['per_s']:.0f} | {b['per_s'] / fcl:.2f} |")
    for row in r["ray"]:
        lines.append(f"| pycinder.batch.run, {row['workers']} Ray "
                     f"worker{'s' if row['workers'] != 1 else ''}, {row['batch_size']} "
                     f"per query | {row['scenes']} | {row['seconds']:.2f} | "
                     f"{row['scenes_per_s']:.0f} | {row['scenes_per_s'] / fcl:.2f} |")
    a = r["agreement"]
    same, alone = r["batch_equals_single"]
    lines += ["", f"Batched answers equal those of one query per configuration in {same} of the "
              f"{alone} configurations queried alone."]
    lines.append("")
    if r["ray"]:
        lines += [
            "Ray rows exclude start-up (Ray's and the workers': "
            + ", ".join(f"{row['startup_s']:.1f} s" for row in r["ray"])
            + "); their answers equal the in-process ones: "
            + ("yes" if all(row["equal_to_in_process"] for row in r["ray"]) else "**no**")
            + ".", ""]
    stages = ("validate", "broad phase", "tiles", "upload", "gpu", "decode", "total")
    lines += ["Wall milliseconds per configuration, by stage (the host stages bound one worker's "
              "rate whatever the GPU):", "", "| query | " + " | ".join(stages) + " |",
              "|---|" + "---|" * len(stages)]
    for name, ms in r["ms_per_configuration"].items():
        lines.append(f"| {name} | " + " | ".join(f"{ms.get(k, 0.0):.3f}" for k in stages) + " |")
    lines += [
        "",
        f"The driver alone reads and checks {r['loading_per_s']:.0f} manifest scenes per second "
        f"(the data-loading limit of one driver; {r['manifest_bytes_per_scene']:.0f} bytes of "
        "JSON per scene).", "",
        f"Agreement with python-fcl: {a['configurations_equal']} of {r['configurations']} "
        f"configurations give the same pairs; {a['only_pycinder']} pairs only pycinder reports, "
        f"{a['only_fcl']} only python-fcl. Scored against exact geometry "
        f"({a['scored']['scored']} of the {a['scored']['differing']} differing pairs): "
        f"{a['scored']['band']} lie within the tolerance band (closer than a tolerance or less "
        "than two deep, where either answer keeps the contract), "
        f"{a['scored']['missed']} penetrate by two tolerances (pycinder missed them), "
        f"{a['scored']['false']} are a tolerance or more apart (pycinder reported them "
        f"falsely); python-fcl missed {a['scored']['fcl_missed']} (a body inside another, which "
        "it does not test) and reported "
        f"{a['scored']['fcl_false']} falsely.", "",
    ]
    return lines

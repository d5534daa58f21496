"""Time pycinder and its peers on the same frames, interleaved, and score every system against
the same exact geometry. ``pycinder bench [SCENE...] [--repeat N] [--out DIR]``.

Scoring (:func:`pycinder.testing.ground_truth`) uses pycinder's default tolerance per pair (1% of
the smaller body's size) for every system: recall over the pairs that penetrate by at least two
tolerances, and the pairs reported though at least one tolerance apart.
"""

from __future__ import annotations

import contextlib

import datetime as _dt
import importlib.metadata as md
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np

from pycinder.testing import ground_truth
from pycinder.testing.scenes import SCENES, Scene, SphereField, Stairs

from . import checkout_env
from .peers import PEERS, Pycinder
from .system import System

DEFAULT_SCENES = ["floor", "stairs", "many", "deforming", "narrow", "sweep-extent", "sweep-bodies",
                  "sweep-triangles", "sweep-tolerance", "manager", "contacts", "contract", "modes",
                  "batch", "broadphase", "hostcpu", "soak"]
DEFAULT_PEERS = ["python-fcl", "coal", "trimesh", "warp"]
TOLERANCE_SWEEP = (0.001, 0.0028, 0.005, 0.01)
"""World tolerances of the Stairs tolerance sweep (the spheres are 0.16 across; pycinder's
default tolerance for them is 0.0028)."""

Progress = Callable[[str], None]


def machine_info() -> dict[str, Any]:
    from pycinder.gpu.device import get_gpu

    def version(name: str) -> str:
        try:
            return md.version(name)
        except md.PackageNotFoundError:
            return "not installed"

    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {
        "date": _dt.date.today().isoformat(),
        "adapter": get_gpu().description,
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": sys.version.split()[0],
        "versions": {n: version(n) for n in ("pycinder", "wgpu", "numpy", "trimesh", "python-fcl",
                                             "coal", "warp-lang", "manifold3d")},
        "command": "pycinder bench " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["bench"] else "",
    }


def truth_for(scene: Scene, k: int, tolerance: float | None = None):
    import trimesh

    verts, transforms = scene.frame(k)
    meshes = [trimesh.Trimesh(v, f, process=False) for v, f in zip(verts, scene.faces)]
    return ground_truth(meshes, list(transforms), tolerance=tolerance)


def make_peers(names: Sequence[str], left_out: dict[str, str] | None = None
               ) -> list[System]:
    """The peers that can run here; one that cannot is left out, with why, in ``left_out``
    (name to reason) and on stderr."""
    out = []
    for name in names:
        if name not in PEERS:
            raise ValueError(f"unknown peer {name!r}; choose from {', '.join(PEERS)}")
        try:
            out.append(PEERS[name]())
        except ImportError as exc:
            print(f"pycinder bench: left out {name}: {exc}", file=sys.stderr)
            if left_out is not None:
                left_out[name] = str(exc)
    return out


def run_scene(scene: Scene, systems: Sequence[System], *, truth_frames: Sequence[int] = (0,),
              tolerance: float | None = None) -> dict[str, Any]:
    """Time every system on every frame, rotating which goes first, and score the truth frames."""
    scene.cached()
    for s in systems:
        s.prepare(scene)
        s.step(scene, 0)  # warm-up: pipelines, caches, first builds
    times: dict[str, list[float]] = {s.name: [] for s in systems}
    pairs: dict[str, dict[int, np.ndarray]] = {s.name: {} for s in systems}
    for k in range(scene.frames):
        order = list(systems[k % len(systems):]) + list(systems[:k % len(systems)])
        for s in order:
            t0 = time.perf_counter()
            found = s.step(scene, k)
            times[s.name].append((time.perf_counter() - t0) * 1e3)
            pairs[s.name][k] = found
    accuracy = {s.name: {"must": 0, "found": 0, "false": 0} for s in systems}
    for k in truth_frames:
        truth = truth_for(scene, k, tolerance)
        for s in systems:
            score = truth.score(pairs[s.name][k])
            acc = accuracy[s.name]
            acc["must"] += score["overlaps"]
            acc["found"] += score["found"]
            acc["false"] += len(score["false"])
    for acc in accuracy.values():
        acc["recall"] = acc["found"] / acc["must"] if acc["must"] else 1.0
    median = {n: statistics.median(t) for n, t in times.items()}
    out = {
        "scene": scene.name, "description": scene.description, "bodies": len(scene.faces),
        "triangles": scene.triangles, "frames": scene.frames, "params": scene.params,
        "median_ms": median, "times_ms": times, "accuracy": accuracy,
        "ratio": {n: median[n] / median["pycinder"] for n in median
                  if n != "pycinder" and "pycinder" in median},
    }
    py = next((s for s in systems if s.name == "pycinder"), None)
    if isinstance(py, Pycinder) and py.last is not None:
        out["pycinder_stats"] = _stats_of(py, scene)
    return out


def _stats_of(py: Pycinder, scene: Scene) -> dict[str, Any]:
    """Where pycinder's time goes: one more frame with GPU timestamps (not timed above)."""
    from pycinder.detector import Detector

    profiled = Detector(py.detector.request.replace(profile=True))
    bodies, transforms = py.bodies(scene, 0)
    profiled.find_collisions(bodies, transforms)
    t0 = time.perf_counter()  # a deforming scene's fresh vertices are checked here (update)
    bodies, transforms = py.bodies(scene, min(1, scene.frames - 1))
    update_ms = (time.perf_counter() - t0) * 1e3 if scene.deforming else 0.0
    st = profiled.find_collisions(bodies, transforms).stats
    keys = ("candidates", "separated", "tiles", "pixels", "triangles", "samples", "rounds",
            "retries", "bytes_read", "tolerance", "submitted_ms")
    with _round_trips(py.detector) as trips:  # an unprofiled frame, as timed above
        plain = py.detector.find_collisions(bodies, transforms).stats
    # The same frame planned on the GPU (planner="gpu"), after a warm-up query.
    on_gpu = Detector(py.detector.request.replace(planner="gpu"))
    on_gpu.find_collisions(bodies, transforms)
    with _round_trips(on_gpu) as gpu_trips:
        planned = on_gpu.find_collisions(bodies, transforms).stats
    gpu = sum(st.gpu_ms.values())
    return {"wall_ms": {"update": update_ms, **st.wall_ms}, "gpu_ms": st.gpu_ms,
            **{k: getattr(st, k) for k in keys},
            "submissions": trips["submissions"], "maps": trips["maps"],
            "host_ms_before_submit": host_before_submit(plain),
            "host_ms_per_query": host_per_query(plain, update_ms),
            "host_ms_per_query_profiled": host_per_query(st, update_ms),
            "waited_ms": plain.waited_ms,
            "gpu_planner": {"submissions": gpu_trips["submissions"], "maps": gpu_trips["maps"],
                            "host_ms_before_submit": host_before_submit(planned),
                            "host_ms_per_query": host_per_query(planned, update_ms),
                            "waited_ms": planned.waited_ms},
            "gpu_busy": gpu / st.wall_ms["total"] if gpu else None}


def host_before_submit(stats: Any) -> float:
    """Host milliseconds of a query's own work before its frame's submission: ``submitted_ms``
    less the waits for the GPU in it (the GPU broad phase's and the GPU planner's maps)."""
    return stats.submitted_ms - stats.waited_ms


def host_per_query(stats: Any, update_ms: float = 0.0) -> float:
    """Host milliseconds of a query's own work in total: a deforming scene's update, the
    validation, the work before the submission and the decoding (no wait for the GPU)."""
    w = stats.wall_ms
    return update_ms + w.get("validate", 0.0) + host_before_submit(stats) + w.get("decode", 0.0)


@contextlib.contextmanager
def _round_trips(detector: Any) -> Iterator[dict[str, int]]:
    """Count the queue submissions and buffer maps pycinder makes while the block runs (not the
    empty submission wgpu-py makes before some maps); every map of pycinder's is asked for by
    :meth:`pycinder.gpu.buffers.Readback.start`."""
    from pycinder.gpu.buffers import Readback

    queue_type = type(detector.gpu.device.queue)
    submit, start = queue_type.submit, Readback.start
    trips = {"submissions": 0, "maps": 0}

    def counted_submit(queue: Any, *args: Any, **kwargs: Any) -> Any:
        if "pycinder" in sys._getframe(1).f_code.co_filename:
            trips["submissions"] += 1
        return submit(queue, *args, **kwargs)

    def counted_start(readback: Any, *args: Any, **kwargs: Any) -> Any:
        trips["maps"] += 1
        return start(readback, *args, **kwargs)

    queue_type.submit, Readback.start = counted_submit, counted_start
    try:
        yield trips
    finally:
        queue_type.submit, Readback.start = submit, start


def run_tolerance_sweep(frames: int, peers: Sequence[System]) -> list[dict[str, Any]]:
    """Stairs at several tolerances: pycinder's time against the peers' (which have none)."""
    rows = []
    for tol in TOLERANCE_SWEEP:
        scene = Stairs(250, frames)
        entry = run_scene(scene, [Pycinder(tolerance=tol)] + list(peers), tolerance=tol)
        entry["params"] = {**entry["params"], "tolerance": tol}
        rows.append(entry)
    return rows


def run_modes(frames: int) -> list[dict[str, Any]]:
    """The scene strategy's readback and self-interference modes on a sparse and a dense scene."""
    rows = []
    for scene in (Stairs(50, frames), SphereField(80, 3, frames)):
        kind = "sparse" if scene.name.startswith("stairs") else "dense"
        scene.cached()
        truths = {k: truth_for(scene, k) for k in range(scene.frames)}
        configs = [{"readback": m} for m in ("full", "compact", "adaptive")]
        configs += [{"readback": "mipmap", "mipmap_levels": k} for k in (2, 4)]
        configs += [{"self_interference": m} for m in ("filter", "prevent", "offset")]
        for options in configs:
            system = Pycinder(strategy="scene", resolution=1024, records="found", **options)
            system.step(scene, 0)
            times, bytes_read, missed, false, lost, self_px = [], [], 0, 0, 0, 0
            for k in range(scene.frames):
                t0 = time.perf_counter()
                found = system.step(scene, k)
                times.append((time.perf_counter() - t0) * 1e3)
                st = system.last.stats
                bytes_read.append(st.bytes_read)
                lost += st.possibly_lost
                self_px += st.self_interference_pixels
                score = truths[k].score(found)
                missed += len(score["missed"])
                false += len(score["false"])
            rows.append({"scene": kind, "scene_name": scene.name, "options": options,
                         "median_ms": statistics.median(times),
                         "median_bytes": int(statistics.median(bytes_read)),
                         "missed_pairs": missed, "false_pairs": false,
                         "must": int(sum(len(t.overlap) for t in truths.values())),
                         "possibly_lost": lost, "self_interference_pixels": self_px,
                         "frames": scene.frames})
    return rows


def run_soak(frames: int = 100_000, every: int = 1000, progress: Progress | None = None,
             mode: str = "fresh") -> dict[str, Any]:
    """The memory soak (:mod:`.soak`) of one ``mode`` ("fresh" arrays or a "deforming" body) in
    a fresh process, so that its resident memory is its own and not that of the scenes before
    it."""
    import json
    import subprocess

    if progress:
        progress(f"soak ({mode}): {frames} frames in a fresh process")
    out = subprocess.run([sys.executable, "-m", "benchmarks.soak", "--frames",
                          str(frames), "--every", str(every), "--mode", mode],
                         capture_output=True, text=True, env=checkout_env())
    if out.returncode != 0:
        raise RuntimeError(f"the soak failed: {out.stderr.strip()[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


FLOOR_BACKENDS: tuple[str | None, ...] = (None, "OpenGL")
"""The backends of the cost floor: wgpu's own choice, then OpenGL (skipped where it is the same
backend, and named where it is missing)."""


def run_floor(calls: int = 100, backends: Sequence[str | None] = FLOOR_BACKENDS,
              progress: Progress | None = None) -> list[dict[str, Any]]:
    """The cost floor (:mod:`.floor`), one fresh process per backend."""
    import json
    import subprocess

    from .floor import COMMAND

    rows: list[dict[str, Any]] = []
    for backend in backends:
        env = checkout_env()
        env.pop("WGPU_BACKEND_TYPE", None)
        if backend:
            env["WGPU_BACKEND_TYPE"] = backend
        if progress:
            progress(f"floor: {backend or 'default backend'}")
        out = subprocess.run([sys.executable, "-c", COMMAND, "--calls", str(calls)],
                             capture_output=True, text=True, env=env)
        if out.returncode != 0:
            rows.append({"backend": backend, "error": out.stderr.strip()[-500:]})
            continue
        row = json.loads(out.stdout.strip().splitlines()[-1])
        row["backend"] = backend or "default"
        if any(r.get("adapter") == row["adapter"] for r in rows):
            continue  # the default backend was this one
        rows.append(row)
    return rows


def run_manager(repeat: int) -> list[dict[str, Any]]:
    """CollisionManager calls against trimesh's (python-fcl) on the same objects, interleaved:
    200 random primitives, a probe, a second manager of 50 objects, and a batch of 700 small
    spheres tested against one box."""
    import trimesh

    from pycinder.manager import CollisionManager
    from pycinder.testing import random_scene

    T = trimesh.transformations.translation_matrix
    meshes, transforms = random_scene(200, 7, density=0.15)
    others, other_t = random_scene(50, 8, density=0.15)
    probe = trimesh.creation.icosphere(subdivisions=3, radius=2.0)
    ball = trimesh.creation.icosphere(subdivisions=1, radius=0.05)
    centres = np.random.default_rng(0).uniform(-1.2, 1.2, (700, 3))
    box = trimesh.creation.box((2, 2, 2))
    managers = {"pycinder": (CollisionManager(), CollisionManager(), CollisionManager()),
                "trimesh": (trimesh.collision.CollisionManager(),
                            trimesh.collision.CollisionManager(),
                            trimesh.collision.CollisionManager())}
    for first, second, batch in managers.values():
        for i, (m, t) in enumerate(zip(meshes, transforms)):
            first.add_object(f"a{i}", m, t)
        for i, (m, t) in enumerate(zip(others, other_t)):
            second.add_object(f"b{i}", m, t)
        for i, c in enumerate(centres):
            batch.add_object(f"p{i}", ball, T(c))
    calls = {
        "in_collision_internal()": lambda m, o, b: m.in_collision_internal(),
        "in_collision_internal(return_names=True)":
            lambda m, o, b: m.in_collision_internal(return_names=True),
        "in_collision_internal(return_data=True)":
            lambda m, o, b: m.in_collision_internal(return_data=True),
        "in_collision_single(probe)": lambda m, o, b: m.in_collision_single(probe),
        "in_collision_single(probe, return_names=True)":
            lambda m, o, b: m.in_collision_single(probe, return_names=True),
        "in_collision_single(box, return_names=True), 700 small spheres":
            lambda m, o, b: b.in_collision_single(box, return_names=True),
        "in_collision_other(return_names=True)":
            lambda m, o, b: m.in_collision_other(o, return_names=True),
        "min_distance_single(probe far away)":
            lambda m, o, b: m.min_distance_single(probe, T((0, 0, 40)), return_name=True),
        "min_distance_internal (overlapping)":
            lambda m, o, b: m.min_distance_internal(return_names=True),
        "min_distance_other (overlapping)":
            lambda m, o, b: m.min_distance_other(o, return_names=True),
    }
    rows = []
    for call, fn in calls.items():
        times: dict[str, list[float]] = {name: [] for name in managers}
        answers: dict[str, Any] = {}
        for name, objects in managers.items():
            answers[name] = fn(*objects)  # warm-up
        for k in range(repeat):
            for name in (list(managers) if k % 2 == 0 else list(managers)[::-1]):
                t0 = time.perf_counter()
                fn(*managers[name])
                times[name].append((time.perf_counter() - t0) * 1e3)
        med = {n: statistics.median(t) for n, t in times.items()}
        rows.append({"call": call, "median_ms": med, "ratio": med["trimesh"] / med["pycinder"],
                     "answers": {n: _summary(a) for n, a in answers.items()}})
    return rows


def _summary(answer: Any) -> str:
    """A short text of a manager call's answer, to put the two side by side."""
    if not isinstance(answer, tuple):
        return f"{answer:.4g}" if isinstance(answer, float) else str(answer)
    parts = []
    for x in answer:
        if isinstance(x, (set, list)):
            parts.append(f"{len(x)} items")
        elif isinstance(x, float):
            parts.append(f"{x:.4g}")
        else:
            parts.append(str(x))
    return ", ".join(parts)


def run_contact_accuracy() -> list[dict[str, Any]]:
    """Contact normal and depth against analytic pairs, pycinder and python-fcl (through
    trimesh's manager) on the same pairs."""
    import trimesh

    from pycinder.manager import CollisionManager

    T = trimesh.transformations.translation_matrix
    R = trimesh.transformations.rotation_matrix
    cases = {
        "sphere-box": ([trimesh.creation.box((2, 2, 2)), trimesh.creation.icosphere(4, 0.5)],
                       [np.eye(4), T((0, 1.45, 0))], (0, 1, 0), 0.05),
        "sphere-sphere": ([trimesh.creation.icosphere(4, 0.5),
                           trimesh.creation.icosphere(4, 0.5)],
                          [np.eye(4), T((0.9, 0, 0))], (1, 0, 0), 0.1),
        "box-edge-on-slab": ([trimesh.creation.box((4, 0.5, 4)), trimesh.creation.box((1, 1, 1))],
                             [np.eye(4), T((0, 0.25 + np.sqrt(0.5) - 0.05, 0))
                              @ R(np.pi / 4, (0, 0, 1))], (0, 1, 0), 0.05),
        "capsule-on-slab": ([trimesh.creation.box((4, 0.5, 4)),
                             trimesh.creation.capsule(height=1.0, radius=0.2, count=[32, 32])],
                            [np.eye(4), T((0, 0.25 + 0.2 - 0.04, 0))], (0, 1, 0), 0.04),
        "boxes-face-to-face": ([trimesh.creation.box((1, 1, 1)), trimesh.creation.box((1, 1, 1))],
                               [np.eye(4), T((0.93, 0.2, 0.1))], (1, 0, 0), 0.07),
    }
    rows = []
    for name, (meshes, transforms, normal, depth) in cases.items():
        row: dict[str, Any] = {"pair": name, "true_depth": depth}
        for system, manager in (("pycinder", CollisionManager(tolerance=0.005)),
                                ("python-fcl", trimesh.collision.CollisionManager())):
            manager.add_object("first", meshes[0], transforms[0])
            manager.add_object("second", meshes[1], transforms[1])
            _, data = manager.in_collision_internal(return_data=True)
            c = max(data, key=lambda d: d.depth)
            # Both normals point from the contact's first object into its second; trimesh keeps
            # that order only in its private face-index dict.
            first = c.pair[0] if hasattr(c, "pair") else list(c._inds)[0]
            n = np.asarray(normal, float) * (1 if first == "first" else -1)
            angle = float(np.degrees(np.arccos(np.clip(np.dot(c.normal, n), -1, 1))))
            row[system] = {"contacts": len(data), "normal_error_deg": angle,
                           "depth": float(c.depth), "depth_error": float(c.depth - depth)}
        rows.append(row)
    return rows


def run(scenes: Sequence[str], *, repeat: int = 5, peers: Sequence[str] = DEFAULT_PEERS,
        soak_frames: int = 100_000, progress: Progress | None = None) -> dict[str, Any]:
    """Run the named scenes, ``repeat`` frames each."""
    extra = ("floor", "modes", "soak", "manager", "contacts", "batch", "contract", "broadphase",
             "hostcpu", "building", "building-small")
    unknown = [n for n in scenes if n not in SCENES and n not in extra]
    if unknown:
        raise ValueError(f"unknown scene {unknown[0]!r}; choose from "
                         f"{', '.join(sorted(SCENES) + list(extra))}")
    say = progress or (lambda msg: None)
    results: dict[str, Any] = {"machine": machine_info(), "scenes": {}, "sweeps": {}}
    results["left_out"] = {}
    peer_systems = make_peers(peers, results["left_out"])
    results["peers"] = [p.name for p in peer_systems]
    for name in scenes:
        say(name)
        if name == "floor":
            results["floor"] = run_floor(max(20 * repeat, 50), progress=say)
            continue
        if name == "modes":
            results["modes"] = run_modes(repeat)
            continue
        if name == "soak":
            results["soak"] = run_soak(soak_frames, progress=say)
            results["soak-deforming"] = run_soak(soak_frames, progress=say, mode="deforming")
            continue
        if name == "manager":
            results["manager"] = run_manager(repeat)
            continue
        if name == "contract":
            from .contract import run_contract

            results["contract"] = run_contract()
            continue
        if name == "contacts":
            results["contacts"] = run_contact_accuracy()
            continue
        if name == "batch":
            from .batch import run_batch

            results["batch"] = run_batch(progress=say)
            continue
        if name == "hostcpu":
            from .hostcpu import run_fresh

            # Host CPU per query (:mod:`.hostcpu`), in a process of its own: no thread or cache
            # of the scenes before it.
            say("hostcpu: host CPU per query, both planners, in a fresh process")
            results["hostcpu"] = run_fresh(repeats=max(repeat, 3))
            continue
        if name == "broadphase":
            from .broadbench import run_broadphase

            results["broadphase"] = run_broadphase(frames=repeat, progress=say)
            continue
        if name in ("building", "building-small"):
            from .building import run_building

            sizes = (3000, 20000) if name == "building" else (3000,)
            results["building"] = run_building(sizes, progress=say)
            continue
        if name == "sweep-tolerance":
            results["sweeps"][name] = run_tolerance_sweep(repeat, make_peers(["python-fcl"]))
            continue
        entries = []
        for scene in SCENES[name](repeat):
            say(f"{name}: {scene.name}")
            systems: list[System] = [Pycinder()]
            tolerance = None
            if name == "sweep-extent":
                tolerance = scene.params["tolerance"]
                systems = [Pycinder(tolerance=tolerance),
                           Pycinder("pycinder-scene", strategy="scene", resolution=1024)]
                systems += make_peers(["python-fcl"])
            else:
                if name in ("stairs", "many", "deforming", "narrow"):
                    # The paper's whole-scene strategy on the same frames, for the default's case.
                    systems.append(Pycinder("pycinder-scene", strategy="scene", resolution=1024))
                # Fresh peers per scene: they keep per-scene state.
                systems += make_peers([p.name for p in peer_systems])
            entries.append(run_scene(scene, systems, tolerance=tolerance))
        if name.startswith("sweep"):
            results["sweeps"][name] = entries
        else:
            results["scenes"][name] = entries[0]
    return results

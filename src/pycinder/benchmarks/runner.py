"""Time pycinder and its peers on the same frames, interleaved, and score them against exact
geometry. ``pycinder bench [SCENE...] [--repeat N] [--out DIR]``."""

from __future__ import annotations

import datetime as _dt
import importlib.metadata as md
import platform
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ..testing import ground_truth
from .peers import PEERS, Pycinder, System
from .scenes import SCENES, Scene, Stairs

DEFAULT_SCENES = ["stairs", "deforming", "many", "narrow", "sweep-triangles", "sweep-bodies",
                  "sweep-resolution", "modes"]
DEFAULT_OPTIONS = {"readback": "compact", "self_interference": "prevent"}


def machine_info() -> dict[str, Any]:
    from ..gpu.device import get_gpu

    def version(name: str) -> str:
        try:
            return md.version(name)
        except md.PackageNotFoundError:
            return "not installed"

    cpu = platform.processor()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import os
    return {
        "date": _dt.date.today().isoformat(),
        "adapter": get_gpu().description,
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": sys.version.split()[0],
        "versions": {n: version(n) for n in ("pycinder", "wgpu", "numpy", "trimesh", "python-fcl",
                                             "coal", "manifold3d")},
        "command": "pycinder bench " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["bench"] else "",
    }


def truth_for(scene: Scene, k: int):
    import trimesh

    verts, transforms = scene.frame(k)
    meshes = [trimesh.Trimesh(v, f, process=False) for v, f in zip(verts, scene.faces)]
    return ground_truth(meshes, list(transforms))


def run_scene(scene: Scene, systems: Sequence[System], *, truth_frames: Sequence[int] = (0,),
              advance: Callable[[], None] = lambda: None) -> dict[str, Any]:
    """Time every system on every frame, rotating which goes first, and score the truth frames."""
    for s in systems:
        s.prepare(scene)
        s.step(scene, 0)  # warm-up: pipelines, caches, first builds
    times: dict[str, list[float]] = {s.name: [] for s in systems}
    pairs: dict[str, dict[int, np.ndarray]] = {s.name: {} for s in systems}
    for k in scene.iter_frames():
        order = list(systems[k % len(systems):]) + list(systems[:k % len(systems)])
        for s in order:
            t0 = time.perf_counter()
            found = s.step(scene, k)
            times[s.name].append((time.perf_counter() - t0) * 1e3)
            pairs[s.name][k] = found
        advance()
    accuracy: dict[str, dict[str, Any]] = {s.name: {"overlaps": 0, "found": 0, "false": 0}
                                           for s in systems}
    for k in truth_frames:
        truth = truth_for(scene, k)
        for s in systems:
            score = truth.score(pairs[s.name][k])
            acc = accuracy[s.name]
            acc["overlaps"] += score["overlaps"]
            acc["found"] += score["found"]
            acc["false"] += len(score["false"])
    for acc in accuracy.values():
        acc["recall"] = acc["found"] / acc["overlaps"] if acc["overlaps"] else 1.0
    median = {n: statistics.median(t) for n, t in times.items()}
    out = {
        "scene": scene.name, "description": scene.description, "bodies": len(scene.faces),
        "triangles": scene.triangles, "frames": scene.frames, "params": scene.params,
        "median_ms": median, "times_ms": times, "accuracy": accuracy,
        "speedup_vs": {n: median[n] / median["pycinder"] for n in median if n != "pycinder"},
    }
    py = next((s for s in systems if isinstance(s, Pycinder)), None)
    if py is not None and py.last is not None:
        st = py.last.stats
        out["pycinder_stats"] = {"resolution": py.detector.resolution, "bytes_read": st.bytes_read,
                                 "records": st.records, "wall_ms": st.wall_ms,
                                 "gpu_ms": st.gpu_ms}
    return out


def run_modes(frames: int, resolution: int) -> list[dict[str, Any]]:
    """Readback and self-interference modes on a sparse and a dense scene (issue: readback)."""
    from .scenes import SphereField

    rows = []
    for scene in (Stairs(50, frames), SphereField(80, 3, frames)):
        kind = "sparse" if scene.name.startswith("stairs") else "dense"
        truths = {k: truth_for(scene, k) for k in range(scene.frames)}
        configs = [("readback", {"readback": "full"}), ("readback", {"readback": "compact"})]
        configs += [("readback", {"readback": "mipmap", "mipmap_levels": k}) for k in (1, 2, 3, 4)]
        configs += [("readback", {"readback": "adaptive"})]
        configs += [("self_interference", {"self_interference": m, "readback": "compact"})
                    for m in ("filter", "prevent", "offset")]
        for group, options in configs:
            if group == "readback":
                options = {"self_interference": "prevent", **options}
            system = Pycinder(resolution, **options)
            system.step(scene, 0)
            times, bytes_read, missed, false, lost, self_px = [], [], 0, 0, 0, 0
            for k in scene.iter_frames():
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
            rows.append({"scene": kind, "scene_name": scene.name, "group": group,
                         "options": options, "median_ms": statistics.median(times),
                         "median_bytes": int(statistics.median(bytes_read)),
                         "missed_pairs": missed, "false_pairs": false,
                         "overlaps": int(sum(len(t.overlap) for t in truths.values())),
                         "possibly_lost": lost, "self_interference_pixels": self_px,
                         "frames": scene.frames})
    return rows


def run(scenes: Sequence[str], *, repeat: int = 5, resolution: int = 1024,
        peers: Sequence[str] = ("python-fcl", "coal", "trimesh"), progress: Any = None
        ) -> dict[str, Any]:
    """Run the named scenes; ``repeat`` frames each."""
    results: dict[str, Any] = {"machine": machine_info(), "resolution": resolution,
                               "pycinder_options": DEFAULT_OPTIONS, "scenes": {}, "sweeps": {}}
    for name in scenes:
        if name == "modes":
            if progress:
                progress("modes")
            results["modes"] = run_modes(repeat, resolution)
            continue
        if name not in SCENES:
            raise ValueError(f"unknown scene {name!r}; choose from {sorted(SCENES) + ['modes']}")
        scene_list = SCENES[name](repeat)
        entries = []
        resolutions = (256, 512, 1024, 2048) if name == "sweep-resolution" else (resolution,)
        for scene in scene_list:
            for res in resolutions:
                if progress:
                    progress(f"{name}: {scene.name} @ {res}")
                systems: list[System] = [Pycinder(res, **DEFAULT_OPTIONS)]
                if name != "sweep-resolution" or res == resolutions[0]:
                    systems += [PEERS[p]() for p in peers]
                entry = run_scene(scene, systems)
                entry["resolution"] = res
                entries.append(entry)
        if name.startswith("sweep"):
            results["sweeps"][name] = entries
        else:
            results["scenes"][name] = entries[0]
    return results

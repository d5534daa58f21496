"""The benchmark harness: peers agree with exact geometry on a small scene, reports are written."""

import json

import numpy as np
import pytest

from pycinder.benchmarks import peers, report, runner
from pycinder.benchmarks.scenes import SphereField

pytest.importorskip("fcl")


def test_aabb_candidates_match_brute_force():
    rng = np.random.default_rng(0)
    lo = rng.uniform(0, 10, (60, 3))
    hi = lo + rng.uniform(0.1, 2, (60, 3))
    got = {tuple(p) for p in peers.aabb_candidates(lo, hi).tolist()}
    want = {(i, j) for i in range(60) for j in range(i + 1, 60)
            if (lo[i] <= hi[j]).all() and (lo[j] <= hi[i]).all()}
    assert got == want


def test_run_scene_scores_every_system(tmp_path):
    scene = SphereField(12, 2, frames=2)
    systems = [peers.Pycinder(512), peers.FCL(), peers.Trimesh()]
    try:
        systems.append(peers.Coal())
    except ImportError:
        pass
    entry = runner.run_scene(scene, systems)
    for name, acc in entry["accuracy"].items():
        assert acc["false"] == 0, name
        assert acc["recall"] == 1.0, name
    assert set(entry["median_ms"]) == {s.name for s in systems}
    results = {"machine": {"date": "today", "adapter": "test", "cpu": "cpu", "cores": 1,
                           "python": "3", "versions": {}, "command": "pycinder bench"},
               "resolution": 512, "pycinder_options": {}, "scenes": {"spheres": entry},
               "sweeps": {}}
    paths = report.write(results, tmp_path)
    assert json.loads(paths[0].read_text())["scenes"]["spheres"]["bodies"] == 12
    assert "| spheres-12x320 |" in paths[1].read_text()

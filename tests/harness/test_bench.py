"""The benchmark harness: every system scored against exact geometry, reports written."""

import json

import numpy as np
import pytest
import trimesh

pytest.importorskip("fcl", reason="python-fcl is the first peer and the exact truth (the test "
                                  "and bench extras)")

from benchmarks import peers, report, runner
from pycinder.testing.scenes import Scene, SphereField, SpreadPairs


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
    systems = [peers.Pycinder(), peers.FCL(), peers.Trimesh()]
    systems += runner.make_peers(["coal", "warp"])
    entry = runner.run_scene(scene, systems)
    for name, acc in entry["accuracy"].items():
        assert acc["false"] == 0, name
        assert acc["recall"] == 1.0, name
    assert acc["must"] > 0
    assert set(entry["median_ms"]) == {s.name for s in systems}
    assert entry["pycinder_stats"]["candidates"] > 0
    results = {"machine": {"date": "today", "adapter": "test", "cpu": "cpu", "cores": 1,
                           "python": "3", "versions": {}, "command": "pycinder bench"},
               "peers": [s.name for s in systems[1:]], "scenes": {"stairs": entry}, "sweeps": {}}
    paths = report.write(results, tmp_path)
    assert json.loads(paths[0].read_text())["scenes"]["stairs"]["bodies"] == 12
    text = paths[1].read_text()
    assert "| spheres-12x320 |" in text and "Stairs-250" in text
    assert (tmp_path / "scenes.png").stat().st_size > 1000


class Breathing(Scene):
    """Two balls whose vertices grow: apart in frame 0, overlapping in frame 1 (a deforming
    scene small enough to check by hand)."""

    def __init__(self) -> None:
        ball = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        super().__init__("breathing", "two balls growing", [np.asarray(ball.faces)] * 2,
                         [np.asarray(ball.vertices)] * 2, 2, deforming=True)
        self.transforms = np.tile(np.eye(4), (2, 1, 1))
        self.transforms[1, 0, 3] = 1.0

    def frame(self, k):
        radius = (0.4, 0.6)[k]  # 0.2 apart, then 0.2 deep
        return [v * radius for v in self.rest], self.transforms


def test_deforming_scenes_give_the_peer_each_frames_vertices():
    scene = Breathing()
    py = peers.Pycinder()
    entry = runner.run_scene(scene, [py, peers.FCL()], truth_frames=(0, 1))
    assert py.prepared is not None  # checked once, then updated frame by frame
    assert py.step(scene, 0).tolist() == [] and py.step(scene, 1).tolist() == [[0, 1]]
    for name, acc in entry["accuracy"].items():
        assert (acc["must"], acc["found"], acc["false"]) == (1, 1, 0), name


def test_spread_pairs_are_what_they_say():
    """Half the pairs must be found, half are apart, whatever the extent."""
    for extent in (10.0, 10000.0):
        scene = SpreadPairs(extent, pairs=8, frames=1)
        truth = runner.truth_for(scene, 0, tolerance=scene.params["tolerance"])
        assert len(truth.overlap) == 4 and len(truth.separate) == 8 * 15 - 4


def test_soak_keeps_memory_steady():
    """Fresh (vertices, faces) arrays every frame: three topology builds, then no growth (the
    old id-keyed cache grew about 0.1 MiB a frame, 30 MiB over these frames)."""
    soak = runner.run_soak(frames=300, every=50)
    assert soak["rss_end_mib"] < 1024
    assert soak["rss_growth_mib"] < 8, soak["samples"]
    assert soak["topology_builds"] == 3 and soak["pairs_found"] > 0
    assert len(soak["samples"]) >= 6


def test_missing_optional_packages_name_their_extra(monkeypatch, capsys):
    """Without the bench extra: a missing peer is left out and named, matplotlib is asked for
    before a run starts, and the manager's distances name the distance extra."""
    import importlib

    import pycinder
    from pycinder import cli

    real_import = importlib.import_module
    hidden = ("coal", "matplotlib", "fcl")

    def fake(name, *args, **kwargs):
        if name.split(".")[0] in hidden:
            raise ImportError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(importlib, "import_module", fake)
    left_out = {}
    assert [p.name for p in runner.make_peers(["coal"], left_out)] == []
    assert "pip install 'pycinder[bench]'" in left_out["coal"]
    assert "left out coal" in capsys.readouterr().err
    assert cli.main(["bench", "stairs", "--repeat", "1"]) == 2
    err = capsys.readouterr().err
    assert "matplotlib" in err and "pip install '.[bench]'" in err
    manager = pycinder.CollisionManager()
    with pytest.raises(ImportError, match=r"python-fcl: pip install 'pycinder\[distance\]'"):
        manager.min_distance_internal()


def test_floor_times_the_first_query_and_the_least_a_query_costs():
    """One fresh process on the backend this suite runs on: every figure measured, pycinder's
    and python-fcl's side by side, and the report's table names the adapter."""
    (row,) = runner.run_floor(calls=3, backends=(None,))
    assert "error" not in row, row
    assert row["import_ms"] > 0 and row["detector_ms"] > 0 and row["first_call_ms"] > 0
    assert row["pycinder_ms"]["apart"] > 0 and row["pycinder_ms"]["touching"] > 0
    assert row["python-fcl"]["ms"]["touching"] > 0
    text = "\n".join(report.floor_table([row, {"backend": "Metal", "error": "no adapter"}]))
    assert row["adapter"] in text and "| Metal | not available: no adapter |" in text

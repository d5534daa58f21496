"""pycinder batch on a local Ray of 2 CPUs: results as single queries give them, a killed
worker, a resumed run, bad scenes. One Ray instance for the module."""

import json
import os
import signal

import pytest

from pycinder.batch import run
from pycinder.cli import main

from batch_helpers import expected_pairs, mesh_pool, random_entries, write_manifest

ray = pytest.importorskip("ray", reason="the cluster extra brings Ray")


@pytest.fixture(scope="module", autouse=True)
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level="ERROR")
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def data(tmp_path_factory, detector):
    """48 scenes over 6 mesh files, in a manifest with relative paths, and their pairs from
    single queries."""
    folder = tmp_path_factory.mktemp("batch")
    (folder / "meshes").mkdir()
    paths = mesh_pool(folder / "meshes")
    entries = random_entries(paths, 48, seed=11, relative_to=folder)
    manifest = write_manifest(folder / "scenes.jsonl", entries)
    return folder, manifest, entries, expected_pairs(entries, detector, base=folder)


def test_run_equals_single_queries_in_order(data):
    folder, _, entries, want = data
    results = run(entries, workers=2, batch_size=8, base=str(folder))
    out = list(results)
    assert [r["id"] for r in out] == [e["id"] for e in entries]
    assert all(r["pairs"] == want[r["id"]] for r in out)
    assert sum(len(p) for p in want.values()) > 50
    assert {r["stats"]["worker"] for r in out} == {0, 1}
    assert all(r["stats"]["query_scenes"] <= 8 for r in out)
    # Meshes are read once per worker, not once per scene.
    assert all(n is not None and 0 < n <= 6 for n in results.summary["mesh_loads"])
    assert results.summary["scenes"] == 48 and results.summary["failed"] == 0
    assert results.closed


def test_killed_worker_still_gives_every_result_once(data):
    folder, _, entries, want = data
    results = run(entries, workers=2, batch_size=2, ordered=False, base=str(folder))
    out = [next(results)]
    os.kill(results.pids[0], signal.SIGKILL)  # mid-run: its chunks in flight are lost
    out += list(results)
    ids = [r["id"] for r in out]
    assert sorted(ids) == sorted(want) and len(ids) == len(set(ids))
    assert [r for r in out if "error" in r] == [], results.summary
    assert all(r["pairs"] == want[r["id"]] for r in out)
    assert results.summary["worker_failures"] >= 1 and results.summary["retried"] >= 1
    assert any(r["stats"]["attempt"] == 2 for r in out)


def test_cli_resumes_after_an_interruption(data, monkeypatch, capsys):
    """Stopped after 10 results (and a line torn as by a crash), the same command goes on:
    every scene once in OUT, those done before not run again."""
    from pycinder.batch import sink

    folder, manifest, entries, want = data
    out = folder / "out.jsonl"
    real = sink.JsonLinesSink.write
    count = {"n": 0}

    def stop_after_ten(self, result):
        if count["n"] == 10:
            raise KeyboardInterrupt
        count["n"] += 1
        real(self, result)

    monkeypatch.setattr(sink.JsonLinesSink, "write", stop_after_ten)
    args = ["batch", str(manifest), "--out", str(out), "--workers", "2", "--batch-size", "4"]
    assert main(args) == 130
    assert "run the same command again" in capsys.readouterr().err
    monkeypatch.setattr(sink.JsonLinesSink, "write", real)
    first = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["id"] for r in first] == [e["id"] for e in entries[:10]]
    with open(out, "a") as f:
        f.write('{"id": "scene-10", "pairs": [[0, ')  # torn
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "38 scenes in" in captured.out and "10 already in" in captured.out
    assert "dropped 1 torn" in captured.err
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["id"] for r in rows] == [e["id"] for e in entries]
    assert all(r["pairs"] == want[r["id"]] for r in rows)
    assert all(r["names"] == [[f"part{i}", f"part{j}"] for i, j in r["pairs"]] for r in rows)
    assert main(args) == 0 and "nothing to do" in capsys.readouterr().out


def test_bad_scenes_are_reported_and_the_rest_complete(data, capsys):
    folder, _, entries, want = data
    bad = [
        {"id": "no-file", "bodies": [{"mesh": "meshes/missing.stl"}, entries[0]["bodies"][0]]},
        {"id": "flat", "bodies": [entries[0]["bodies"][0],
                                  {**entries[0]["bodies"][1],
                                   "transform": [[1, 0, 0, 0], [0, 0, 0, 0], [0, 0, 1, 0],
                                                 [0, 0, 0, 1]]}]},
        {"id": "typo", "bodies": [{"mesh": "meshes/box.ply", "transfrom": []}]},
    ]
    mixed = entries[:6] + bad[:1] + entries[6:12] + bad[1:] + entries[12:16]
    manifest = write_manifest(folder / "bad.jsonl", mixed)
    out = folder / "bad.parquet"
    assert main(["batch", str(manifest), "--out", str(out), "--workers", "1",
                 "--batch-size", "8"]) == 1
    assert "3 failed" in capsys.readouterr().out
    import pyarrow.parquet as pq

    rows = {r["id"]: r for r in pq.read_table(out).to_pylist()}
    assert list(rows) == [e["id"] for e in mixed]
    assert "missing.stl: no such file" in rows["no-file"]["error"]
    assert "failed 2 times" in rows["no-file"]["error"]
    assert "body 1 ('scene flat: part1'): transform is singular" in rows["flat"]["error"]
    assert "scene 'typo' body 0: unknown keys ['transfrom']" in rows["typo"]["error"]
    for e in entries[:16]:
        assert rows[e["id"]]["pairs"] == want[e["id"]] and rows[e["id"]]["error"] is None


def test_workers_that_cannot_be_placed_are_an_error():
    with pytest.raises(ValueError, match="3 workers need 3 CPUs and 0 GPUs; the Ray cluster "
                                         "has 2 CPUs and 0 GPUs"):
        run([], workers=3)
    with pytest.raises(ValueError, match="batch_size must be a whole number"):
        run([], batch_size=0)

"""pycinder batch on a local Ray of 2 CPUs: results as single queries give them, a killed
worker, a resumed run, bad scenes. One Ray instance for the module (and one more, started by
the command, in the test of its start)."""

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time

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
    assert "3 failed, 0 retried" in capsys.readouterr().out
    import pyarrow.parquet as pq

    rows = {r["id"]: r for r in pq.read_table(out).to_pylist()}
    assert list(rows) == [e["id"] for e in mixed]
    assert rows["no-file"]["error"] == ("FileError: scene 'no-file' body 0 ('missing.stl'): "
                                        f"{folder / 'meshes' / 'missing.stl'}: no such file")
    assert "body 1 ('scene flat: part1'): transform is singular" in rows["flat"]["error"]
    assert "scene 'typo' body 0: unknown keys ['transfrom']" in rows["typo"]["error"]
    # Bad input, every time: written at its first try, none retried.
    for key in ("no-file", "flat", "typo"):
        assert (rows[key]["status"], rows[key]["error_kind"], rows[key]["attempts"]) == \
            ("error", "input", 1), rows[key]
    for e in entries[:16]:
        assert rows[e["id"]]["pairs"] == want[e["id"]] and rows[e["id"]]["error"] is None


def test_workers_that_cannot_be_placed_are_an_error():
    with pytest.raises(ValueError, match="3 workers need 3 CPUs and 0 GPUs; the Ray cluster "
                                         "has 2 CPUs and 0 GPUs"):
        run([], workers=3)
    with pytest.raises(ValueError, match="batch_size must be a whole number"):
        run([], batch_size=0)


def _nan_obj(path):
    """A unit box as OBJ with its first vertex NaN."""
    v = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    faces = [(1, 3, 2), (1, 2, 4), (1, 4, 3), (2, 3, 4)]
    path.write_text("v nan 0 0\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in v[1:])
                    + "".join(f"f {a} {b} {c}\n" for a, b, c in faces))
    return path


def test_bad_input_is_written_at_once_naming_its_body(data):
    """A missing file and NaN vertices fail their scenes at the first of 3 tries, with errors
    naming the scene and the body by its manifest name; the scenes around them are checked."""
    folder, _, entries, want = data
    nan = _nan_obj(folder / "nan.obj")
    scenes = [entries[0],
              {"id": "gone", "bodies": [{"mesh": "meshes/gone.stl", "name": "ghost"}]},
              {"id": "nan", "bodies": [entries[0]["bodies"][0], {"mesh": "nan.obj",
                                                                 "name": "lid"}]},
              entries[1]]
    results = run(scenes, workers=1, attempts=3, batch_size=4, base=str(folder))
    rows = list(results)
    assert [r["status"] for r in rows] == ["ok", "error", "error", "ok"]
    assert rows[1]["error"] == ("FileError: scene 'gone' body 0 ('ghost'): "
                                f"{folder / 'meshes' / 'gone.stl'}: no such file")
    assert rows[2]["error"].startswith(f"FileError: scene 'nan' body 1 ('lid'): {nan}: 1 vertex "
                                       "is NaN or infinite"), rows[2]
    assert all((r["error_kind"], r["attempts"]) == ("input", 1) for r in rows[1:3])
    assert results.summary["retried"] == 0 and results.summary["failed"] == 2
    assert [r["pairs"] for r in (rows[0], rows[3])] == [want[e["id"]] for e in entries[:2]]


def test_docstring_examples_run():
    """The examples of ``pycinder.batch`` and ``pycinder.batch.run``, with their output."""
    import doctest

    import pycinder.batch

    finder, runner = doctest.DocTestFinder(recurse=False), doctest.DocTestRunner()
    for obj in (pycinder.batch, pycinder.batch.run):
        for test in finder.find(obj, globs={}):
            runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.attempted >= 10 and result.failed == 0


def test_cli_times_the_whole_run_and_retries_errors_when_asked(data, capsys):
    """The summary's time is the run's wall time (starting the worker included, as measured
    here around the command); a resumed run keeps an earlier error and exits 1; once the
    missing file is there, --retry-errors runs its scene again and the run exits 0."""
    folder, _, entries, want = data
    late = folder / "meshes" / "late.ply"
    scenes = entries[:3] + [{"id": "late", "bodies": [{"mesh": "meshes/late.ply"},
                                                     entries[0]["bodies"][0]]}]
    manifest = write_manifest(folder / "late.jsonl", scenes)
    out = folder / "late-out.jsonl"
    args = ["batch", str(manifest), "--out", str(out), "--workers", "1"]
    t0 = time.perf_counter()
    assert main(args) == 1
    wall = time.perf_counter() - t0
    printed = capsys.readouterr().out
    found = re.search(r"4 scenes in ([\d.]+) s, wall time \(([\d.]+) s of it starting Ray and "
                      r"1 worker on .*\): [\d.]+ scenes/s once ready", printed)
    assert found, printed
    seconds, startup = float(found[1]), float(found[2])
    assert wall - 0.5 <= seconds <= wall + 0.05 and 0 < startup <= seconds, (wall, printed)
    assert main(args) == 1
    captured = capsys.readouterr()
    assert "all 4 scenes already there; 1 of them failed before" in captured.out
    shutil.copy(folder / "meshes" / "box.ply", late)
    try:
        assert main(args + ["--retry-errors"]) == 0
    finally:
        late.unlink()
    captured = capsys.readouterr()
    assert "1 scene in" in captured.out and "3 already in" in captured.out
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["id"] for r in rows] == [e["id"] for e in scenes]
    assert [r["status"] for r in rows] == ["ok"] * 4
    assert rows[3]["stats"]["bodies"] == 2 and rows[3]["stats"]["attempt"] == 1
    assert [r["pairs"] for r in rows[:3]] == [want[e["id"]] for e in entries[:3]]


def test_local_ray_starts_without_the_token_warning(tmp_path):
    """``pycinder batch`` starting its own Ray: no warning about token authentication (Ray
    2.59 on prints one at every start unless RAY_AUTH_MODE is set), and still Ray's default
    mode, token authentication, with the token Ray makes."""
    from importlib.metadata import version

    (tmp_path / "meshes").mkdir()
    entries = random_entries(mesh_pool(tmp_path / "meshes"), 2, seed=5, relative_to=tmp_path)
    manifest = write_manifest(tmp_path / "m.jsonl", entries)
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    env["HOME"] = str(tmp_path)  # no token of the user's
    proc = subprocess.run([sys.executable, "-m", "pycinder", "batch", str(manifest), "--out",
                           str(tmp_path / "out.jsonl"), "--workers", "1"], env=env,
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "2 scenes in" in proc.stdout
    assert "authentication" not in proc.stderr.lower() + proc.stdout.lower(), proc.stderr
    if tuple(int(x) for x in version("ray").split(".")[:2]) >= (2, 52):
        assert (tmp_path / ".ray" / "auth_token").is_file()


@pytest.fixture(scope="module")
def robot_manifest(tmp_path_factory):
    """A Panda manifest (adjacent links allowed, a table) of 40 configurations, and its rows
    checked in this process."""
    pytest.importorskip("yourdfpy", reason="robot manifests need the robot extra")
    pytest.importorskip("pybullet_data", reason="the Panda comes from pybullet_data")
    from robot_helpers import load_robots, write_panda_manifest

    folder = tmp_path_factory.mktemp("robot")
    panda = load_robots()["panda"]
    manifest, _ = write_panda_manifest(folder, panda, panda.random_configurations(40, seed=5))
    here = folder / "here.jsonl"
    assert main(["batch", str(manifest), "--out", str(here), "--robot-batch", "8"]) == 0
    return folder, manifest, here.read_text().splitlines()


def test_robot_manifest_on_ray_workers_gives_the_rows_of_one_process(robot_manifest, capsys):
    """``--workers 2``: chunks of configurations over two workers, each loading the robot once;
    the rows, in order, are those of the run in one process; a run cut short goes on."""
    folder, manifest, want = robot_manifest
    out = folder / "ray.jsonl"
    capsys.readouterr()
    assert main(["batch", str(manifest), "--out", str(out), "--workers", "2",
                 "--robot-batch", "8"]) == 0
    assert "on 2 Ray workers" in capsys.readouterr().out
    assert out.read_text().splitlines() == want
    assert any(json.loads(line)["collides"] for line in want)
    out.write_text("".join(line + "\n" for line in want[:13]))
    assert main(["batch", str(manifest), "--out", str(out), "--workers", "2"]) == 0
    assert "27 configurations" in capsys.readouterr().out
    assert out.read_text().splitlines() == want


def test_robot_run_survives_a_killed_worker(robot_manifest):
    """A worker killed mid-run is restarted by Ray, which checks its chunks again: every row
    comes once, in order."""
    import numpy as np

    from pycinder.batch.robot_ray import RobotRun
    from pycinder.batch.robot_run import load_configurations, read_robot_manifest

    _, manifest, want = robot_manifest
    spec = read_robot_manifest(manifest)
    q = load_configurations(spec["configurations"], [f"panda_joint{k}" for k in range(1, 8)]
                            + ["panda_finger_joint1"])
    run = RobotRun(spec, q, np.arange(len(q)), workers=2, chunk=4, batch=4)
    rows = [next(run)]
    os.kill(run.pids[1], signal.SIGKILL)  # its chunks in flight are lost, then run again
    rows += list(run)
    assert rows == [json.loads(line) for line in want]
    with pytest.raises(ValueError, match="chunk must be"):
        RobotRun(spec, q, np.arange(3), chunk=0)

"""Many scenes in one query (find_collisions_batch), the manifest, the result files. No Ray."""

import json

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.batch.manifest import ManifestError, normalize, read_manifest
from pycinder.batch.sink import JsonLinesSink, open_sink
from pycinder.batch.worker import BatchWorker, error_kind
from pycinder.focused.broad.broad_numpy import sweep_and_prune
from pycinder.testing import ground_truth, random_scene

from batch_helpers import expected_pairs, mesh_pool, random_entries
from conftest import assert_matches_truth


@pytest.fixture(scope="module")
def scenes():
    """48 random scenes of 2 to 9 primitives, all about the origin, on top of each other."""
    rng = np.random.default_rng(7)
    return [random_scene(int(rng.integers(2, 10)), seed) for seed in range(48)]


def test_sweep_within_keys_matches_brute_force():
    rng = np.random.default_rng(0)
    lo = rng.uniform(0, 10, (300, 3))
    hi = lo + rng.uniform(0.1, 3, (300, 3))
    lo[::7, 0] = hi[1::7, 0]  # boxes that touch exactly along x
    lo = np.minimum(lo, hi)
    keys = rng.integers(0, 5, 300) * 3 - 4
    got = {tuple(p) for p in sweep_and_prune(lo, hi, keys).tolist()}
    want = {(i, j) for i in range(300) for j in range(i + 1, 300) if keys[i] == keys[j]
            and (lo[i] <= hi[j]).all() and (lo[j] <= hi[i]).all()}
    assert got == want and len(want) > 50
    # Sorted, as without keys.
    pairs = sweep_and_prune(lo, hi, keys)
    assert (np.lexsort((pairs[:, 1], pairs[:, 0])) == np.arange(len(pairs))).all()


def _pixel_per_pair(result) -> dict:
    """The tiles' pixel size (the pair's tolerance) of each pair that has records."""
    rec = result.records
    a = np.minimum(rec["penetrating"], rec["penetrated"])
    b = np.maximum(rec["penetrating"], rec["penetrated"])
    pixel = result.tiles.pixel[rec["view"]] if len(rec) else []
    return {(int(i), int(j)): round(float(p), 9) for i, j, p in zip(a, b, pixel)}


def test_batch_equals_single_queries(detector, scenes):
    """Every scene's pairs are those of a query of that scene alone, though the scenes lie on
    top of each other: the broad phase paired no bodies of different scenes, each pair got the
    tolerance it gets alone, and the records name the scene's own bodies. (Records themselves
    can differ in a sample or two, as between two runs of one scene: where a tile lies in the
    atlas, and which pass finds a pair first, vary.)"""
    batch = detector.find_collisions_batch(scenes)
    singles = [detector.find_collisions(m, t) for m, t in scenes]
    assert len(batch) == len(scenes)
    found = 0
    for k, (b, s) in enumerate(zip(batch, singles)):
        assert np.array_equal(b.pairs, s.pairs), k
        found += len(s.pairs)
        assert b.stats.bodies == len(scenes[k][0]) and b.stats.records == len(b.records)
        assert _pixel_per_pair(b) == _pixel_per_pair(s), k
        assert set(_pixel_per_pair(b)) == {tuple(p) for p in b.pairs.tolist()}, k
        assert len(b.scene) == len(scenes[k][0])
    assert found > 100
    assert batch[0].stats.candidates == sum(s.stats.candidates for s in singles)
    assert batch[0].stats.rounds >= 1 and batch[0].stats.wall_ms["total"] > 0


def test_batch_against_exact_geometry(detector, scenes):
    """On 10 of the scenes: every pair penetrating by two tolerances is found and no pair a
    tolerance apart is reported (manifold3d volumes and distances)."""
    batch = detector.find_collisions_batch(scenes[:10])
    must = apart = 0
    for k, result in enumerate(batch):
        truth = ground_truth(*scenes[k])
        assert_matches_truth(result.pairs, truth, context=f"scene {k}")
        must, apart = must + len(truth.overlap), apart + len(truth.separate)
    assert must >= 10 and apart >= 10


def test_each_scene_gets_its_own_tolerance(detector):
    """Two boxes 3 units apart in scale: the first scene at tolerance 0.01, the second at the
    default (1% of a unit box's diagonal), the third at 0.05: each record's tile has pixels of
    its own scene's tolerance, and the contract holds for each."""
    box = trimesh.creation.box((1, 1, 1))
    T = trimesh.transformations.translation_matrix
    deep = [np.eye(4), T((0.9, 0.05, 0.02))]      # 0.1 deep: at least 2 tolerances for all
    apart = [np.eye(4), T((1.06, 0.0, 0.0))]      # 0.06 apart: more than a tolerance for all
    scenes = [([box, box], deep), ([box, box], deep), ([box, box], deep), ([box, box], apart)]
    results = detector.find_collisions_batch(scenes, tolerance=[0.01, None, 0.05, 0.05])
    for result, tol in zip(results[:3], (0.01, 0.01 * np.sqrt(3), 0.05)):
        assert result.pairs.tolist() == [[0, 1]]
        pixel = result.tiles.pixel[result.records["view"]]
        np.testing.assert_allclose(pixel, tol, rtol=1e-6)
    assert results[3].pairs.tolist() == []
    with pytest.raises(ValueError, match="scene 1: tolerance must be a positive"):
        detector.find_collisions_batch(scenes[:2], tolerance=[0.01, -1])
    with pytest.raises(ValueError, match="one number or one per scene"):
        detector.find_collisions_batch(scenes[:2], tolerance=[0.01])


def test_batch_bad_input_names_the_scene(detector):
    box = trimesh.creation.box((1, 1, 1))
    with pytest.raises(ValueError, match=r"scene b: transforms must have shape \(2, 4, 4\)"):
        detector.find_collisions_batch([([box, box], None), ([box, box], np.eye(4))],
                                       labels=["a", "b"])
    singular = [np.eye(4), np.diag([1.0, 0.0, 1.0, 1.0])]
    with pytest.raises(ValueError, match=r"scene 1: lid'\): transform is singular"):
        detector.find_collisions_batch([([box], None), ([box, box], singular, ["base", "lid"])])
    with pytest.raises(ValueError, match="strategy='focused'"):
        pycinder.Detector(strategy="scene").find_collisions_batch([([box, box], None)])
    # Empty scenes and scenes of one body are answered, with nothing found.
    out = detector.find_collisions_batch([([], None), ([box], None)])
    assert [len(r.pairs) for r in out] == [0, 0]


def test_worker_checks_chunks_like_single_queries(tmp_path, detector):
    """The worker without Ray: a chunk in one query equals single queries; each mesh file is
    read once however many scenes use it; a scene whose mesh is missing fails alone."""
    paths = mesh_pool(tmp_path)
    entries = [normalize(e, k) for k, e in enumerate(random_entries(paths, 12, seed=3))]
    entries.insert(5, normalize({"id": "missing", "bodies": [{"mesh": str(tmp_path / "no.stl")},
                                                              {"mesh": str(paths[0])}]}, 5))
    worker = BatchWorker({})
    out = worker.check(entries)
    want = expected_pairs([e for e in entries if e["id"] != "missing"], detector)
    assert [r["id"] for r in out] == [e["id"] for e in entries]
    assert out[5]["error"].startswith(
        f"FileError: scene 'missing' body 0 ('no.stl'): {tmp_path / 'no.stl'}: no such file")
    assert out[5]["status"] == "error" and out[5]["error_kind"] == "input"
    assert all(r["status"] == "ok" for r in out if r["id"] != "missing")
    for r in out:
        if r["id"] != "missing":
            assert r["pairs"] == want[r["id"]], r["id"]
            assert r["names"] == [[f"part{i}", f"part{j}"] for i, j in r["pairs"]]
            assert r["stats"]["query_scenes"] == 12
    assert worker.mesh_loads() == len({b["mesh"] for e in entries for b in e["bodies"]}) - 1
    assert [r.get("pairs") for r in worker.check(entries, batch=False)] == \
        [r.get("pairs") for r in out]


def test_errors_of_a_scene_s_own_input_are_told_from_others():
    """Bad input (pycinder's FileError and ManifestError are ValueErrors; a missing file an
    OSError) can never succeed; anything else may be the device's."""
    from pycinder.batch.worker import BodyError
    from pycinder.files import FileError

    assert [error_kind(e) for e in (FileError("x"), ManifestError("x"), FileNotFoundError("x"),
                                    TypeError("x"), BodyError("b", PermissionError("x")))] \
        == ["input"] * 5
    assert [error_kind(e) for e in (RuntimeError("lost"), MemoryError(),
                                    BodyError("b", RuntimeError("x")))] == ["query"] * 3


def test_mesh_warnings_name_each_scene_s_body(tmp_path):
    """An open mesh file used by two scenes under two names: each scene's warnings name its
    own body (scene id, place, manifest name), in a chunk of one query or scene by scene; a
    closed file warns nothing; nothing said about one scene is given to the other."""
    box = trimesh.creation.box((1, 1, 1))
    trimesh.Trimesh(box.vertices, box.faces[:-2]).export(tmp_path / "open.stl")
    box.export(tmp_path / "closed.stl")
    entries = [normalize({"id": "a", "bodies": [{"mesh": "open.stl", "name": "lid"},
                                                {"mesh": "closed.stl", "name": "base"}]},
                         0, tmp_path),
               normalize({"id": "b", "bodies": [{"mesh": "closed.stl"},
                                                {"mesh": "open.stl", "name": "cover"}]},
                         1, tmp_path),
               normalize({"id": "c", "bodies": [{"mesh": "closed.stl"}]}, 2, tmp_path)]
    worker = BatchWorker({})
    for batch in (True, False):
        out = worker.check(entries, batch)
        said = [r["stats"].get("warnings", []) for r in out]
        assert [len(w) for w in said] == [1, 1, 0], said
        assert said[0][0].startswith(f"scene 'a' body 0 ('lid'): {tmp_path / 'open.stl'} is not "
                                     "a closed, consistently oriented surface: 4 boundary"), said
        assert said[1][0].startswith("scene 'b' body 1 ('cover'): "), said
        assert said[0][0].split(": ", 1)[1] == said[1][0].split(": ", 1)[1]


def test_manifest_errors_name_the_line(tmp_path):
    m = tmp_path / "m.jsonl"
    m.write_text('{"id": 1, "bodies": []}\n\n{"id": 2, "bodies": []}\n{"id": 1, "bodies": []}\n')
    with pytest.raises(ManifestError, match=r"m.jsonl:4: id 1 repeats line 1"):
        list(read_manifest(m))
    m.write_text('{"id": 1, "bodies": []}\n{"id": 2, "bodies": [\n')
    with pytest.raises(ManifestError, match=r"m.jsonl:2: not JSON"):
        list(read_manifest(m))
    m.write_text('{"id": 1.5, "bodies": []}\n')
    with pytest.raises(ManifestError, match=r"m.jsonl:1: id must be a string or an integer"):
        list(read_manifest(m))
    with pytest.raises(ValueError, match=r"scene 'a' body 0: transform must be 4 x 4"):
        normalize({"id": "a", "bodies": [{"mesh": "x.stl", "transform": [[1, 0], [0, 1]]}]}, 0)
    with pytest.raises(ValueError, match=r"scene 'a': unknown keys \['tolerence'\]"):
        normalize({"id": "a", "tolerence": 1, "bodies": []}, 0)
    e = normalize({"bodies": [{"mesh": "parts/a.stl"}]}, 7, base="/data/run")
    assert e["id"] == 7 and e["bodies"][0]["mesh"] == "/data/run/parts/a.stl"


def test_json_lines_resume_drops_torn_and_repeated_lines(tmp_path):
    out = tmp_path / "out.jsonl"
    sink = JsonLinesSink(out)
    for k in range(3):
        sink.write({"id": k, "pairs": []})
    sink.close()
    with open(out, "ab") as f:
        f.write(b'{"id": 1, "pairs": [[0, 1]]}\n{"id": 2, "error": "E"}\n{"id": 9, "pai')
    sink = JsonLinesSink(out)
    assert sink.done == {"0", "1", "2"} and sink.repaired == 3 and sink.previous == 3
    sink.write({"id": 9, "pairs": []})
    sink.close()
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["id"] for r in rows] == [0, 1, 2, 9] and rows[1]["pairs"] == []
    # Errors are kept unless they are to be retried.
    out.write_text('{"id": 1, "pairs": []}\n{"id": 2, "error": "E"}\n')
    sink = JsonLinesSink(out)
    assert sink.done == {"1", "2"} and sink.failed == {"2"}
    sink.write({"id": 3, "error": "E"})
    assert sink.failed == {"2", "3"}
    sink.close()
    sink = JsonLinesSink(out, retry_errors=True)
    assert sink.done == {"1"} and sink.failed == set()
    sink.close()
    assert out.read_text() == '{"id":1,"pairs":[]}\n'


def test_parquet_written_from_its_journal_and_resumed(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    out = tmp_path / "out.parquet"
    sink = open_sink(out)
    sink.write({"id": "a", "pairs": [[0, 1]], "names": [["x", "y"]], "stats": {"bodies": 2}})
    sink.write({"id": "b", "error": "ValueError: bad"})
    assert (tmp_path / "out.parquet.partial.jsonl").exists() and not out.exists()
    sink.close()
    assert not (tmp_path / "out.parquet.partial.jsonl").exists()
    sink = open_sink(out)
    assert sink.done == {'"a"', '"b"'}
    with pytest.raises(ValueError, match="ids of one type"):
        sink.write({"id": 3, "pairs": []})
    sink.write({"id": "c", "pairs": [], "names": [], "stats": {}})
    sink.close()
    rows = pq.read_table(out).to_pylist()
    assert [r["id"] for r in rows] == ["a", "b", "c"]
    assert rows[0]["pairs"] == [[0, 1]] and json.loads(rows[0]["stats"]) == {"bodies": 2}
    assert rows[1]["error"] == "ValueError: bad" and rows[1]["pairs"] is None
    # Rows written without a status (before 0.3) get theirs; error kind and tries are kept.
    assert [r["status"] for r in rows] == ["ok", "error", "ok"]
    sink = open_sink(out)
    assert sink.failed == {'"b"'}
    sink.write({"id": "d", "status": "error", "error": "FileError: x", "error_kind": "input",
                "attempts": 1})
    sink.close()
    d = pq.read_table(out).to_pylist()[-1]
    assert (d["status"], d["error_kind"], d["attempts"]) == ("error", "input", 1)


def test_missing_ray_and_pyarrow_name_the_cluster_extra(tmp_path, monkeypatch, capsys):
    import importlib

    from pycinder.batch import run
    from pycinder.cli import main

    real_import = importlib.import_module

    def fake(name, *args, **kwargs):
        if name.split(".")[0] in ("ray", "pyarrow"):
            raise ImportError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(importlib, "import_module", fake)
    with pytest.raises(ImportError, match=r"needs ray: pip install 'pycinder\[cluster\]'"):
        run([])
    manifest = tmp_path / "m.jsonl"
    manifest.write_text('{"id": 1, "bodies": []}\n')
    assert main(["batch", str(manifest), "--out", str(tmp_path / "o.jsonl")]) == 2
    assert "pip install '.[cluster]'" in capsys.readouterr().err
    assert main(["batch", str(manifest), "--out", str(tmp_path / "o.parquet")]) == 2
    assert "Parquet output of pycinder batch needs pyarrow" in capsys.readouterr().err


def _out(path, rows: list[dict]) -> None:
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))


def test_resumed_run_reports_earlier_errors_and_exits_1(tmp_path, capsys):
    """Every scene already in OUT, one of them an error from an earlier run: the run does
    nothing, says that one failed and how to run it again, and exits 1; with only "ok" rows it
    exits 0. (No scene runs, so no Ray is needed.)"""
    from pycinder.cli import main

    manifest = tmp_path / "m.jsonl"
    manifest.write_text('{"id": 1, "bodies": []}\n{"id": "two", "bodies": []}\n')
    out = tmp_path / "out.jsonl"
    _out(out, [{"id": 1, "status": "ok", "pairs": [], "names": [], "stats": {}},
               {"id": "two", "status": "error", "error": "FileError: gone",
                "error_kind": "input", "attempts": 1},
               {"id": "other", "status": "error", "error": "not in this manifest"}])
    assert main(["batch", str(manifest), "--out", str(out)]) == 1
    captured = capsys.readouterr()
    assert "all 2 scenes already there; 1 of them failed before" in captured.out
    assert "1 scene of the manifest failed in an earlier run" in captured.err
    assert "--retry-errors" in captured.err
    _out(out, [{"id": 1, "status": "ok", "pairs": []}, {"id": "two", "pairs": []}])
    assert main(["batch", str(manifest), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "nothing to do" in captured.out and captured.err == ""


def test_batch_help_documents_rows_and_exit_status(capsys):
    from pycinder.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["batch", "--help"])
    assert stop.value.code == 0
    text = capsys.readouterr().out
    for needle in ('"status": "ok"', '"status": "error"', '"error_kind": "input" | "query" | '
                   '"worker"', '"attempts": N', "exit status:", "0    every scene of MANIFEST "
                   'has an "ok" row', "1    some scenes have error rows in OUT", "2    no run",
                   "130  interrupted"):
        assert needle in text, needle

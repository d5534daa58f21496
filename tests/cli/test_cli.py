"""The pycinder command: exit codes, output, messages, scene files, hostile files, and the debug
buffers of the paper's scene."""

import json
import os
import struct
import subprocess
import sys
import zipfile

import numpy as np
import pytest
import trimesh

from pycinder import Detector, __version__
from pycinder.cli import main
from pycinder.debug.pass_buffers import BufferCapture, three_boxes

T = trimesh.transformations.translation_matrix


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("meshes")
    trimesh.creation.box((1, 1, 1)).export(d / "box.stl")
    ball = trimesh.creation.icosphere(radius=0.4)
    ball.apply_translation((0.6, 0, 0))
    ball.export(d / "ball.obj")
    far = trimesh.creation.icosphere(radius=0.4)
    far.apply_translation((3, 0, 0))
    far.export(d / "far.ply")
    return d


def run_cli(*args, env=None):
    """``python -m pycinder ARGS`` in a fresh process: (exit status, stdout, stderr)."""
    out = subprocess.run([sys.executable, "-m", "pycinder", *map(str, args)],
                         capture_output=True, text=True, env=env)
    return out.returncode, out.stdout, out.stderr


def test_check_exit_codes(files, capsys):
    assert main(["check", str(files / "box.stl"), str(files / "ball.obj"),
                 str(files / "far.ply")]) == 1
    assert "box.stl  <->  ball.obj" in capsys.readouterr().out
    assert main(["check", str(files / "box.stl"), str(files / "far.ply")]) == 0
    assert "no collisions" in capsys.readouterr().out
    assert main(["check", str(files / "missing.stl")]) == 2
    assert "missing.stl: no such file" in capsys.readouterr().err


def test_check_json(files, capsys):
    code = main(["check", "--json", "--tolerance", "0.005", str(files / "box.stl"),
                 str(files / "ball.obj")])
    captured = capsys.readouterr()
    data = json.loads(captured.out)
    assert code == 1 and data["collision"] is True and captured.err == ""
    assert [(p["a"], p["b"]) for p in data["pairs"]] == [("box.stl", "ball.obj")]
    assert data["pairs"][0]["samples"] > 0
    assert data["strategy"] == "focused" and data["tolerance"] == [0.005, 0.005]
    assert data["warnings"] == [] and data["errors"] == []
    code = main(["check", "--json", "--strategy", "scene", "--resolution", "256",
                 str(files / "box.stl"), str(files / "ball.obj")])
    assert code == 1 and json.loads(capsys.readouterr().out)["resolution"] == 256
    assert main(["check", "--resolution", "256", str(files / "box.stl")]) == 2
    assert "--strategy scene" in capsys.readouterr().err
    # The options are checked (by CollisionRequest, in the command line's words) before any
    # file is read.
    assert main(["check", "--json", "--strategy", "scene", "--tolerance", "0.1",
                 str(files / "missing.stl")]) == 2
    assert json.loads(capsys.readouterr().out)["errors"] == [
        "--tolerance applies to --strategy focused; the scene strategy's accuracy is set by its "
        "resolution"]


def test_json_carries_warnings_and_errors(tmp_path, files, capsys):
    box = trimesh.creation.box((1, 1, 1))
    trimesh.Trimesh(box.vertices, box.faces[:-2]).export(tmp_path / "open.stl")
    assert main(["check", "--json", str(tmp_path / "open.stl"), str(files / "far.ply")]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    data = json.loads(captured.out)
    assert data["errors"] == [] and len(data["warnings"]) == 1
    assert data["warnings"][0]["category"] == "OpenMeshWarning"
    assert "open.stl" in data["warnings"][0]["message"]
    assert main(["check", "--json", str(tmp_path / "nothing.stl")]) == 2
    captured = capsys.readouterr()
    assert captured.err == ""
    data = json.loads(captured.out)
    assert data["collision"] is None and data["errors"] == ["nothing.stl: no such file"]


def test_messages_say_what_is_wrong(tmp_path, capsys):
    garbage = tmp_path / "garbage.stl"
    garbage.write_bytes(bytes(range(256)) * 3)
    assert main(["check", str(garbage)]) == 2
    assert "garbage.stl: could not parse it as STL" in capsys.readouterr().err
    empty = tmp_path / "empty.stl"
    empty.write_text("solid nothing\nendsolid\n")
    assert main(["check", str(empty)]) == 2
    assert "empty.stl: holds no triangles" in capsys.readouterr().err
    unknown = tmp_path / "part.step"
    unknown.write_text("ISO-10303-21;")
    assert main(["check", str(unknown)]) == 2
    err = capsys.readouterr().err
    assert "unknown mesh format '.step'" in err
    points = tmp_path / "cloud.xyz"  # trimesh reads point clouds; they are not meshes
    points.write_text("0 0 0\n1 0 0\n0 1 0\n")
    assert main(["check", str(points)]) == 2
    err = capsys.readouterr().err
    assert "unknown mesh format '.xyz'" in err and ".xyz" not in err.split("formats read")[1]
    folder = tmp_path / "parts"
    folder.mkdir()
    assert main(["check", str(folder)]) == 2
    assert "parts: is a directory, not a mesh file" in capsys.readouterr().err
    nan = tmp_path / "nan.obj"
    nan.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n")
    assert main(["check", str(nan)]) == 2
    err = capsys.readouterr().err
    assert "nan.obj: 1 vertex is NaN or infinite (first: vertex 4 on line 4, counting from 1" \
        in err, err


def test_strict_errors_do_not_advise_strict(tmp_path, capsys):
    box = trimesh.creation.box((1, 1, 1))
    trimesh.Trimesh(box.vertices, box.faces[:-2]).export(tmp_path / "open.stl")
    assert main(["check", str(tmp_path / "open.stl")]) == 0
    err = capsys.readouterr().err
    assert "not a closed" in err and "pass --strict" in err and "strict=True" not in err
    assert main(["check", "--strict", str(tmp_path / "open.stl")]) == 2
    err = capsys.readouterr().err
    assert "open.stl" in err and "not a closed" in err and "strict" not in err, err


def two_overlapping_parts():
    """One box geometry placed three times: "left" and "right" overlap by 0.5, "away" is far.
    Only the instance transforms make them overlap."""
    scene = trimesh.Scene()
    box = trimesh.creation.box((1, 1, 1))
    scene.add_geometry(box, node_name="left", geom_name="box")
    scene.add_geometry(box, node_name="right", geom_name="box", transform=T((0.5, 0.2, 0)))
    scene.add_geometry(box, node_name="away", geom_name="box", transform=T((5, 0, 0)))
    return scene


@pytest.mark.parametrize("ext", ["glb", "gltf", "3mf", "obj"])
def test_scene_files_give_one_body_per_part(tmp_path, capsys, ext):
    scene = two_overlapping_parts()
    if ext == "gltf":  # a .gltf with its buffers in files beside it
        for name, data in scene.export(file_type="gltf").items():
            (tmp_path / name).write_bytes(data)
        path = tmp_path / "model.gltf"
    else:
        path = tmp_path / f"parts.{ext}"
        path.write_bytes(scene.export(file_type=ext).encode() if ext == "obj"
                         else scene.export(file_type=ext))
    assert main(["check", "--json", str(path)]) == 1
    data = json.loads(capsys.readouterr().out)
    stem = path.name
    bodies = sorted(data["bodies"])
    assert len(bodies) == 3 and all(b.startswith(f"{stem}:") for b in bodies), bodies
    pairs = [(p["a"], p["b"]) for p in data["pairs"]]
    assert len(pairs) == 1, pairs
    a, b = pairs[0]
    assert "away" not in a + b  # the far instance touches nothing
    if ext != "obj":  # OBJ names objects after their geometry; the others keep node names
        assert {a, b} == {f"{stem}:left", f"{stem}:right"}


def test_file_names_with_any_bytes(tmp_path, files, capsys):
    name = os.fsdecode(b"box-\xff\xfe.stl")
    trimesh.creation.box((1, 1, 1)).export(os.path.join(str(tmp_path), name))
    assert main(["check", os.path.join(str(tmp_path), name), str(files / "ball.obj")]) == 1
    assert "box-\\xff\\xfe.stl  <->  ball.obj" in capsys.readouterr().out
    assert main(["check", "--json", os.path.join(str(tmp_path), name)]) == 0
    assert json.loads(capsys.readouterr().out)["bodies"] == ["box-\\xff\\xfe.stl"]


def test_limits_are_checked_before_loading(tmp_path, files, capsys):
    # An STL whose header claims 2**31 triangles, in 84 bytes.
    claims = tmp_path / "claims.stl"
    claims.write_bytes(b"\0" * 80 + struct.pack("<I", 2**31))
    assert main(["check", str(claims)]) == 2
    assert "claims 2,147,483,648 triangles" in capsys.readouterr().err
    box = str(files / "box.stl")  # 12 triangles, 684 bytes
    assert main(["check", "--max-triangles", "10", box]) == 2
    err = capsys.readouterr().err
    assert "box.stl: its header claims 12 triangles, over the limit of 10" in err
    assert "--max-triangles" in err
    assert main(["check", "--max-file-size", "600", box]) == 2
    assert "box.stl: is 684 bytes, over the limit of 600 bytes (raise it with --max-file-size)" \
        in capsys.readouterr().err
    assert main(["check", "--max-file-size", "1K", "--max-triangles", "12", box]) == 0
    capsys.readouterr()


def test_bad_limit_values_are_usage_errors(files, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["check", "--max-file-size", "lots", str(files / "box.stl")])
    assert exc.value.code == 2
    assert "'lots' is not a size" in capsys.readouterr().err


def test_archive_bombs_are_refused_before_unpacking(tmp_path, capsys):
    # A 3MF package (a zip) whose model claims to unpack to 4 GiB ...
    bomb = tmp_path / "bomb.3mf"
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("3D/3dmodel.model", b"<model/>")
    data = bytearray(bomb.read_bytes())
    central = data.rfind(b"PK\x01\x02")
    data[central + 24:central + 28] = struct.pack("<I", 0xFFFF0000)  # declared size
    bomb.write_bytes(bytes(data))
    assert main(["check", str(bomb)]) == 2
    assert "bomb.3mf: its package unpacks to 4 GiB, over the limit" in capsys.readouterr().err
    # ... and one that really does unpack to far more than it weighs.
    real = tmp_path / "zeros.3mf"
    with zipfile.ZipFile(real, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("3D/3dmodel.model", b"\0" * (24 << 20))
    assert real.stat().st_size < 100_000
    assert main(["check", "--max-file-size", "16M", str(real)]) == 2
    assert "zeros.3mf: its package unpacks to 24 MiB, over the limit of 16 MiB" \
        in capsys.readouterr().err


def test_gltf_claiming_huge_buffers_is_refused(tmp_path, capsys):
    doc = json.dumps({"asset": {"version": "2.0"},
                      "buffers": [{"byteLength": 10 * 2**30}]}).encode()
    doc += b" " * (-len(doc) % 4)
    binary = b"\0" * 8
    glb = b"glTF" + struct.pack("<II", 2, 12 + 8 + len(doc) + 8 + len(binary)) + \
        struct.pack("<I", len(doc)) + b"JSON" + doc + struct.pack("<I", len(binary)) + \
        b"BIN\0" + binary
    (tmp_path / "huge.glb").write_bytes(glb)
    assert main(["check", str(tmp_path / "huge.glb")]) == 2
    assert "huge.glb: buffer 0 claims 10 GiB, but the file's binary chunk holds 8 bytes" \
        in capsys.readouterr().err


def test_progress_bar_when_asked(files, capsys):
    pytest.importorskip("rich", reason="the progress bar is rich's (the demo and bench extras)")
    assert main(["check", "--progress", str(files / "box.stl"), str(files / "far.ply")]) == 0
    captured = capsys.readouterr()
    assert "no collisions" in captured.out and "loading" in captured.err


def test_example_says_it_needs_pillow_before_writing(tmp_path, monkeypatch, capsys):
    for module in ("PIL", "PIL.Image", "PIL.ImageDraw", "PIL.ImageFont"):
        monkeypatch.setitem(sys.modules, module, None)
    assert main(["example", "--out", str(tmp_path)]) == 2
    assert "pillow" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_python_m_pycinder_version_help_and_a_clean_stderr(files):
    """``python -m pycinder`` works; a correct run prints nothing on stderr, even without
    XDG_RUNTIME_DIR (on the backend this suite runs on: WGPU_BACKEND_TYPE is inherited)."""
    code, out, err = run_cli("--version")
    assert code == 0 and out.strip() == f"pycinder {__version__}"
    code, out, err = run_cli("--help")
    assert code == 0 and "``" not in out and out.startswith("usage: pycinder")
    env = {k: v for k, v in os.environ.items() if k != "XDG_RUNTIME_DIR"}
    code, out, err = run_cli("check", files / "box.stl", files / "ball.obj", env=env)
    assert code == 1 and "box.stl  <->  ball.obj" in out
    assert err == "", err


def test_debug_buffers_writes_the_papers_figures(tmp_path):
    assert main(["debug-buffers", "--out", str(tmp_path), "--resolution", "128"]) == 0
    names = sorted(p.name for p in tmp_path.glob("*.png"))
    assert names == ["01_pass1_depth.png", "02_pass2_stencil.png", "03_pass3_stencil.png",
                     "04_pass4_colour.png", "05_pass7_colour.png", "06_filtered_colour.png"]
    for p in tmp_path.glob("*.png"):
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_captured_buffers_follow_the_algorithm():
    """Hand-checked facts of Figures 9-13 on the three boxes."""
    boxes, _, view = three_boxes()
    buf = BufferCapture(Detector(strategy="scene", resolution=256, readback="full",
                                 self_interference="filter")).capture(boxes, view=view)
    depth = buf["pass1_depth"]
    edge = depth > 0
    assert 0.02 < edge.mean() < 0.5                       # only edges are drawn (Figure 9b)
    assert (buf["pass2_stencil"][~edge] == 0).all()       # counting only where edges are (10)
    assert (buf["pass3_stencil"][~edge] == 0).all()
    colour4 = buf["pass4_colour"]
    assert ((colour4[..., 0] != 0) <= (buf["pass3_stencil"] != 0)).all()  # Figure 12
    assert (colour4[..., 1] == 0).all()
    filtered = buf["filtered_colour"]
    ids = {tuple(sorted(p)) for p in filtered[..., :2].reshape(-1, 2).tolist() if p[0]}
    assert ids == {(1, 2), (2, 3)}                        # red-green, green-blue (Figure 13)
    assert (filtered[..., 0] != filtered[..., 1])[filtered[..., 0] > 0].all()


def test_files_in_different_units_are_compared_as_they_are(tmp_path, capsys):
    scene = two_overlapping_parts()
    (tmp_path / "a.glb").write_bytes(scene.export(file_type="glb"))   # glTF: metres
    (tmp_path / "b.3mf").write_bytes(scene.export(file_type="3mf"))   # 3MF: millimetres
    assert main(["check", str(tmp_path / "a.glb"), str(tmp_path / "b.3mf")]) == 1
    captured = capsys.readouterr()
    assert "a.glb:left  <->  b.3mf:left" in captured.out  # the same coordinates, unconverted
    assert "different units (a.glb in meters, b.3mf in millimeter)" in captured.err


def test_demo_prints_progress_while_it_runs(capsys):
    assert main(["demo", "stairs", "--frames", "3", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "stairs: frame 1/3" in out and "stairs: frame 3/3" in out
    assert "stairs: 3 frames" in out  # and the summary at the end


def _pipe(centre, radius=0.05, length=1.0):
    """A pipe along y (a 32-sided prism: its extent along x and z is exactly ``radius``)."""
    pipe = trimesh.creation.cylinder(radius=radius, height=length, sections=32)
    pipe.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))
    return pipe.apply_translation(centre)


@pytest.fixture(scope="module")
def beam_and_pipes(tmp_path_factory):
    """A beam 4 x 0.3 x 0.4 m about the origin (its top at z = 0.2) and three pipes across it:
    one through it 0.2 m deep (the shortest way out is up: 0.05 + 0.15), one resting on its top
    (touching along a line), one 1 mm into its top."""
    d = tmp_path_factory.mktemp("pipes")
    trimesh.creation.box((4, 0.3, 0.4)).export(d / "beam.stl")
    _pipe((-1, 0, 0.05)).export(d / "through.stl")
    _pipe((0, 0, 0.25)).export(d / "resting.stl")
    _pipe((1, 0, 0.249)).export(d / "grazing.stl")
    return [d / n for n in ("beam.stl", "through.stl", "resting.stl", "grazing.stl")]


def test_check_min_depth_reports_hard_clashes_with_their_depth(beam_and_pipes, capsys):
    """--min-depth D: the pipe through the beam, with its depth; never the pipe resting on it
    (touching) nor the one 1 mm into it (at most D/2 deep)."""
    code = main(["check", "--json", "--min-depth", "0.01", *map(str, beam_and_pipes)])
    report = json.loads(capsys.readouterr().out)
    assert code == 1 and report["mode"] == "min_depth" and report["errors"] == []
    [pair] = report["pairs"]
    assert (pair["a"], pair["b"]) == ("beam.stl", "through.stl")
    # An upper bound of the penetration depth, within its error bound; exact here (up to
    # rounding: STL holds float32), the beam and the pipe lying along the world's axes.
    assert 0 <= pair["depth_error"] < pair["depth"]
    assert pair["depth"] - pair["depth_error"] <= 0.2 <= pair["depth"] + 1e-5
    assert pair["depth"] == pytest.approx(0.2, abs=1e-5)
    assert "distance" not in pair
    assert main(["check", "--min-depth", "0.01", *map(str, beam_and_pipes)]) == 1
    [line] = capsys.readouterr().out.strip().splitlines()
    assert line.startswith("beam.stl  <->  through.stl  depth 0.2")
    # The pipes that touch or graze alone: nothing to report.
    assert main(["check", "--min-depth", "0.01", *map(str, beam_and_pipes[::2]),
                 str(beam_and_pipes[3])]) == 0
    assert capsys.readouterr().out.strip() == "no collisions"
    # Where the default contract may report the touching pair, --min-depth never does.
    assert main(["check", "--json", "--min-depth", "0.001",
                 *map(str, beam_and_pipes[::2])]) == 0
    assert json.loads(capsys.readouterr().out)["pairs"] == []


def test_check_min_depth_usage_errors(beam_and_pipes, capsys):
    beam, through = map(str, beam_and_pipes[:2])
    assert main(["check", "--min-depth", "0.01", "--strategy", "scene", beam, through]) == 2
    assert "--min-depth applies to --strategy focused" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # argparse: one mode at most, a positive distance
        main(["check", "--min-depth", "0.01", "--clearance", "0.1", beam, through])
    assert "not allowed with argument" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["check", "--min-depth", "-1", beam, through])
    assert "is not a positive distance" in capsys.readouterr().err


def test_result_report_is_check_json():
    """``CollisionResult.report``, which ``check --json`` prints, by hand: samples counted per
    pair from the records (either body first), figures added, the strategy's own keys."""
    from pycinder import RECORD_DTYPE, CollisionResult, Stats

    rec = np.zeros(4, RECORD_DTYPE)
    rec["penetrating"], rec["penetrated"] = [0, 2, 0, 1], [2, 0, 2, 3]
    stats = Stats(strategy="focused", adapter="test", bodies=4)
    stats.candidates = 3
    result = CollisionResult(np.array([[0, 1], [0, 2]]), rec, stats)
    assert result.pair_samples().tolist() == [0, 3]
    report = result.report(["a", "b", "c", "d"], tolerance_range=[0.5, 1.0])
    assert report == {
        "collision": True,
        "pairs": [{"a": "a", "b": "b", "samples": 0}, {"a": "a", "b": "c", "samples": 3}],
        "bodies": ["a", "b", "c", "d"], "strategy": "focused", "tolerance": [0.5, 1.0],
        "candidates": 3, "adapter": "test", "warnings": [], "errors": []}
    assert list(report) == ["collision", "pairs", "bodies", "strategy", "tolerance",
                            "candidates", "adapter", "warnings", "errors"]
    result.depths, result.depth_errors = np.array([0.25, 0.5]), np.array([0.01, 0.02])
    report = result.report(mode="min_depth", warnings=[{"category": "W", "message": "m"}])
    assert report["bodies"] == ["0", "1", "2", "3"]  # no names: the bodies' indices
    assert report["pairs"][1] == {"a": "0", "b": "2", "samples": 3, "depth": 0.5,
                                  "depth_error": 0.02}
    assert report["tolerance"] is None and report["mode"] == "min_depth"
    assert report["warnings"] == [{"category": "W", "message": "m"}]
    scene = CollisionResult.empty(Stats(strategy="scene", adapter="test"))
    scene.stats.resolution = (128, 128)
    assert scene.report([]) == {"collision": False, "pairs": [], "bodies": [],
                                "strategy": "scene", "resolution": 128, "adapter": "test",
                                "warnings": [], "errors": []}

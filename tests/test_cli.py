"""The pycinder command: exit codes, output, and the debug buffers of the paper's scene."""

import json
import subprocess
import sys

import pytest
import trimesh

from pycinder.cli import main
from pycinder.debug import BufferCapture, three_boxes
from pycinder import Detector


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


def test_check_exit_codes(files, capsys):
    assert main(["check", str(files / "box.stl"), str(files / "ball.obj"), str(files / "far.ply")]) == 1
    assert "box.stl  <->  ball.obj" in capsys.readouterr().out
    assert main(["check", str(files / "box.stl"), str(files / "far.ply")]) == 0
    assert "no collisions" in capsys.readouterr().out
    assert main(["check", str(files / "missing.stl")]) == 2
    assert "missing.stl" in capsys.readouterr().err


def test_check_json(files, capsys):
    code = main(["check", "--json", "--tolerance", "0.005", str(files / "box.stl"),
                 str(files / "ball.obj")])
    data = json.loads(capsys.readouterr().out)
    assert code == 1 and data["collision"] is True
    assert [(p["a"], p["b"]) for p in data["pairs"]] == [("box.stl", "ball.obj")]
    assert data["pairs"][0]["samples"] > 0
    assert data["strategy"] == "focused" and data["tolerance"] == [0.005, 0.005]
    code = main(["check", "--json", "--strategy", "scene", "--resolution", "256",
                 str(files / "box.stl"), str(files / "ball.obj")])
    assert code == 1 and json.loads(capsys.readouterr().out)["resolution"] == 256
    assert main(["check", "--resolution", "256", str(files / "box.stl")]) == 2
    assert "--strategy scene" in capsys.readouterr().err


def test_check_bad_file_is_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.stl"
    bad.write_text("solid nothing\nendsolid\n")
    assert main(["check", str(bad)]) == 2
    unknown = tmp_path / "part.step"
    unknown.write_text("ISO-10303-21;")
    assert main(["check", str(unknown)]) == 2
    assert "unknown mesh format '.step'" in capsys.readouterr().err
    nan = tmp_path / "nan.obj"
    nan.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n")
    assert main(["check", str(nan)]) == 2
    assert "nan.obj: 1 vertices are NaN" in capsys.readouterr().err


def test_check_open_mesh_names_the_cli_option(tmp_path, capsys):
    box = trimesh.creation.box((1, 1, 1))
    trimesh.Trimesh(box.vertices, box.faces[:-2]).export(tmp_path / "open.stl")
    assert main(["check", str(tmp_path / "open.stl")]) == 0
    err = capsys.readouterr().err
    assert "not a closed" in err and "--strict" in err and "strict=True" not in err
    assert main(["check", "--strict", str(tmp_path / "open.stl")]) == 2
    assert "--strict" in capsys.readouterr().err


def test_console_script_runs(files):
    out = subprocess.run([sys.executable, "-m", "pycinder.cli", "check", str(files / "box.stl"),
                          str(files / "ball.obj")], capture_output=True, text=True)
    assert out.returncode == 1, out.stderr


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

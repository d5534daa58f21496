"""The CLI's rough edges (issue 26, item 6): every bad file reported, singular and plural, the
JSON's tolerance and resolution, duplicate names, 3MF without lxml, demo output paths, help text,
open meshes in the help, bodies whose disconnected components overlap (``--split``), and
``bench`` outside a checkout of the repository.

Expectations are worked out by hand from the meshes each test makes."""

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from pycinder import cli
from pycinder.cli import build_parser, main
from pycinder.demos.output import FrameWriter, output_kind
from pycinder.files import file_labels, plural

T = trimesh.transformations.translation_matrix


def box(size=1.0, at=(0, 0, 0)):
    return trimesh.creation.box((size, size, size), T(at))


def check_json(capsys, *args):
    """``pycinder check --json ARGS``: (exit status, the parsed JSON, stderr)."""
    code = main(["check", "--json", *map(str, args)])
    captured = capsys.readouterr()
    return code, json.loads(captured.out), captured.err


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    d = tmp_path_factory.mktemp("edges")
    box().export(d / "a.stl")
    (d / "empty.stl").write_bytes(b"")
    (d / "text.stl").write_text("hello\n")  # 6 bytes, not 'solid'
    # One file, two boxes overlapping by half (x from -0.5 to 0.5 and from 0 to 1).
    trimesh.util.concatenate([box(), box(at=(0.5, 0, 0))]).export(d / "two.stl")
    return d


# -- every bad file is reported -------------------------------------------------------------


def test_every_bad_file_is_reported_and_nothing_is_checked(meshes, capsys):
    files = [meshes / "missing.stl", meshes / "empty.stl", meshes / "a.stl", meshes / "text.stl"]
    assert main(["check", *map(str, files)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # nothing checked: a partial answer could hide a collision
    errors = [line for line in captured.err.splitlines() if line.startswith("pycinder: error:")]
    assert errors == [
        "pycinder: error: missing.stl: no such file",
        "pycinder: error: empty.stl: is empty",
        "pycinder: error: text.stl: could not parse it as STL: 6 bytes are too few for a binary "
        "STL and it does not start with 'solid' as a text STL does"]
    code, data, err = check_json(capsys, *files)
    assert code == 2 and err == "" and data["collision"] is None and data["pairs"] == []
    assert len(data["errors"]) == 3
    assert [e.split(":")[0] for e in data["errors"]] == ["missing.stl", "empty.stl", "text.stl"]


def test_one_byte_file_is_singular(tmp_path, capsys):
    (tmp_path / "x.stl").write_bytes(b"x")
    code, data, _ = check_json(capsys, tmp_path / "x.stl")
    assert code == 2
    assert data["errors"] == ["x.stl: could not parse it as STL: 1 byte is too few for a binary "
                              "STL and it does not start with 'solid' as a text STL does"]


# -- singular and plural --------------------------------------------------------------------


@pytest.mark.parametrize("n, word, many, text", [
    (1, "body", None, "1 body"), (2, "body", None, "2 bodies"), (0, "body", None, "0 bodies"),
    (1, "candidate pair", None, "1 candidate pair"), (3, "candidate pair", None,
                                                      "3 candidate pairs"),
    (1, "name", None, "1 name"), (2, "name", None, "2 names"), (1, "day", None, "1 day"),
    (2, "day", None, "2 days"), (1234, "tile", None, "1,234 tiles"),
    (1, "vertex", "vertices", "1 vertex"), (5, "vertex", "vertices", "5 vertices")])
def test_plural(n, word, many, text):
    assert plural(n, word, many) == text


def test_example_counts_in_words(tmp_path, capsys):
    """The three boxes: red-green and green-blue overlap; red and blue are 1.2 apart in z, more
    than the boxes' size 1, so the broad phase passes on exactly 2 candidate pairs."""
    pytest.importorskip("PIL")
    assert main(["example", "--out", str(tmp_path), "--resolution", "64", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "2 candidate pairs, " in out
    assert "  red <-> green" in out and "  green <-> blue" in out


def test_demo_summary_of_one_frame(capsys):
    assert main(["demo", "stairs", "--frames", "1", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "stairs: 1 frame;" in out and "1 frames" not in out


# -- the JSON's tolerance and resolution ----------------------------------------------------


def test_json_tolerance_without_candidate_pairs(tmp_path, capsys):
    """Boxes of sides 1, 2 and 4 far apart: no candidate pair. A pair's default tolerance is 1%
    of its smaller body's diagonal, side * sqrt(3): the smallest over the pairs is the 1-box's,
    the largest the 2-box's (the pair of the 2-box and the 4-box)."""
    for name, size, x in (("one.stl", 1, 0), ("two.stl", 2, 10), ("four.stl", 4, 20)):
        box(size, (x, 0, 0)).export(tmp_path / name)
    paths = [tmp_path / n for n in ("four.stl", "one.stl", "two.stl")]
    code, data, _ = check_json(capsys, *paths)
    assert code == 0 and data["candidates"] == 0 and data["collision"] is False
    assert data["tolerance"] == pytest.approx([0.01 * math.sqrt(3), 0.02 * math.sqrt(3)])
    assert "resolution" not in data  # the focused strategy has no image size
    code, data, _ = check_json(capsys, "--tolerance", "0.05", *paths)
    assert code == 0 and data["tolerance"] == [0.05, 0.05]
    code, data, _ = check_json(capsys, paths[0])  # one body: no pair, no tolerance
    assert code == 0 and data["tolerance"] is None and data["bodies"] == ["four.stl"]


def test_json_of_the_scene_strategy_has_no_tolerance(meshes, tmp_path, capsys):
    box(at=(5, 0, 0)).export(tmp_path / "far.stl")
    code, data, _ = check_json(capsys, "--strategy", "scene", "--resolution", "128",
                               meshes / "a.stl", tmp_path / "far.stl")
    assert code == 0 and data["resolution"] == 128 and data["strategy"] == "scene"
    assert "tolerance" not in data and "candidates" not in data


def test_json_schema_is_in_the_help(capsys):
    with pytest.raises(SystemExit):
        main(["check", "--help"])
    out = capsys.readouterr().out
    for key in ("collision", "pairs", "bodies", "strategy", "tolerance", "candidates",
                "resolution", "adapter", "warnings", "errors"):
        assert f"\n  {key} " in out, key
    assert "null with fewer than two bodies" in out


# -- duplicate names ------------------------------------------------------------------------


def test_a_file_given_twice_gets_numbered_names(meshes, capsys):
    a = str(meshes / "a.stl")
    assert main(["check", a, a]) == 1
    assert capsys.readouterr().out.splitlines() == ["a.stl#1  <->  a.stl#2"]
    code, data, _ = check_json(capsys, a, a)
    assert code == 1 and data["bodies"] == ["a.stl#1", "a.stl#2"]
    assert [(p["a"], p["b"]) for p in data["pairs"]] == [("a.stl#1", "a.stl#2")]


def test_file_labels():
    assert file_labels(["x/a.stl", "b.stl"]) == ["a.stl", "b.stl"]
    assert file_labels(["x/a.stl", "y/a.stl"]) == ["x/a.stl", "y/a.stl"]
    assert file_labels(["a.stl", "b.stl", "a.stl", "y/a.stl"]) == [
        "a.stl#1", "b.stl", "a.stl#2", "y/a.stl"]


# -- 3MF without lxml -----------------------------------------------------------------------


def test_3mf_without_lxml_names_the_file(tmp_path, monkeypatch, capsys):
    pytest.importorskip("lxml")  # to write the file
    scene = trimesh.Scene()
    scene.add_geometry(box(), node_name="part")
    (tmp_path / "parts.3mf").write_bytes(scene.export(file_type="3mf"))
    monkeypatch.setitem(sys.modules, "lxml", None)  # as if it were not installed
    code, data, _ = check_json(capsys, tmp_path / "parts.3mf", tmp_path / "gone.stl")
    assert code == 2
    assert data["errors"] == [
        "parts.3mf: reading 3MF files needs lxml: pip install 'pycinder[files]' (from a clone: "
        "pip install '.[files]')",
        "gone.stl: no such file"]


# -- demo output paths ----------------------------------------------------------------------


def test_demo_refuses_a_video_suffix_it_cannot_write(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main(["demo", "stairs", "--frames", "1", "--out", "st.avi"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "st.avi: cannot write .avi videos" in err and ".mp4 or .gif" in err
    assert list(tmp_path.iterdir()) == []  # no folder named st.avi


def test_output_kind(tmp_path):
    assert output_kind(tmp_path / "run.mp4") == ".mp4"
    assert output_kind(tmp_path / "RUN.GIF") == ".gif"
    assert output_kind(tmp_path / "frames") == "folder"
    assert output_kind(f"{tmp_path}/frames.v2/") == "folder"  # a trailing slash asks for one
    (tmp_path / "old.avi").mkdir()
    assert output_kind(tmp_path / "old.avi") == "folder"  # a folder that is there
    for bad in ("st.avi", "st.mov", "frames.v2"):
        with pytest.raises(ValueError, match=r"cannot write \.\w+ videos.*\.mp4 or \.gif"):
            output_kind(tmp_path / bad)
        with pytest.raises(ValueError):
            FrameWriter(tmp_path / bad)
        assert not (tmp_path / bad).exists()


def test_demo_writes_png_frames_to_a_folder(tmp_path, capsys):
    pytest.importorskip("pygfx", reason="the demos draw with pygfx (the demo and test extras)")
    assert main(["demo", "stairs", "--frames", "2", "--no-progress", "--out",
                 str(tmp_path / "frames")]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == [
        "frame_0000.png", "frame_0001.png"]


# -- help text ------------------------------------------------------------------------------


def _commands() -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices


@pytest.mark.parametrize("command", ["check", "debug-buffers", "demo", "bench", "example"])
def test_every_option_has_help(command):
    parser = _commands()[command]
    missing = [a.dest for a in parser._actions if not a.help]
    assert missing == [], f"{command}: {missing}"


def test_example_and_debug_buffers_options_have_help():
    commands = _commands()
    for command, options in (("example", ("--out", "--resolution")),
                             ("debug-buffers", ("--out", "--resolution", "--self-interference"))):
        text = commands[command].format_help()
        for option in options:
            action = next(a for a in commands[command]._actions if option in a.option_strings)
            assert action.help and len(action.help) > 20, (command, option)
        assert "width and height in pixels" in text
    assert "filter (default)" in commands["debug-buffers"].format_help()


def test_help_says_open_meshes_are_surfaces(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "closed triangle meshes" not in out
    assert "closed meshes are tested as solids, open ones as surfaces" in out
    assert "open ones as surfaces" in " ".join(cli.__doc__.split())


# -- disconnected components ----------------------------------------------------------------


def test_overlapping_components_are_named_without_split(meshes, capsys):
    two = meshes / "two.stl"
    assert main(["check", str(two)]) == 0
    captured = capsys.readouterr()
    assert captured.out == "no collisions\n"
    assert "warning: two.stl: 2 disconnected components, of which 1 pair overlaps ([0] and " \
           "[1])" in captured.err and "--split" in captured.err
    code, data, err = check_json(capsys, two)
    assert code == 0 and err == ""
    assert [w["category"] for w in data["warnings"]] == ["OverlappingComponentsWarning"]
    assert data["warnings"][0]["message"].startswith("two.stl: 2 disconnected components")


def test_split_makes_components_bodies(meshes, capsys):
    two = meshes / "two.stl"
    assert main(["check", "--split", str(two)]) == 1
    captured = capsys.readouterr()
    assert captured.out.splitlines() == ["two.stl[0]  <->  two.stl[1]"]
    assert captured.err == ""
    code, data, _ = check_json(capsys, "--split", two, meshes / "a.stl")
    # a.stl (x from -0.5 to 0.5) overlaps both boxes of two.stl
    assert code == 1 and data["bodies"] == ["two.stl[0]", "two.stl[1]", "a.stl"]
    assert data["warnings"] == []
    assert sorted((p["a"], p["b"]) for p in data["pairs"]) == [  # in the bodies' order
        ("two.stl[0]", "a.stl"), ("two.stl[0]", "two.stl[1]"), ("two.stl[1]", "a.stl")]


def test_a_component_inside_another_is_named(tmp_path, capsys):
    """A box of side 0.5 wholly inside a box of side 2: no surfaces cross, but solids overlap."""
    trimesh.util.concatenate([box(2), box(0.5)]).export(tmp_path / "nested.stl")
    code, data, _ = check_json(capsys, tmp_path / "nested.stl")
    assert code == 0
    assert [w["category"] for w in data["warnings"]] == ["OverlappingComponentsWarning"]
    assert "([0] and [1])" in data["warnings"][0]["message"]


def test_apart_components_and_cavities_are_not_named(tmp_path, capsys):
    # Two boxes 3 apart: their bounding boxes do not even meet.
    trimesh.util.concatenate([box(), box(at=(3, 0, 0))]).export(tmp_path / "apart.stl")
    # A ball of radius 1 and a box of side 0.2 at (0.9, 0.9, 0.9): the box's bounding box is
    # inside the ball's, but the box is outside the ball (its nearest corner is 1.39 from the
    # centre): pycinder itself must tell.
    corner = trimesh.util.concatenate([trimesh.creation.icosphere(radius=1.0),
                                       box(0.2, (0.9, 0.9, 0.9))])
    corner.export(tmp_path / "corner.stl")
    # A hollow box: the cavity is an inside-out box within the outer one.
    cavity = box(1)
    cavity.invert()
    trimesh.util.concatenate([box(2), cavity]).export(tmp_path / "hollow.stl")
    for name in ("apart.stl", "corner.stl", "hollow.stl"):
        code, data, _ = check_json(capsys, tmp_path / name)
        assert code == 0, name
        categories = [w["category"] for w in data["warnings"]]
        assert "OverlappingComponentsWarning" not in categories, (name, data["warnings"])


def test_boxes_meeting():
    import numpy as np

    from pycinder.files import boxes_meeting

    lo = np.array([[0, 0, 0], [2, 0, 0], [0.5, 0.5, 0.5], [0, 5, 0]], float)
    hi = lo + 1  # unit boxes: the first and third meet; the second and fourth meet nothing
    assert boxes_meeting(lo, hi).tolist() == [True, False, True, False]
    assert boxes_meeting(lo[:1], hi[:1]).tolist() == [False]


def test_components_in_file_order():
    from pycinder.files import components

    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.2)  # 320 triangles
    ball.apply_translation((5, 0, 0))
    mesh = trimesh.util.concatenate([box(), ball, box(at=(0.5, 0, 0))])
    mesh.merge_vertices()
    assert [len(p.faces) for p in components(mesh)] == [12, 320, 12]
    assert components(box())[0].faces.shape == (12, 3)


def test_component_labels_need_no_scipy() -> None:
    """Components in NumPy alone (the base install has no SciPy): by hand, and against SciPy's
    connected components on random graphs."""
    import scipy.sparse
    import scipy.sparse.csgraph

    from pycinder.files import component_labels

    assert component_labels(np.array([[0, 1], [3, 2], [4, 3]]), 6).tolist() == [0, 0, 2, 2, 2, 5]
    assert component_labels(np.zeros((0, 2), int), 3).tolist() == [0, 1, 2]
    rng = np.random.default_rng(3)
    for n, e in ((40, 20), (200, 150), (300, 600)):
        links = rng.integers(0, n, (e, 2))
        graph = scipy.sparse.coo_matrix((np.ones(e), links.T), shape=(n, n))
        count, truth = scipy.sparse.csgraph.connected_components(graph, directed=False)
        got = component_labels(links, n)
        assert len(set(zip(got.tolist(), truth.tolist()))) == count == len(np.unique(got))


# -- bench runs from a checkout -------------------------------------------------------------


@pytest.fixture
def no_harness(monkeypatch):
    """As if the harness (the checkout's top-level package ``benchmarks``) had not been
    imported and were not importable as it is: its modules out of ``sys.modules`` (put back
    after) and the checkout's root off ``sys.path``. Yields the checkout's root."""
    import pycinder

    root = Path(pycinder.__file__).resolve().parents[2]
    saved = {k: v for k, v in sys.modules.items() if k.split(".")[0] == "benchmarks"}
    for name in saved:
        del sys.modules[name]
    monkeypatch.setattr(sys, "path", [p for p in sys.path if Path(p or ".").resolve() != root])
    yield root
    for name in [k for k in sys.modules if k.split(".")[0] == "benchmarks"]:
        del sys.modules[name]
    sys.modules.update(saved)


def test_bench_finds_the_harness_of_its_checkout(no_harness):
    from pycinder.cli import bench

    assert bench.checkout_root() == no_harness
    runner, report = bench.load_harness()
    assert Path(runner.__file__).resolve() == no_harness / "benchmarks" / "runner.py"
    assert Path(report.__file__).resolve() == no_harness / "benchmarks" / "report.py"
    assert sys.path[0] == str(no_harness) and runner.DEFAULT_SCENES


def test_bench_outside_a_checkout_says_where_to_run_it(no_harness, tmp_path, monkeypatch,
                                                       capsys):
    """Installed from a wheel (site-packages/pycinder): no checkout, exit 2 and what to do."""
    from pycinder.cli import bench

    monkeypatch.setattr(bench, "package_dir", lambda: tmp_path / "site-packages" / "pycinder")
    assert bench.checkout_root() is None
    assert main(["bench", "stairs", "--repeat", "1"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    err = " ".join(captured.err.split())
    assert err.startswith("pycinder: error: the benchmarks are not in the wheel")
    assert str(tmp_path / "site-packages" / "pycinder") in err
    assert "pip install -e \".[bench]\"" in err and "pycinder bench (or make bench)" in err
    assert "benchmarks" not in sys.modules


def test_checkout_root_needs_the_harness_and_pyproject(tmp_path):
    from pycinder.cli.bench import checkout_root

    package = tmp_path / "src" / "pycinder"
    package.mkdir(parents=True)
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "benchmarks" / "runner.py").write_text("")
    assert checkout_root(package) is None  # no pyproject.toml
    (tmp_path / "pyproject.toml").write_text("")
    assert checkout_root(package) == tmp_path
    (tmp_path / "benchmarks" / "runner.py").unlink()
    assert checkout_root(package) is None

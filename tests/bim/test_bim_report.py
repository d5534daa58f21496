"""Clashes grouped, pictured and tracked: pycinder.bim.groups, .snapshot, .tracking, .report and
``pycinder check --group-distance / --snapshots / --against`` on generated buildings."""

from __future__ import annotations

import io
import json
import re
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("ifcopenshell", reason="IFC needs ifcopenshell: pip install 'pycinder[bim]'")
pytest.importorskip("scipy", reason="grouping needs scipy: pip install 'pycinder[bim]'")

from benchmarks import building as B  # noqa: E402
from pycinder.bim import ifc  # noqa: E402
from pycinder.bim.groups import group_clashes, pair_key, topic_guid  # noqa: E402
from pycinder.bim.tracking import track  # noqa: E402
from pycinder.cli import main  # noqa: E402
from pycinder.util.environ import path_first  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]

# -- grouping, by hand ----------------------------------------------------------------------


def _fake(a: str, b: str, point: tuple[float, float, float], classes=("IfcWall", "IfcWall"),
          storeys=("", "")) -> types.SimpleNamespace:
    def body(gid: str, ifc_class: str, storey: str) -> types.SimpleNamespace:
        return types.SimpleNamespace(file="f.ifc", global_id=gid, ifc_class=ifc_class,
                                     element_name=gid, name=gid, storey=storey)

    return types.SimpleNamespace(a=body(a, classes[0], storeys[0]),
                                 b=body(b, classes[1], storeys[1]), point=np.array(point, float))


def _partition(groups) -> list[list[tuple[str, str]]]:
    return sorted(sorted(pair_key(c.a.global_id, c.b.global_id) for c in g.clashes)
                  for g in groups)


def test_groups_by_element_and_by_distance_by_hand():
    """AB and BC share B, 10 m apart; DE is 1.5 m from AB; FG 50 m from everything."""
    clashes = [_fake("A", "B", (0, 0, 0)), _fake("B", "C", (10, 0, 0)),
               _fake("D", "E", (1.5, 0, 0)), _fake("F", "G", (50, 0, 0))]
    ab, bc, de, fg = ("A", "B"), ("B", "C"), ("D", "E"), ("F", "G")
    assert _partition(group_clashes(clashes, 0)) == [[ab, bc], [de], [fg]]
    assert _partition(group_clashes(clashes, by="element")) == [[ab, bc], [de], [fg]]
    assert _partition(group_clashes(clashes, 1.0)) == [[ab], [bc], [de], [fg]]
    assert _partition(group_clashes(clashes, 2.0)) == [[ab, de], [bc], [fg]]
    assert _partition(group_clashes(clashes, None)) == [[ab], [bc], [de], [fg]]
    assert _partition(group_clashes(clashes, None, by="element")) == [[ab], [bc], [de], [fg]]
    # Neither the order nor the numbering changes the groups; keys and GUIDs follow GlobalIds.
    assert _partition(group_clashes(clashes[::-1], 2.0)) == [[ab, de], [bc], [fg]]
    first = group_clashes(clashes, 2.0)[0]
    assert first.index == 1 and first.key == ab and first.guid == topic_guid(ab)
    assert [b.global_id for b in first.elements] == ["A", "B", "D", "E"]
    assert first.title() == "IfcWall/A and IfcWall/B (+1 clash)"
    with pytest.raises(ValueError, match="grouping distance"):
        group_clashes(clashes, -1.0)
    with pytest.raises(ValueError, match="grouped by one of distance, element, storey, "
                       "classes"):
        group_clashes(clashes, by="colour")


def test_groups_by_distance_span_at_most_the_distance():
    """Clashes 1 m apart along a line (a chain that single linkage at 2 m takes whole): every
    group's clashes lie at most 2 m apart, in whichever order they come; thirty clashes at one
    spot make groups of at most a tenth of them (three), nineteen one group."""
    line = [_fake(f"A{k}", f"B{k}", (float(k), 0, 0)) for k in range(9)]
    groups = group_clashes(line, 2.0)
    for g in groups:
        x = [float(c.point[0]) for c in g.clashes]
        assert max(x) - min(x) <= 2.0
    assert len(groups) >= 3 and sum(len(g.clashes) for g in groups) == 9
    assert _partition(group_clashes(line[::-1], 2.0)) == _partition(groups)
    spot = [_fake(f"A{k}", f"B{k}", (0.0, 0.0, 0.01 * k)) for k in range(30)]
    assert [len(g.clashes) for g in group_clashes(spot)] == [3] * 10
    assert [len(g.clashes) for g in group_clashes(spot[:19])] == [19]  # under twenty: no cap


def test_groups_by_storey_and_by_classes():
    clashes = [_fake("A", "B", (0, 0, 0), ("IfcWall", "IfcDuctSegment"), ("Level 1", "")),
               _fake("C", "D", (90, 0, 0), ("IfcDuctSegment", "IfcWall"), ("", "Level 1")),
               _fake("E", "F", (0, 0, 0), ("IfcBeam", "IfcDuctSegment"), ("Level 2", "Level 2")),
               _fake("G", "H", (5, 0, 0), ("IfcBeam", "IfcPipeSegment"), ("", ""))]
    ab, cd, ef, gh = ("A", "B"), ("C", "D"), ("E", "F"), ("G", "H")
    assert _partition(group_clashes(clashes, by="storey")) == [[ab, cd], [ef], [gh]]
    assert _partition(group_clashes(clashes, by="classes")) == [[ab, cd], [ef], [gh]]


def test_a_picture_that_cannot_be_rendered_leaves_the_bcf_file_without_pictures(monkeypatch,
                                                                               tmp_path):
    """Pictures for the BCF file are a bonus: when rendering fails, the topics are written
    without them and a warning says why; pictures asked for with --snapshots fail the run."""
    from pycinder.bim import bcf, report

    def broken(*args, **kwargs):
        raise RuntimeError("no adapter for pygfx")

    written = {}
    monkeypatch.setattr(report, "_pictures", broken)
    monkeypatch.setattr(bcf, "write_bcf", lambda clashes, path, **kw: written.update(kw))
    clashes = [_fake("A", "B", (0, 0, 0))]
    model = types.SimpleNamespace(bodies=[])
    with pytest.warns(UserWarning, match="could not be rendered.*no adapter for pygfx"):
        report.clash_report(model, clashes, bcf=tmp_path / "out.bcf")
    assert written["snapshots"] == {} and len(written["groups"]) == 1
    with pytest.raises(RuntimeError, match="no adapter"):
        report.clash_report(model, clashes, snapshots=tmp_path / "pictures")


def test_the_same_globalids_clashing_twice_get_topics_of_their_own():
    """A model checked against its revised copy: one GlobalId pair clashes in two places, 100 m
    apart. Each group's topic has its own GUID, and the first keeps the unsalted one."""
    twice = [_fake("A", "B", (0, 0, 0)), _fake("A", "B", (100, 0, 0))]
    for b in (twice[1].a, twice[1].b):
        b.file = "copy.ifc"
    groups = group_clashes(twice, 1.0)
    assert len(groups) == 2 and groups[0].guid == topic_guid(("A", "B"))
    assert len({g.guid for g in groups}) == 2


def test_track_by_hand():
    """A previous run's topics: {AB, BC} and {FG}; now AB (with a new HI beside it) and DE."""
    ab, bc, fg = ("A", "B"), ("B", "C"), ("F", "G")
    previous = read_previous_from({"g1": [ab, bc], "g2": [fg]})
    now = group_clashes([_fake("A", "B", (0, 0, 0)), _fake("H", "I", (0.5, 0, 0)),
                         _fake("D", "E", (30, 0, 0))], 1.0)
    t = track(now, previous, source="before.json")
    assert t.clashes == {ab: "active", ("H", "I"): "new", ("D", "E"): "new"}
    assert set(t.resolved) == {bc, fg} and t.counts() == {"new": 2, "active": 1, "resolved": 2}
    assert [(g.guid, g.status, g.resolved) for g in now] == [
        ("g1", "active", [bc]), (topic_guid(("D", "E")), "new", [])]
    assert [(x.guid, x.status, list(x.pairs)) for x in t.closed] == [("g2", "resolved", [fg])]


def read_previous_from(topics: dict[str, list[tuple[str, str]]]):
    from pycinder.bim.tracking import PreviousTopic

    return [PreviousTopic(guid, guid, "active", {p: "" for p in pairs})
            for guid, pairs in topics.items()]


# -- on generated buildings -----------------------------------------------------------------


def _pipe(name: str, gid: str, lo, hi) -> B.Part:
    assert len(gid) == 22
    return B.Part("IfcPipeSegment", name, gid, tuple(map(float, lo)), tuple(map(float, hi)),
                  axis=1, radius=0.05, cell=0, discipline="mep")


# Cell 0 (origin 0): "Pipe through beam 0" runs along y at x = 4, z = 2.6 through the south
# beam (x 0.3..5.7, y 0..0.3, z 2.4..2.8). Added: a second pipe through that beam at x = 2
# (sharing the beam), and a pipe into column 1 (x 5.7..6, y 0..0.3) at z = 1, whose clash
# point (5.85, 0.125, 1.0) is 2.34 m from the first pipe's (4.0, 0.15, 2.6) and 4.1 m from the
# second's; the nearest other clash (cell 1's duct into its beam, about (10, 0.15, 2.4)) is 6 m
# away. Cell 5 (origin (8, 8)) has no hard clash; the second run adds a pipe through its south
# beam (x 8.3..13.7, y 8..8.3, z 2.4..2.8), 7.6 m from the nearest other clash, and drops the
# pipe into the column.
PIPE_TWO = _pipe("Pipe two through beam 0", "0PipeTwoThroughBeam000", (1.95, -0.3, 2.55),
                 (2.05, 1.0, 2.65))
PIPE_COLUMN = _pipe("Pipe into column 0", "0PipeIntoColumn0000000", (5.8, -0.3, 0.95),
                    (5.9, 0.25, 1.05))
PIPE_NEW = _pipe("Pipe through beam 5", "0PipeThroughSouthBeam5", (9.45, 7.7, 2.55),
                 (9.55, 9.0, 2.65))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two versions of a 16-cell building, as federated files: the first with PIPE_TWO and
    PIPE_COLUMN added, the second with PIPE_TWO and PIPE_NEW."""
    base = B.generate(16 * B.ELEMENTS_PER_CELL)
    folder = tmp_path_factory.mktemp("runs")
    out = []
    for k, extra in enumerate([(PIPE_TWO, PIPE_COLUMN), (PIPE_TWO, PIPE_NEW)]):
        building = B.Building(base.parts + list(extra), {}, base.openings)
        out.append(B.write_federated(building, folder / f"v{k + 1}"))
    return types.SimpleNamespace(base=base, paths=out, folder=folder)


def _ids(base: B.Building, *names: str) -> tuple[str, ...]:
    by_name = {p.name: p.global_id for p in base.parts}
    return tuple(by_name[n] for n in names)


@pytest.fixture(scope="module")
def first(runs):
    """The first version's model and its hard clashes deeper than d."""
    model = ifc.read_ifc(runs.paths[0], cache=False)
    return model, ifc.find_clashes(model, min_depth=B.DEPTH)


def test_groups_on_a_generated_building(runs, first):
    model, clashes = first
    beam, column, pipe = _ids(runs.base, "Beam south 0", "Column 1 0", "Pipe through beam 0")
    p1, p2 = pair_key(pipe, beam), pair_key(PIPE_TWO.global_id, beam)
    p3 = pair_key(PIPE_COLUMN.global_id, column)
    # The building's own cells hold at most one hard clash each: the truth's, deeper than d.
    expected = {k for k, r in runs.base.truth.items() if r.depth > B.DEPTH + r.error}
    keys = {pair_key(c.a.global_id, c.b.global_id) for c in clashes}
    assert keys == expected | {p2, p3}

    def group_of(groups, key):
        [g] = [g for g in groups if key in {pair_key(c.a.global_id, c.b.global_id)
                                            for c in g.clashes}]
        return sorted(pair_key(c.a.global_id, c.b.global_id) for c in g.clashes)

    # By element alone: the two pipes through the south beam.
    by_element = group_clashes(clashes, 0)
    assert len(by_element) == len(clashes) - 1 and group_of(by_element, p1) == sorted([p1, p2])
    # 3 m (the default): the two pipes, 2 m apart, are one group; the pipe into the column is
    # 2.34 m from the first but 4.1 m from the second, so it stays apart (no group spans more
    # than 3 m), and so does every other cell's clash (the nearest is 6 m away).
    assert group_of(group_clashes(clashes), p1) == sorted([p1, p2])
    assert group_of(group_clashes(clashes), p3) == [p3]
    assert group_of(group_clashes(clashes, 2.0), p3) == [p3]
    # However far, a group spans at most the distance: all in one (fewer than twenty clashes).
    assert len(group_clashes(clashes, 1000.0)) == 1
    assert len(group_clashes(clashes, None)) == len(clashes)
    # The benchmark's counts, and its report's line.
    counts = B.group_counts(clashes)
    assert counts == {"groups": len(clashes) - 1, "groups_by_element": len(clashes) - 1}
    row = {"system": "pycinder", "mode": "min_depth", "elements": len(model.bodies), "must": 0,
           "found": 0, "recall": 1.0, "touching": 0, "grazes": 0, "near": 0, "false": 0,
           "reported": len(clashes), "tessellation_s": 0.0, "clash_s": 0.0, **counts}
    text = "\n".join(B.markdown({"depth": B.DEPTH, "clearance": B.CLEARANCE, "rows": [row],
                                 "sizes": []}))
    assert (f"| {len(model.bodies):,} | origin | pycinder | min_depth | 10 | {len(clashes)} | "
            f"{len(clashes) - 1} | {len(clashes) - 1} | 0.0 |") in text


def _topics(path: Path) -> dict[str, tuple]:
    """Each topic of a BCF file as bcf-client reads it: GUID to its title, labels, status,
    description, and per viewpoint its selection, colours, camera and snapshot."""
    from bcf.v2.bcfxml import BcfXml

    out = {}
    with BcfXml.load(path) as read:
        for t in read.topics.values():
            views = []
            for v in t.viewpoints.values():
                info = v.visualization_info
                colours = sorted((c.color, sorted(x.ifc_guid for x in c.component))
                                 for c in info.components.coloring.color)
                cam = info.perspective_camera
                views.append([sorted(v.get_selected_guids()), colours,
                              [getattr(getattr(cam, p), xyz)
                               for p in ("camera_view_point", "camera_direction",
                                         "camera_up_vector") for xyz in "xyz"],
                              cam.field_of_view, v.snapshot])
            out[t.topic.guid] = (t.topic.title, t.topic.labels, t.topic.topic_status,
                                 t.topic.description, views)
    return out


def test_both_bcf_writers_write_the_same_topics(runs, first, tmp_path):
    """The built-in writer and bcf-client's give bcf-client the same topics: groups, stable
    GUIDs, statuses, cameras, colours and pictures (one group pictured, the others not)."""
    pytest.importorskip("bcf", reason="reading BCF back needs bcf-client")
    from PIL import Image

    from pycinder.bim.bcf import write_bcf
    from pycinder.bim.snapshot import COLOUR_A, COLOUR_B, group_camera

    model, clashes = first
    groups = group_clashes(clashes)
    gone = "8c1f9f8e-3b1e-4d43-9a57-5d0f4b7f2a10"  # a previous topic, resolved now
    tracking = track(groups, read_previous_from({gone: [("X", "Y")]}), source="x.json")
    picture = io.BytesIO()  # any PNG: the pictures' rendering is tested with the command
    Image.new("RGB", (8, 6), (200, 40, 30)).save(picture, format="PNG")
    pictures = {groups[0].index: (picture.getvalue(), group_camera(groups[0].elements))}
    written = [_topics(write_bcf(clashes, tmp_path / f"{w}.bcf", groups=groups,
                                 tracking=tracking, snapshots=pictures, writer=w))
               for w in ("builtin", "bcf-client")]
    # The same, but for the cameras' last digits (the built-in writer writes six decimals).
    cameras = [{g: [v[2] for v in t[4]] for g, t in w.items()} for w in written]
    assert cameras[0].keys() == cameras[1].keys()
    for g, views in cameras[0].items():
        np.testing.assert_allclose(views, cameras[1][g], atol=1e-5)
    for w in written:
        for t in w.values():
            for v in t[4]:
                v[2] = None
    assert written[0] == written[1]
    topics = written[0]
    assert set(topics) == {g.guid for g in groups} | {gone}
    assert topics[gone][1:3] == (["resolved"], "Closed") and topics[gone][4] == []
    colours = {"".join(f"{round(255 * x):02X}" for x in c) for c in (COLOUR_A, COLOUR_B)}
    for g in groups:
        title, labels, status, description, [view] = topics[g.guid]
        assert (title, labels, status) == (g.title(), ["new"], "Open")
        assert description.count("\n- ") == len(g.clashes)
        assert view[0] == sorted(b.global_id for b in g.elements)
        assert {c for c, _ in view[1]} <= colours and view[3] == 50.0
        assert (view[4] is not None) == (g.index in pictures)
    assert topics[groups[0].guid][4][0][4] == pictures[groups[0].index][0]


def _run(capsys, *argv) -> tuple[int, str, str]:
    code = main(["check", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def _rendering(*argv) -> tuple[int, str, str]:
    """``pycinder check`` in a process of its own: pictures are rendered by pygfx on wgpu's
    default device, which the demos (tested in this process too) configure for themselves."""
    done = subprocess.run([sys.executable, "-m", "pycinder", "check", *map(str, argv)],
                          env=path_first(ROOT / "src"),
                          capture_output=True, text=True, timeout=600)
    return done.returncode, done.stdout, done.stderr


def _colour_pixels(png: bytes) -> tuple[int, int]:
    """Pixels of the PNG within 40 (of 255) of each highlight colour, per channel."""
    from PIL import Image

    from pycinder.bim.snapshot import COLOUR_A, COLOUR_B

    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    return tuple(int((np.abs(image - np.array(c) * 255).max(axis=-1) <= 40).sum())
                 for c in (COLOUR_A, COLOUR_B))


def test_bcf_groups_snapshots_and_tracking(runs, capsys, tmp_path):
    pytest.importorskip("bcf", reason="reading BCF back needs bcf-client")
    pytest.importorskip("pygfx", reason="snapshots need pygfx")
    from bcf.v2.bcfxml import BcfXml

    first_bcf, first_json = tmp_path / "first.bcf", tmp_path / "first.json"
    code, out, err = _rendering(*runs.paths[0], "--min-depth", B.DEPTH, "--json", "--bcf",
                                first_bcf, "--snapshots", tmp_path / "pictures", "--no-cache")
    assert code == 1, err
    first_json.write_text(out)
    first = json.loads(out)
    groups = {g["id"]: g for g in first["groups"]}
    assert all(p["status"] == "new" and p["group"] in groups for p in first["pairs"])
    assert sorted(k for g in first["groups"] for k in g["clashes"]) == \
        list(range(len(first["pairs"])))
    # BCF, read back by bcf-client: a topic per group, under its GUID, labelled new, with a
    # viewpoint selecting the group's elements, its camera, and its picture.
    with BcfXml.load(first_bcf) as read:
        topics = {t.topic.guid: t for t in read.topics.values()}
        assert set(topics) == {g["guid"] for g in first["groups"]}
        for g in first["groups"]:
            t = topics[g["guid"]]
            assert t.topic.labels == ["new"] and t.topic.topic_status == "Open"
            [view] = t.viewpoints.values()
            assert sorted(view.get_selected_guids()) == sorted(g["elements"])
            cam = view.visualization_info.perspective_camera
            position = np.array([cam.camera_view_point.x, cam.camera_view_point.y,
                                 cam.camera_view_point.z])
            direction = np.array([cam.camera_direction.x, cam.camera_direction.y,
                                  cam.camera_direction.z])
            to_group = np.array(g["point"]) - position
            cosine = direction @ to_group / np.linalg.norm(to_group) / np.linalg.norm(direction)
            angle = np.degrees(np.arccos(min(cosine, 1.0)))
            assert angle < cam.field_of_view / 2, (g["title"], angle)  # the group is in view
            a_pixels, b_pixels = _colour_pixels(view.snapshot)
            assert a_pixels > 100 and b_pixels > 100, (g["title"], a_pixels, b_pixels)
            picture = Path(g["snapshot"])
            assert picture.name == f"group-{g['id']}.png"
            assert picture.read_bytes() == view.snapshot
    # The second version: the pipe into the column is gone, a pipe through a beam is new.
    column, north = _ids(runs.base, "Column 1 0", "Beam south 5")
    gone = list(pair_key(PIPE_COLUMN.global_id, column))
    added = pair_key(PIPE_NEW.global_id, north)
    before = {tuple(sorted((p["a_global_id"], p["b_global_id"]))) for p in first["pairs"]}
    for against in (first_bcf, first_json):
        code, out, err = _rendering(*runs.paths[1], "--min-depth", B.DEPTH, "--json",
                                    "--against", against, "--bcf", tmp_path / "second.bcf",
                                    "--no-cache")
        assert code == 1, err
        second = json.loads(out)
        status = {tuple(sorted((p["a_global_id"], p["b_global_id"]))): p["status"]
                  for p in second["pairs"]}
        assert status == {k: "new" if k == added else "active" for k in before - {tuple(gone)}
                          | {added}}
        assert [[r["a_global_id"], r["b_global_id"]] for r in second["resolved"]] in \
            ([gone], [gone[::-1]])
        assert second["against"] == against.name
        new_group = [g for g in second["groups"] if g["status"] == "new"]
        assert len(new_group) == 1 and new_group[0]["guid"] not in groups_guids(first)
        assert all(g["guid"] in groups_guids(first) for g in second["groups"]
                   if g["status"] == "active")
        # The group of the pipes through the south beam continues whole; the pipe into the
        # column, 2.34 m from one of them and 4.1 m from the other, was a group of its own,
        # which is resolved: its topic comes back closed.
        assert not any(g["resolved"] for g in second["groups"])
        [closed] = second["resolved_groups"]
        assert [sorted(p) for p in closed["pairs"]] == [sorted(gone)]
    with BcfXml.load(tmp_path / "second.bcf") as read:
        labels = sorted(t.topic.labels[0] for t in read.topics.values())
        assert labels == sorted([g["status"] for g in second["groups"]] + ["resolved"])
        descriptions = "\n".join(t.topic.description for t in read.topics.values())
        assert f"- resolved: {gone[0]} <-> {gone[1]}" in descriptions or \
            f"- resolved: {gone[1]} <-> {gone[0]}" in descriptions
    # Text: each clash with its group and status, the resolved one after them.
    code, out, err = _run(capsys, *runs.paths[1], "--min-depth", B.DEPTH, "--against",
                          first_json, "--no-cache", "--no-groups")
    lines = out.strip().splitlines()
    assert sum(" new] " in x for x in lines) == 1 and lines[-1].startswith("[resolved] ")
    assert "1 new" in err and "1 resolved" in err


def groups_guids(report: dict) -> set[str]:
    return {g["guid"] for g in report["groups"]}


def test_bad_options_are_named(runs, capsys, tmp_path):
    bad = tmp_path / "previous.txt"
    bad.write_text("")
    code, _, err = _run(capsys, *runs.paths[0], "--against", bad)
    assert code == 2 and "previous.txt: a previous run is read from its .bcf or .json" in err
    junk = tmp_path / "junk.json"
    junk.write_text("{}")
    code, _, err = _run(capsys, *runs.paths[0], "--against", junk)
    assert code == 2 and "junk.json: not the JSON of 'pycinder check --json'" in err
    with pytest.raises(SystemExit):
        _run(capsys, *runs.paths[0], "--group-distance", "-1")
    assert "--group-distance: '-1' is not 0 or a positive distance" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        _run(capsys, *runs.paths[0], "--group-distance", "2", "--no-groups")
    assert "not allowed with argument" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        _run(capsys, *runs.paths[0], "--snapshots", tmp_path, "--no-snapshots")
    assert "not allowed with argument" in capsys.readouterr().err
    # 0: by element alone (the two pipes through the south beam of cell 0 are one group).
    code, out, err = _run(capsys, *runs.paths[0], "--min-depth", B.DEPTH, "--json",
                          "--group-distance", "0", "--cache-dir", tmp_path / "cache")
    report = json.loads(out)
    assert code == 1 and report["group_distance"] == 0, err
    assert len(report["groups"]) == len(report["pairs"]) - 1
    code, _, err = _run(capsys, "box.stl", "--snapshots", tmp_path)
    assert code == 2 and "--snapshots applies to IFC files" in err


def _check(args: list[str], folder: Path) -> subprocess.CompletedProcess:
    env = path_first(ROOT / "src")
    return subprocess.run([sys.executable, "-m", "pycinder", "check", *args], cwd=folder,
                          env=env, capture_output=True, text=True, timeout=300)


def test_progress_only_on_a_terminal(tmp_path):
    paths = B.write_federated(B.generate(B.ELEMENTS_PER_CELL), tmp_path)
    names = [p.name for p in paths]
    piped = _check([*names, "--no-cache"], tmp_path)
    assert piped.returncode in (0, 1), piped.stderr
    assert "\x1b[" not in piped.stderr and "tessellating" not in piped.stderr
    [summary] = piped.stderr.strip().splitlines()  # nothing but the summary
    assert re.fullmatch(r"\d+ clash(es)? in \d+ groups?", summary), summary
    shown = _check([*names, "--no-cache", "--progress"], tmp_path)
    assert shown.returncode == piped.returncode, shown.stderr
    # The bar is drawn when it starts and when it stops (at its last step), between them as
    # often as rich refreshes it: only those two are sure to be seen.
    assert "\x1b[" in shown.stderr and "reading IFC" in shown.stderr
    assert f"checking {B.ELEMENTS_PER_CELL} elements" in shown.stderr
    assert shown.stdout == piped.stdout

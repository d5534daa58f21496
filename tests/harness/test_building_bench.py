"""The building benchmark's parts: the building in map coordinates, ``pycinder check --json``
against the API at the origin and 707 km out, the scoring rules at fine depths, IfcClash's
smart-group count, the dense-mesh hook and the report (benchmarks.building, scored by
pycinder.testing.buildingscore)."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest

pytest.importorskip("ifcopenshell", reason="IFC needs ifcopenshell: pip install 'pycinder[bim]'")

from benchmarks import building as B  # noqa: E402
from pycinder.bim import ifc  # noqa: E402
from pycinder.cli import main  # noqa: E402
from pycinder.testing import buildingscore as S  # noqa: E402

D_FINE = 0.002


@pytest.fixture(scope="module")
def small() -> B.Building:
    """About 300 elements: 19 cells, every case of the generator two or three times."""
    return B.generate(300)


@pytest.fixture(scope="module")
def placed(small, tmp_path_factory):
    """The building written at each placement (three files each) and read, with a warm cache
    for the command line."""
    root = tmp_path_factory.mktemp("placed")
    cache = root / "cache"
    out = {}
    for name, offset in B.PLACEMENTS:
        paths = B.write_federated(small, root / name, offset=offset)
        out[name] = types.SimpleNamespace(paths=paths, offset=np.asarray(offset),
                                          model=ifc.read_ifc(paths, cache=cache))
    return types.SimpleNamespace(cache=cache, **out)


def _key(a: str, b: str) -> tuple[str, str]:
    return tuple(sorted((a, b)))


def test_map_placement_moves_every_vertex_by_the_offset(small, placed):
    """The site's placement moves the world coordinates IfcOpenShell gives, and nothing else:
    the same elements, each vertex moved by the offset (within double precision's rounding at
    707 km, about 1e-10 m)."""
    origin, far = placed.origin.model, placed.map.model
    assert far.names == origin.names and len(origin.bodies) == len(small.parts)
    for a, b in zip(origin.bodies, far.bodies):
        assert a.mesh.faces.tolist() == b.mesh.faces.tolist()
        moved = a.mesh.vertices + placed.map.offset
        assert np.abs(b.mesh.vertices - moved).max() < 1e-6, a.name
    # The boxes come out exactly where the generator put them.
    parts = small.by_id()
    for body in origin.bodies:
        p = parts[body.global_id]
        if not p.is_cylinder:
            assert np.allclose(body.mesh.bounds, [p.lo, p.hi], rtol=0, atol=1e-9), body.name


def _cli(capsys, paths, cache, *args):
    code = main(["check", *map(str, paths), "--min-depth", str(D_FINE), "--json",
                 "--cache-dir", str(cache), *args])
    out, err = capsys.readouterr()
    assert code == 1, err
    return json.loads(out)


@pytest.mark.parametrize("placement", ["origin", "map"])
def test_cli_json_is_the_api_answer_and_the_truth(small, placed, capsys, placement):
    """``pycinder check FILES --min-depth 0.002 --json`` gives the pairs of
    ``find_clashes(model, min_depth=0.002)``, with the same depths, at the origin and in map
    coordinates; and they are exactly the pairs deeper than 2 mm: no touching pair, no 1 mm
    graze (exactly d / 2 deep), every depth within its bound of the true one."""
    where = getattr(placed, placement)
    api = ifc.find_clashes(where.model, min_depth=D_FINE)
    report = _cli(capsys, where.paths, placed.cache)
    assert report["errors"] == [] and report["mode"] == "min_depth"
    assert report["tessellated"] == []  # the fixture's cache
    cli = {_key(p["a_global_id"], p["b_global_id"]): p for p in report["pairs"]}
    mine = {_key(c.a.global_id, c.b.global_id): c for c in api}
    assert cli.keys() == mine.keys()
    for k, c in mine.items():
        bound = max(c.depth_error, cli[k]["depth_error"])
        assert abs(cli[k]["depth"] - c.depth) <= bound, (c.a.name, c.b.name)
    s = B.score(small, set(cli), "min_depth", depth=D_FINE)
    assert (s["found"], s["false"], s["touching"], s["grazes"], s["either"]) == \
        (s["must"], 0, 0, 0, 0)
    assert s["must"] == sum(k in ("deep", "shallow", "contained")
                            for k in (r.kind for r in small.truth.values()))
    assert B.check_depths(small, api)["depths_outside"] == 0
    assert len(report["groups"]) == S.group_counts(api)["groups"]


def test_rules_at_exactly_d_and_d_over_2():
    """A pair built exactly d deep may go either way, whichever way its figure rounds; one
    exactly d / 2 deep must not be reported; touching and apart pairs never; the tessellation's
    error widens only the side that must be reported."""
    d = 0.001
    for depth in (0.0009999999999998899, 0.001, 0.0010000000000001):
        r = B.Relation(0.0, depth)
        assert not S.must_report(r, "min_depth", depth=d)
        assert not S.must_not_report(r, "min_depth", depth=d)
        assert S.must_not_report(r, "intersection", depth=2 * d)  # d / 2 at 2 mm
    assert S.must_not_report(B.Relation(0.0, 0.0), "min_depth", depth=d)  # touching
    assert S.must_not_report(B.Relation(0.01, 0.0), "min_depth", depth=d)  # apart
    assert S.must_not_report(None, "clearance", clearance=0.05)  # outside the truth
    rounded = B.Relation(0.0, 0.0015, error=0.001)  # a cylinder's, tessellated
    assert not S.must_report(rounded, "min_depth", depth=d)
    assert S.must_report(B.Relation(0.0, 0.0021, error=0.001), "min_depth", depth=d)
    assert S.must_not_report(B.Relation(0.0, 0.0005, error=0.001), "min_depth", depth=d)
    assert S.must_report(B.Relation(0.0019, 0.0), "clearance", clearance=0.002)
    assert not S.must_report(B.Relation(0.0019, 0.0, error=0.001), "clearance",
                             clearance=0.002)
    assert S.must_not_report(B.Relation(0.0023, 0.0), "clearance", clearance=0.002)
    assert not S.must_not_report(B.Relation(0.0022, 0.0), "clearance", clearance=0.002)


def test_truth_classes_at_fine_depths(small):
    """The ducts 1 mm into the slab: must not at d = 2 mm (exactly d / 2), either way at
    1 mm (exactly d); every shallow, deep and contained pair must be reported at both."""
    grazing = small.pairs("grazing")
    assert grazing and {round(small.truth[k].depth, 12) for k in grazing} == {0.001}
    must = sum(len(small.pairs(k)) for k in ("shallow", "deep", "contained"))
    at2 = S.truth_classes(small, "min_depth", depth=0.002)
    at1 = S.truth_classes(small, "intersection", depth=0.001)
    assert at2 == {"must": must, "either": 0, "never": len(small.truth) - must}
    assert at1 == {"must": must, "either": len(grazing),
                   "never": len(small.truth) - must - len(grazing)}
    s = S.score(small, grazing | {next(iter(small.pairs("touching")))}, "min_depth",
                depth=0.001)
    assert (s["either"], s["false"], s["touching"], s["grazes"]) == (len(grazing), 1, 1, 0)
    assert s["wrong"] and "touching" in s["wrong"][0]
    s = S.score(small, grazing, "min_depth", depth=0.002)
    assert (s["either"], s["false"], s["grazes"]) == (0, len(grazing), len(grazing))
    assert len(s["missed"]) == min(must, S.SHOWN) and "depth" in s["missed"][0]
    clear = S.truth_classes(small, "clearance", clearance=0.002)
    assert clear["must"] == sum(r.distance == 0 for r in small.truth.values())


def test_smart_group_count():
    pytest.importorskip("ifcclash")
    pytest.importorskip("sklearn")

    def result(a, b, x):
        side = types.SimpleNamespace
        return side(a=side(GlobalId=a), b=side(GlobalId=b), p1=(x, 0.0, 0.0), p2=(x, 0.0, 0.0))

    # Two clashes 1 m apart cluster; one 10 m away is a group of its own.
    near = [result("A", "B", 0.0), result("C", "D", 1.0), result("E", "F", 10.0)]
    assert B.smart_group_count(near) == 2
    assert B.smart_group_count(near[:1]) == 1 and B.smart_group_count([]) == 0


def test_dense_entry(tmp_path):
    missing = B.dense_entry(tmp_path / "dense.json")
    assert missing["status"] == "not run"
    assert "not run" in B._dense_lines(missing)[0]
    (tmp_path / "dense.json").write_text(json.dumps(
        {"rows": [{"system": "pycinder", "faces": 20000, "clash_s": 1.25, "pairs": [1, 2]}]}))
    entry = B.dense_entry(tmp_path / "dense.json")
    assert entry["status"] == "run"
    assert entry["rows"] == [{"system": "pycinder", "faces": 20000, "clash_s": 1.25}]
    assert B._dense_lines(entry)[-1] == "| system pycinder, faces 20000, clash_s 1.25 | | | | | |"
    (tmp_path / "dense.json").write_text(json.dumps({"rows": [
        {"case": "torus through sphere", "option": "min_depth", "first_s": 1.87, "s": 1.5,
         "reported": True, "right": "yes (reported)"}]}))
    assert B._dense_lines(B.dense_entry(tmp_path / "dense.json"))[-1] == \
        "| torus through sphere | min_depth | 1.87 | 1.50 | yes | yes (reported) |"
    (tmp_path / "dense.json").write_text("{")
    assert B.dense_entry(tmp_path / "dense.json")["status"] == "unreadable"


def test_markdown_of_a_run():
    """The report names every row, placement and figure, the failures with their pairs, the
    command line's comparison and the dense-mesh row."""
    base = {"must": 2, "found": 1, "recall": 0.5, "touching": 0, "grazes": 0, "near": 0,
            "either": 0, "false": 0, "reported": 1, "missed": ["Pipe 0 / Wall 0: deep"],
            "wrong": [], "tessellation_s": 1.0, "clash_s": 0.5, "elements": 16}
    r = {"depth": 0.01, "clearance": 0.05, "offset": list(B.MAP_OFFSET), "adapter": "test",
         "sizes": [{"elements": 16, "truth": {"deep": 2},
                    "classes": [{"mode": "min_depth", "value": 0.001, "must": 2, "either": 1,
                                 "never": 3}]}],
         "rows": [{**base, "system": "IfcClash", "mode": "intersection", "value": 0.002,
                   "placement": "map", "smart_groups": 1, "grouping_s": 0.1},
                  {**base, "system": "pycinder", "mode": "min_depth", "value": 0.001,
                   "placement": "origin", "missed": [], "found": 2, "recall": 1.0,
                   "groups": 1, "groups_by_element": 2, "depths_checked": 2,
                   "depths_outside": 0, "depth_worst": 1e-8}],
         "cli": [{"command": "pycinder check a.ifc --min-depth 0.002 --json", "elements": 16,
                  "placement": "map", "exit": 1, "pairs": 2, "groups": 1, "api_pairs": 2,
                  "same_pairs": True, "min_depth": 0.002, "depth_diff": 0.0,
                  "depth_bound": 1e-6, "found": 2, "must": 2, "touching": 0, "grazes": 0,
                  "false": 0, "wall_s": 1.0}],
         "dense": {"status": "not run", "source": "dense.json"}}
    text = "\n".join(B.markdown(r))
    assert "| 16 | map | IfcClash | intersection | 2 | 2 | 1 | 50.0% |" in text
    assert "| 16 | origin | pycinder | min_depth | 1 | 2 | 2 | 100.0% |" in text
    assert "d = 1 mm: 2 must be reported, 1 either way, 3 must not" in text
    assert "IfcClash intersection d = 2 mm, 16 elements, map: 1 missed, among them: " \
           "Pipe 0 / Wall 0: deep." in text
    assert "the same pairs as `find_clashes(model, min_depth=0.002)`" in text
    assert "(500 km, 500 km, 0 km), 707 km out" in text
    assert "Dense meshes" in text and "not run (no dense.json)" in text

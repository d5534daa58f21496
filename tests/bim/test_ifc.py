"""IFC in, clash sets, BCF out: pycinder.ifc, pycinder.bcf, ``pycinder check *.ifc`` and the
generated building with exact truth (pycinder.testing.buildings)."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest

pytest.importorskip("ifcopenshell", reason="IFC needs ifcopenshell: pip install 'pycinder[bim]'")

from pycinder.bim import bcf, ifc  # noqa: E402
from pycinder.cli import main  # noqa: E402
from pycinder.files import FileErrors, load_bodies  # noqa: E402
from pycinder.testing import buildings as B  # noqa: E402
from pycinder.testing import buildingscore as S  # noqa: E402
from pycinder.tolerance import body_sizes, default_pair_tolerances  # noqa: E402


@pytest.fixture(scope="module")
def house() -> B.Building:
    """Eight cells: every case of :data:`~pycinder.testing.buildings.CASES` once."""
    return B.generate(8 * B.ELEMENTS_PER_CELL)


@pytest.fixture(scope="module")
def fed(house, tmp_path_factory):
    """The building as three files (architecture, structure, MEP), and a warm cache."""
    folder = tmp_path_factory.mktemp("fed")
    paths = B.write_federated(house, folder)
    cache = folder / "cache"
    model = ifc.read_ifc(paths, cache=cache)
    return types.SimpleNamespace(paths=paths, cache=cache, model=model, folder=folder)


@pytest.fixture(scope="module")
def everything(fed):
    """Every element against every other, by the default query: sorted GlobalId pairs."""
    return {_key(c) for c in ifc.find_clashes(fed.model)}


def _key(c: ifc.Clash) -> tuple[str, str]:
    return tuple(sorted((c.a.global_id, c.b.global_id)))


def test_read_back_element_set_names_classes_ids(tmp_path):
    house = B.generate(4 * B.ELEMENTS_PER_CELL)
    path = B.write_ifc(house, tmp_path / "one.ifc")
    model = ifc.read_ifc(path, cache=False)
    parts = house.by_id()
    # IfcClash's element set: the door openings (IfcFeatureElement) are left out.
    assert {b.global_id for b in model.bodies} == set(parts)
    assert model.files == ["one.ifc"] and model.schemas == {"one.ifc": "IFC4"}
    for body in model.bodies:
        part = parts[body.global_id]
        assert body.name == f"{part.name} [{part.global_id}]"
        assert body.ifc_class == part.ifc_class and body.file == "one.ifc"
        assert body.mesh.is_watertight, body.name
        err = B.chord_error(part.radius) + 1e-6
        assert np.allclose(body.mesh.bounds, [part.lo, part.hi], atol=err), body.name
    # Openings are applied: the door takes 0.2 x 1 x 2.1 m out of the wall it voids.
    voided = {wall for wall, _, _ in house.openings}
    for body in model.bodies:
        box = np.prod(np.subtract(parts[body.global_id].hi, parts[body.global_id].lo))
        if body.global_id in voided:
            assert body.mesh.volume == pytest.approx(box - 0.2 * 1.0 * 2.1, rel=1e-6)
        elif body.ifc_class == "IfcWall":
            assert body.mesh.volume == pytest.approx(box, rel=1e-6)


def test_ifc2x3(tmp_path):
    house = B.generate(B.ELEMENTS_PER_CELL)
    model = ifc.read_ifc(B.write_ifc(house, tmp_path / "old.ifc", schema="IFC2X3"), cache=False)
    assert model.schemas == {"old.ifc": "IFC2X3"}
    classes = {b.global_id: b.ifc_class for b in model.bodies}
    for part in house.parts:
        expected = "IfcFlowSegment" if part.ifc_class.endswith("Segment") else part.ifc_class
        assert classes[part.global_id] == expected
    # Class selectors follow the file's schema: IfcFlowSegment is a distribution element.
    assert model.select("IfcDistributionElement").sum() == sum(
        p.ifc_class.endswith("Segment") for p in house.parts)


def test_cache_retessellates_only_the_changed_file(fed, tmp_path):
    cache = tmp_path / "cache"
    paths = [tmp_path / p.name for p in fed.paths]
    for src, dst in zip(fed.paths, paths):
        dst.write_bytes(src.read_bytes())
    first = ifc.read_ifc(paths, cache=cache)
    assert first.tessellated == ["architecture.ifc", "structure.ifc", "mep.ifc"]
    again = ifc.read_ifc(paths, cache=cache)
    assert again.tessellated == []
    assert [b.name for b in again.bodies] == [b.name for b in first.bodies]
    assert all(np.array_equal(x.mesh.vertices, y.mesh.vertices)
               for x, y in zip(again.bodies, first.bodies))
    mep = paths[2]
    mep.write_bytes(mep.read_bytes().replace(b"'Pipe 0 0'", b"'Pipe 0 X'"))
    changed = ifc.read_ifc(paths, cache=cache)
    assert changed.tessellated == ["mep.ifc"]
    assert any(b.name.startswith("Pipe 0 X [") for b in changed.bodies)


def test_clash_set_by_file(fed, everything):
    m = fed.model
    clashes = ifc.find_clashes(m, ifc.Group(files=["mep.ifc"]), ifc.Group(files=["structure.ifc"]))
    assert clashes and all(c.a.file == "mep.ifc" and c.b.file == "structure.ifc" for c in clashes)
    files = {b.global_id: b.file for b in m.bodies}
    expected = {k for k in everything if {files[k[0]], files[k[1]]} == {"mep.ifc",
                                                                       "structure.ifc"}}
    assert {_key(c) for c in clashes} == expected
    with pytest.raises(ValueError, match="nowhere.ifc: not a file of this model"):
        m.select(ifc.Group(files=["nowhere.ifc"]))


def test_clash_set_by_class_and_selector(fed, everything):
    m = fed.model
    classes = {b.global_id: b.ifc_class for b in m.bodies}
    mep, structure = {"IfcPipeSegment", "IfcDuctSegment"}, {"IfcBeam", "IfcColumn"}
    clashes = ifc.find_clashes(m, "IfcPipeSegment, IfcDuctSegment", "IfcBeam, IfcColumn")
    assert all(c.a.ifc_class in mep and c.b.ifc_class in structure for c in clashes)
    expected = {k for k in everything
                if {classes[k[0]], classes[k[1]]} & mep and {classes[k[0]], classes[k[1]]}
                & structure}
    assert {_key(c) for c in clashes} == expected and expected
    # Superclasses select their subclasses; IfcClash's selector syntax goes to IfcOpenShell.
    assert m.select("IfcBuildingElement").sum() == sum(
        p.ifc_class in ("IfcWall", "IfcSlab", "IfcColumn", "IfcBeam") for p in fed_parts(m))
    south = m.select('IfcBeam, Name=/Beam south.*/')
    assert south.sum() == 8 and all(m.bodies[i].element_name.startswith("Beam south")
                                    for i in np.flatnonzero(south))
    # A against itself: pipes and ducts among themselves only.
    alone = ifc.find_clashes(m, "IfcPipeSegment, IfcDuctSegment")
    assert all(c.a.ifc_class in mep and c.b.ifc_class in mep for c in alone)
    assert {_key(c) for c in alone} == {k for k in everything
                                        if {classes[k[0]], classes[k[1]]} <= mep}
    # Groups that overlap: the elements in both are tested against both.
    both = ifc.find_clashes(m, "IfcElement, ! IfcWall", "IfcBeam")
    assert all(c.b.ifc_class == "IfcBeam" for c in both)
    assert {_key(c) for c in both} == {k for k in everything
                                       if "IfcBeam" in (classes[k[0]], classes[k[1]])
                                       and "IfcWall" not in (classes[k[0]], classes[k[1]])}
    excluded = ifc.Group(selector="IfcPipeSegment, IfcDuctSegment", exclude="IfcDuctSegment")
    assert {m.bodies[i].ifc_class for i in np.flatnonzero(m.select(excluded))} == \
        {"IfcPipeSegment"}
    with pytest.raises(ValueError, match="selector 'IfcWall,': IfcOpenShell could not use it"):
        m.select("IfcWall,")


def fed_parts(model: ifc.IfcModel):
    return [types.SimpleNamespace(ifc_class=b.ifc_class) for b in model.bodies]


def test_default_query_against_exact_truth(house, fed, everything):
    """Today's contract, pair by pair: pairs at least t apart never reported, pairs at least 2t
    deep always (t: the default, 1% of the smaller body's size); deep and contained clashes all
    deeper than 2t here."""
    m = fed.model
    sizes = {b.global_id: float(body_sizes(b.mesh.bounds[:1], b.mesh.bounds[1:],
                                           np.eye(4)[None])[0]) for b in m.bodies}
    must = set()
    for key, rel in house.truth.items():
        t = float(default_pair_tolerances(np.array([sizes[key[0]]]), np.array([sizes[key[1]]]))[0])
        if rel.depth >= 2 * t + rel.error:
            must.add(key)
        if rel.distance >= t + rel.error:
            assert key not in everything, (key, rel)
        if rel.kind in ("deep", "contained"):
            assert key in must, (key, rel, t)
    assert must <= everything, must - everything
    kinds = {house.truth[k].kind for k in must}
    assert {"deep", "contained"} <= kinds
    # Pairs not in the truth are at least MARGIN apart, farther than any pair's tolerance.
    assert everything <= set(house.truth)


def test_truth_is_exact_by_construction():
    h = B.generate(8 * B.ELEMENTS_PER_CELL)
    by_kind = {}
    for key, rel in h.truth.items():
        by_kind.setdefault(rel.kind, []).append(rel)
    assert sorted(r.depth for r in by_kind["deep"]) == pytest.approx([0.25, 0.5])
    assert [r.depth for r in by_kind["contained"]] == pytest.approx([0.15])
    assert sorted(r.depth for r in by_kind["shallow"]) == pytest.approx([0.02, 0.02])
    assert [r.depth for r in by_kind["grazing"]] == pytest.approx([0.001])
    near = sorted(r.distance for r in by_kind["near"])
    assert near[0] == pytest.approx(0.01) and pytest.approx(0.04) in near
    assert len(by_kind["touching"]) >= 8 * 20


def _run(capsys, *args):
    code = main(["check", *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_json_and_bcf(fed, capsys, tmp_path):
    out_bcf = tmp_path / "clashes.bcf"
    # Pictures are rendered and checked in test_bim_report.py, in processes of their own.
    code, out, err = _run(capsys, *fed.paths, "--json", "--a-file", "mep.ifc", "--b-file",
                          "structure.ifc", "--bcf", out_bcf, "--cache-dir", fed.cache,
                          "--no-snapshots")
    assert code == 1, err
    report = json.loads(out)
    assert report["errors"] == [] and report["mode"] == "default"
    assert report["tessellated"] == []  # from the fixture's cache
    assert report["clash_set"] == {"a": "every element in mep.ifc",
                                   "b": "every element in structure.ifc"}
    pairs = report["pairs"]
    assert pairs and all(p["a_file"] == "mep.ifc" and p["b_file"] == "structure.ifc"
                         and p["a"].endswith(f"[{p['a_global_id']}]")
                         and p["a_class"] in ("IfcPipeSegment", "IfcDuctSegment")
                         and p["b_class"] in ("IfcBeam", "IfcColumn")
                         and p["depth"] is None and p["distance"] is None for p in pairs)
    # A topic per group, selecting the group's elements; every pair is in its group.
    groups = {g["id"]: g for g in report["groups"]}
    assert all({p["a_global_id"], p["b_global_id"]} <= set(groups[p["group"]]["elements"])
               for p in pairs)
    expected = [set(g["elements"]) for g in report["groups"]]
    try:
        from bcf.v2.bcfxml import BcfXml
    except ImportError:
        topics = bcf.read_bcf_guids(out_bcf)
        got = [set(guids) for _, guids in topics]
    else:
        with BcfXml.load(out_bcf) as read:
            got = [set(v.get_selected_guids())
                   for t in read.topics.values() for v in t.viewpoints.values()]
            assert all(v.snapshot is None for t in read.topics.values()
                       for v in t.viewpoints.values())
    assert sorted(map(sorted, got)) == sorted(map(sorted, expected))
    code, out, _ = _run(capsys, *fed.paths, "--a", "IfcPipeSegment", "--b", "IfcBeam",
                        "--cache-dir", fed.cache)
    lines = out.strip().splitlines()
    assert code == 1 and lines and all(x.startswith("[") and "(IfcPipeSegment)  <->  " in x
                                       and x.endswith("(IfcBeam)") for x in lines)


def test_bcf_builtin_writer(fed, tmp_path):
    clashes = ifc.find_clashes(fed.model, "IfcPipeSegment", "IfcBeam, IfcWall")
    path = bcf.write_bcf(clashes, tmp_path / "own.bcf", writer="builtin")
    topics = bcf.read_bcf_guids(path)
    assert [g for _, g in topics] == [[c.a.global_id, c.b.global_id] for c in clashes]
    assert topics[0][0] == (f"{clashes[0].a.ifc_class}/{clashes[0].a.element_name} and "
                            f"{clashes[0].b.ifc_class}/{clashes[0].b.element_name}")
    try:
        from bcf.v2.bcfxml import BcfXml
    except ImportError:
        return
    with BcfXml.load(path) as read:  # bcf-client reads the built-in writer's files
        assert sorted(sorted(v.get_selected_guids()) for t in read.topics.values()
                      for v in t.viewpoints.values()) == sorted(sorted(g) for _, g in topics)


def _deeper(house: B.Building, d: float) -> set[tuple[str, str]]:
    """The pairs a hard-clash query at ``d`` must report, by the exact truth: deeper than ``d``
    beyond the tessellation's error. None of the generated pairs lies between ``d / 2`` and
    ``d`` for the ``d`` used here, so these are exactly the pairs reported."""
    return {k for k, r in house.truth.items() if r.depth > d + r.error}


@pytest.fixture(scope="module")
def hard(fed):
    """Hard clashes deeper than 1 cm, every element against every other."""
    return ifc.find_clashes(fed.model, min_depth=S.DEPTH)


def test_hard_clashes_against_exact_truth(house, hard):
    """min_depth=d: every pair deeper than d, none at most d/2 deep (touching pairs, the 1 mm
    duct in the slab), each with its depth: an upper bound of the exact one, within its error
    bound (and exact here, up to the tessellation: every element lies along the world's axes,
    which are among the lines measured)."""
    d = S.DEPTH
    assert all(not (d / 2 < r.depth <= d) for r in house.truth.values())  # none in between
    reported = {_key(c) for c in hard}
    assert reported == _deeper(house, d)
    assert {house.truth[k].kind for k in reported} == {"deep", "contained", "shallow"}
    assert S.score(house, reported, "min_depth")["false"] == 0
    for c in hard:
        r = house.truth[_key(c)]
        assert c.mode == "min_depth" and c.distance is None and c.distance_error is None
        assert c.depth_error is not None and 0 <= c.depth_error < c.depth, c
        assert c.depth - c.depth_error <= r.depth + r.error, (c.a.name, c.b.name, r)
        assert abs(c.depth - r.depth) <= r.error + 1e-3, (c.a.name, c.b.name, c.depth, r)
    # The pipe through the south beam, 0.25 m deep; the pipe lying on the duct, and the pipe
    # segments butted end to end and against the walls, are touching: never reported.
    [through] = [c for c in hard if c.a.element_name.startswith("Pipe through beam")
                 or c.b.element_name.startswith("Pipe through beam")]
    assert through.depth == pytest.approx(0.25, abs=2e-3)
    names = {frozenset((c.a.element_name.rsplit(" ", 1)[0], c.b.element_name.rsplit(" ", 1)[0]))
             for c in hard}
    assert not names & {frozenset(("Pipe under duct", "Duct 0")),
                        frozenset(("Pipe under duct", "Duct 1"))}
    assert not any(n <= {"Pipe 0", "Pipe 1", "Pipe 2", "Wall west", "Wall east"} for n in names)


def _bcf_descriptions(path) -> list[str]:
    """Each topic's description, read from the BCF file's XML (either writer's)."""
    import xml.etree.ElementTree as ET
    import zipfile

    out = []
    with zipfile.ZipFile(path) as z:
        for name in z.namelist():
            if name.endswith("/markup.bcf"):
                out += [e.text or "" for e in ET.fromstring(z.read(name)).iter()
                        if e.tag.rsplit("}", 1)[-1] == "Description"]
    return out


def test_cli_hard_clashes_json_and_bcf(house, fed, hard, capsys, tmp_path):
    out_bcf = tmp_path / "hard.bcf"
    code, out, err = _run(capsys, *fed.paths, "--json", "--min-depth", S.DEPTH, "--bcf",
                          out_bcf, "--cache-dir", fed.cache, "--no-snapshots")
    assert code == 1, err
    report = json.loads(out)
    assert report["errors"] == [] and report["mode"] == "min_depth"
    assert report["min_depth"] == S.DEPTH and report["clearance"] is None
    pairs = report["pairs"]
    assert {tuple(sorted((p["a_global_id"], p["b_global_id"]))) for p in pairs} == \
        _deeper(house, S.DEPTH)
    by_key = {_key(c): c for c in hard}
    for p in pairs:
        c = by_key[tuple(sorted((p["a_global_id"], p["b_global_id"])))]
        assert p["mode"] == "min_depth" and p["distance"] is None
        assert (p["depth"], p["depth_error"]) == (c.depth, c.depth_error)
    descriptions = _bcf_descriptions(out_bcf)
    assert len(descriptions) == len(report["groups"])
    lines = [x for t in descriptions for x in t.splitlines() if x.startswith("- ")]
    assert len(lines) == len(pairs)
    assert all("; depth " in t and "(error at most " in t and t.endswith("mode: min_depth")
               for t in lines), descriptions
    # Text: each clash with its depth; a clash set with none deeper than d exits 0.
    code, out, _ = _run(capsys, *fed.paths, "--min-depth", S.DEPTH, "--a", "IfcPipeSegment",
                        "--b", "IfcBeam", "--cache-dir", fed.cache)
    [line] = out.strip().splitlines()
    assert code == 1 and line.startswith("[1] Pipe through beam 0 [")
    assert "(IfcBeam)  depth " in line
    assert float(line.rsplit("depth ", 1)[1].removesuffix(" m")) == pytest.approx(0.25, abs=2e-3)
    code, out, _ = _run(capsys, *fed.paths, "--min-depth", S.DEPTH, "--a", "IfcPipeSegment",
                        "--b", "IfcDuctSegment", "--cache-dir", fed.cache)
    assert code == 0 and out.strip() == "no clashes"


def test_cli_clearance_json(fed, capsys):
    code, out, err = _run(capsys, *fed.paths, "--json", "--clearance", "0.01", "--cache-dir",
                          fed.cache)
    report = json.loads(out)
    assert code == 1 and report["mode"] == "clearance", err
    assert report["pairs"] and all(p["depth"] is None and p["distance"] is not None
                                   and p["distance_error"] is not None
                                   for p in report["pairs"])


def test_modes_reach_the_detector(fed, monkeypatch):
    """find_clashes passes min_depth / clearance to the Detector, and takes each pair's figure
    and its bound from the result."""
    seen = {}

    class Fake:
        def __init__(self, **options):
            seen.update(options)
            self.request = types.SimpleNamespace(strategy="focused", **options)

        def find_collisions(self, bodies, transforms, names=None, groups=None, pairs=None):
            return types.SimpleNamespace(pairs=np.array([[0, 1]]), depths=np.array([0.25]),
                                         depth_errors=np.array([1e-6]),
                                         distances=np.array([0.0]),
                                         distance_errors=np.array([2e-6]))

    monkeypatch.setattr("pycinder.detector.Detector", Fake)
    [c] = ifc.find_clashes(fed.model, min_depth=0.01)
    assert seen["min_depth"] == 0.01 and c.mode == "min_depth"
    assert (c.depth, c.depth_error, c.distance, c.distance_error) == (0.25, 1e-6, None, None)
    assert c.as_dict()["depth"] == 0.25 and c.as_dict()["depth_error"] == 1e-6
    seen.clear()
    [c] = ifc.find_clashes(fed.model, clearance=0.05)
    assert seen["clearance"] == 0.05 and "min_depth" not in seen and c.mode == "clearance"
    assert (c.depth, c.depth_error, c.distance, c.distance_error) == (None, None, 0.0, 2e-6)
    with pytest.raises(ValueError, match="give one of them"):
        ifc.find_clashes(fed.model, min_depth=0.01, clearance=0.05)
    with pytest.raises(ValueError, match="min_depth must be a positive distance"):
        ifc.find_clashes(fed.model, min_depth=-1.0)


def test_cli_errors(fed, capsys, tmp_path):
    import trimesh

    box = tmp_path / "box.stl"
    trimesh.creation.box((1, 1, 1)).export(box)
    code, _, err = _run(capsys, box, "--bcf", tmp_path / "x.bcf")
    assert code == 2 and "--bcf applies to IFC files" in err
    code, _, err = _run(capsys, fed.paths[0], box)
    assert code == 2 and "checked on their own" in err
    bad = tmp_path / "bad.ifc"
    bad.write_text("not IFC at all")
    code, _, err = _run(capsys, bad, fed.paths[0], "--cache-dir", fed.cache)
    assert code == 2 and "bad.ifc: is not an IFC file in STEP form" in err
    broken = tmp_path / "broken.ifc"
    broken.write_text("ISO-10303-21;\nHEADER;\nnonsense\n")
    with pytest.raises(FileErrors, match="broken.ifc: could not read it as IFC"):
        ifc.read_ifc([broken], cache=False)


def test_mesh_file_loader_reads_ifc(fed, monkeypatch, tmp_path):
    monkeypatch.setenv("PYCINDER_CACHE_DIR", str(tmp_path))
    bodies = load_bodies([str(fed.paths[1])])
    assert bodies and all(isinstance(b, ifc.IfcBody) and b.ifc_class in ("IfcBeam", "IfcColumn")
                          for b in bodies)
    assert ifc.default_cache_dir() == tmp_path / "ifc" and any((tmp_path / "ifc").iterdir())


def test_score_counts(house):
    touching = next(iter(house.pairs("touching")))
    deep = next(iter(house.pairs("deep")))
    s = S.score(house, {touching, deep}, "min_depth")
    assert s["touching"] == 1 and s["false"] == 1 and s["found"] == 1

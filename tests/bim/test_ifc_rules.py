"""Clash rules and groups on parts of a real model (``data/ifc``, see its README: Revit's Duplex
Apartment): each rule sets aside exactly the pairs the file's relations name, as read here with
IfcOpenShell; its count is in the output; no other pair changes; groups span at most their
distance."""

from __future__ import annotations

import itertools
import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

ifcopenshell = pytest.importorskip("ifcopenshell")
pytest.importorskip("scipy")

from pycinder.bim.groups import group_clashes  # noqa: E402
from pycinder.bim.ifc import find_clashes, read_ifc  # noqa: E402
from pycinder.bim.rules import RULES, ClashRules  # noqa: E402
from pycinder.cli import main  # noqa: E402

DATA = Path(__file__).parents[1] / "data" / "ifc"
ARCH, ELEC = DATA / "duplex-part.ifc", DATA / "duplex-electrical-part.ifc"
C = 0.01


def read(*paths):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_ifc(list(paths), cache=False)


@pytest.fixture(scope="module")
def arch():
    return read(ARCH)


def keys(model, clashes) -> set[tuple[str, str]]:
    return {tuple(sorted((c.a.global_id, c.b.global_id))) for c in clashes}


def pairs_of(model, set_aside, rule: str) -> set[tuple[str, str]]:
    return {tuple(sorted((model.bodies[i].global_id, model.bodies[j].global_id)))
            for (i, j), r in zip(set_aside.pairs.tolist(), set_aside.rule.tolist()) if r == rule}


def boxes_meet(model, gid_a: str, gid_b: str, margin: float = C) -> bool:
    a, b = ([x for x in model.bodies if x.global_id == g][0].mesh.bounds for g in (gid_a, gid_b))
    return bool(np.all(a[0] - margin / 2 <= b[1] + margin / 2) and
                np.all(b[0] - margin / 2 <= a[1] + margin / 2))


def test_each_rule_sets_aside_what_the_file_says(arch):
    f = ifcopenshell.open(str(ARCH))
    bodies = {b.global_id for b in arch.bodies}
    host = {r.RelatedOpeningElement: r.RelatingBuildingElement
            for r in f.by_type("IfcRelVoidsElement")}
    fills = {tuple(sorted((r.RelatedBuildingElement.GlobalId,
                           host[r.RelatingOpeningElement].GlobalId)))
             for r in f.by_type("IfcRelFillsElement")}
    connected = {tuple(sorted((r.RelatingElement.GlobalId, r.RelatedElement.GlobalId)))
                 for r in f.by_type("IfcRelConnectsElements")}
    parts = [p.GlobalId for r in f.by_type("IfcRelAggregates")
             if r.RelatingObject.is_a("IfcElement") for p in r.RelatedObjects]
    assembly = {tuple(sorted(p)) for p in itertools.combinations(parts, 2)}

    every = find_clashes(arch, clearance=C, rules="none")
    kept = find_clashes(arch, clearance=C)
    aside = kept.set_aside
    assert aside.rules == ClashRules() and set(aside.counts) == set(ClashRules().on())
    # Every clash is either kept or set aside, by one rule each; counts add up.
    assert keys(arch, kept) | {p for r in RULES for p in pairs_of(arch, aside, r)} == \
        keys(arch, every) | {p for r in RULES for p in pairs_of(arch, aside, r)}
    assert not keys(arch, kept) & {p for r in RULES for p in pairs_of(arch, aside, r)}
    assert sum(aside.counts.values()) == len(aside.pairs)

    def named(pairs):  # the file's pairs of two bodies whose boxes meet within C
        return {p for p in pairs if set(p) <= bodies and boxes_meet(arch, *p)}

    assert pairs_of(arch, aside, "fills") == named(fills) and aside.counts["fills"] >= 1
    assert pairs_of(arch, aside, "connected") == named(connected) - named(fills)
    assert aside.counts["connected"] >= 10
    assert pairs_of(arch, aside, "assembly") == named(assembly) and aside.counts["assembly"] >= 4
    # A wall standing in a floor finish's opening: the wall's volume reaches into it.
    openings = pairs_of(arch, aside, "openings")
    assert len(openings) == aside.counts["openings"] >= 1
    classes = {b.global_id: b.ifc_class for b in arch.bodies}
    assert all({classes[g] for g in p} == {"IfcWallStandardCase", "IfcSlab"} for p in openings)
    # None, or any one of them alone, sets aside just that.
    for rule in ("fills", "connected", "assembly", "openings"):
        alone = find_clashes(arch, clearance=C, rules=[rule]).set_aside
        assert set(alone.counts) == {rule}
        assert pairs_of(arch, alone, rule) >= pairs_of(arch, aside, rule)


def test_the_system_rule_and_its_default(arch):
    """Three appliances with their receptacles in one system, three more not: the system rule
    (off by default) sets aside the three in the system."""
    model = read(ELEC)
    [system] = model.relations["duplex-electrical-part.ifc"]["systems"][:, 1].tolist()[:1]
    members = set(model.relations["duplex-electrical-part.ifc"]["systems"][:, 0].tolist())
    every = find_clashes(model, clearance=C)
    assert len(every) == 6 and every.set_aside.counts["duplicates"] == 0
    assert "system" not in every.set_aside.counts
    with_system = find_clashes(model, clearance=C, rules="default,system")
    assert with_system.set_aside.counts["system"] == 3 and len(with_system) == 3
    assert all(set(p) <= members for p in pairs_of(model, with_system.set_aside, "system"))
    assert not any({c.a.global_id, c.b.global_id} <= members for c in with_system)
    assert system


def test_duplicated_globalids_are_reported_apart(tmp_path):
    """One file federated with its copy: every GlobalId is in both. Each element is not tested
    against its own copy (the duplicates rule), and the duplicates are listed; without the
    rule, every element clashes with its copy."""
    copy = tmp_path / "duplex-part-copy.ifc"
    shutil.copy(ARCH, copy)
    with pytest.warns(Warning, match=r"36 GlobalIds are in more than one file"):
        model = read_ifc([ARCH, copy], cache=False)
    assert len(model.duplicates()) == 36
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kept = find_clashes(model, clearance=C)
        none = find_clashes(model, clearance=C, rules="none")
    assert kept.set_aside.counts["duplicates"] == 36 and len(kept.set_aside.duplicates) == 36
    assert not any(c.a.global_id == c.b.global_id for c in kept)
    assert sum(c.a.global_id == c.b.global_id for c in none) == 36


def test_the_command_line_says_what_the_rules_set_aside(tmp_path, capsys):
    out_bcf = tmp_path / "clashes.bcf"
    code = main(["check", str(ARCH), "--clearance", str(C), "--json", "--no-cache",
                 "--no-snapshots", "--bcf", str(out_bcf)])
    report = json.loads(capsys.readouterr().out)
    assert code == 1
    rules = report["rules"]
    assert rules["system"] == {"on": False, "set_aside": 0}
    assert rules["fills"]["on"] and rules["fills"]["set_aside"] >= 1
    assert sum(r["set_aside"] for r in rules.values()) == sum(
        r["set_aside"] for r in find_clashes(read(ARCH), clearance=C).set_aside.as_json(
            read(ARCH))["rules"].values())
    import zipfile

    with zipfile.ZipFile(out_bcf) as z:
        markups = [z.read(n).decode() for n in z.namelist() if n.endswith("markup.bcf")]
    assert markups and all("Clash rules (fills, openings, assembly, connected, duplicates)"
                           in m for m in markups)
    code = main(["check", str(ARCH), "--clearance", str(C), "--no-cache", "--rules", "none"])
    captured = capsys.readouterr()
    assert code == 1 and "set" not in captured.err.splitlines()[-1]
    with pytest.raises(SystemExit):
        main(["check", str(ARCH), "--rules", "fills,colour"])
    assert "'colour' is not a clash rule" in capsys.readouterr().err


def test_groups_on_a_real_model_span_at_most_their_distance(arch):
    clashes = find_clashes(arch, clearance=C, rules="none")
    assert len(clashes) >= 20
    for distance in (3.0, 1.0):
        groups = group_clashes(clashes, distance)
        assert sum(len(g.clashes) for g in groups) == len(clashes)
        for g in groups:
            points = np.array([c.point for c in g.clashes])
            span = max((np.linalg.norm(p - q) for p, q in itertools.combinations(points, 2)),
                       default=0.0)
            assert span <= distance + 1e-9
        assert max(len(g.clashes) for g in groups) <= len(clashes) // 10
    by = {how: group_clashes(clashes, by=how) for how in ("element", "storey", "classes")}
    assert all(sum(len(g.clashes) for g in groups) == len(clashes) for groups in by.values())
    assert {len({tuple(sorted((c.a.ifc_class, c.b.ifc_class))) for c in g.clashes})
            for g in by["classes"]} == {1}
    storeys = {len({c.a.storey or c.b.storey for c in g.clashes}) for g in by["storey"]}
    assert storeys == {1}

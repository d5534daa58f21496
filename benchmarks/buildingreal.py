"""The building benchmark on real IFC models: pycinder and IfcClash on public models other people
made (Archicad, Revit), every pair either reports scored against exact geometry
(:mod:`pycinder.testing.realtruth`), and the clash step timed against IfcClash's in the same
run::

    models (files in a folder: see MODELS for where to get them)
      -> read_ifc (IfcOpenShell's iterator; the tessellation, cached per file)
      -> exact truth of every pair within a margin
      -> pycinder: the default query, hard clashes at d, clearance at c; with no rules (scored)
         and with the default rules (what they set aside, and the groups)
      -> IfcClash: its tree (its own tessellation), then collision, intersection at d and
         clearance at c (scored)
      -> a row per model, mode and system: clash seconds, reported, must, found, false, either

Run it as ``python -m benchmarks.buildingreal --models DIR`` (Markdown on stdout;
``--out FILE.md`` and ``--json FILE.json`` keep it). The public models are not in this
repository: :data:`MODELS` says where each is published.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pycinder.testing.realtruth import exact_truth, score

from .building import ifcclash_tree

DEPTH = 0.002
"""Metres: the hard-clash depth ``d`` (``min_depth``, IfcClash's intersection tolerance)."""
CLEARANCE = 0.01
"""Metres: the clearance ``c``."""
MARGIN = 0.02
"""Metres: pairs whose boxes lie farther apart than this, and than their default tolerance, are
apart by more (left out of the truth; no mode may report them)."""
REPEATS = 3
"""Timed runs of each mode of each system after a warm one; the fastest is kept."""

Say = Callable[[str], None]


@dataclass(frozen=True)
class RealModel:
    """A public model of the benchmark: its files and where they are published."""

    name: str
    files: tuple[str, ...]
    source: str


MODELS = (
    RealModel("FZK-Haus", ("AC20-FZK-Haus.ifc",),
              "Karlsruhe Institute of Technology, Archicad, IFC4 (ThatOpen/engine_web-ifc, "
              "tests/ifcfiles/public/)"),
    RealModel("Duplex", ("duplex.ifc",),
              "buildingSMART Common BIM Files, Duplex_A_20110907.ifc, Revit, IFC2X3, CC BY 4.0 "
              "(also ThatOpen/engine_web-ifc, tests/ifcfiles/public/duplex.ifc)"),
    RealModel("Duplex federated", ("duplex.ifc", "Duplex_Electrical_20121207.ifc"),
              "the Duplex's architecture with its electrical model (buildingSMART "
              "Sample-Test-Files, IFC 2x3/Duplex Apartment/)"),
    RealModel("Office", ("Office_A_20110811.ifc",),
              "buildingSMART Common BIM Files, Revit, IFC2X3 (ThatOpen/engine_web-ifc, "
              "tests/ifcfiles/public/)"),
)
"""The benchmark's models, in order."""


def _pairs_of(model: Any, clashes: Sequence[Any]) -> set[tuple[int, int]]:
    index = {(b.file, b.global_id): k for k, b in enumerate(model.bodies)}
    out = set()
    for c in clashes:
        i, j = index[(c.a.file, c.a.global_id)], index[(c.b.file, c.b.global_id)]
        out.add((min(i, j), max(i, j)))
    return out


def _group_figures(clashes: Sequence[Any]) -> dict[str, Any]:
    """The default groups' count, largest share of the clashes and widest span (metres)."""
    from pycinder.bim.groups import group_clashes

    groups = group_clashes(clashes)
    span = 0.0
    for g in groups:
        points = np.array([c.point for c in g.clashes])
        for p, q in itertools.combinations(points, 2):
            span = max(span, float(np.linalg.norm(p - q)))
    largest = max((len(g.clashes) for g in groups), default=0)
    return {"groups": len(groups), "largest_group": largest,
            "largest_share": largest / len(clashes) if clashes else 0.0, "group_span": span}


def _pycinder_rows(model: Any, truth: dict, names: list[str], depth: float, clearance: float,
                   repeats: int, say: Say) -> list[dict[str, Any]]:
    from pycinder.bim.ifc import find_clashes, make_detector

    rows = []
    for mode, value in (("default", None), ("min_depth", depth), ("clearance", clearance)):
        options = {} if mode == "default" else {mode: value}
        detector = make_detector(**options)
        say(f"real models: pycinder {mode}, {len(model.bodies):,} elements")
        find_clashes(model, detector=detector, rules="none")  # pipelines made, shapes cached
        best = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            clashes = find_clashes(model, detector=detector, rules="none")
            best = min(best, time.perf_counter() - t0)
        row: dict[str, Any] = {"system": "pycinder", "mode": mode, "value": value,
                               "clash_s": best}
        row.update(score(truth, _pairs_of(model, clashes), mode, value, names))
        ruled = find_clashes(model, detector=detector)
        row["with_rules"] = len(ruled)
        row["set_aside"] = dict(ruled.set_aside.counts)
        row.update(_group_figures(ruled))
        rows.append(row)
    return rows


def _ifcclash_rows(model: Any, paths: Sequence[Path], truth: dict, names: list[str],
                   depth: float, clearance: float, repeats: int, say: Say
                   ) -> list[dict[str, Any]]:
    """IfcClash's steps (:class:`ifcclash.Clasher`): its tree of the files' elements (its own
    tessellation), then each mode over every element against every other, timed as pycinder's
    are (after a warm run, the fastest of ``repeats``)."""
    say("real models: IfcClash's tree")
    tree, elements, tessellation = ifcclash_tree(paths)
    # IfcClash keys its elements by GlobalId alone (its groups' "elements"), so a GlobalId
    # that two files share is one element to it: mapped to the first body that has it.
    index: dict[str, int] = {}
    for k, b in enumerate(model.bodies):
        index.setdefault(b.global_id, k)
    calls = {"default": lambda: tree.clash_collision_many(elements, elements,
                                                          allow_touching=False),
             "min_depth": lambda: tree.clash_intersection_many(
                 elements, elements, tolerance=depth, check_all=True),
             "clearance": lambda: tree.clash_clearance_many(
                 elements, elements, clearance=clearance, check_all=True)}
    rows = []
    for mode, value in (("default", None), ("min_depth", depth), ("clearance", clearance)):
        say(f"real models: IfcClash {mode}")
        calls[mode]()  # warm, as pycinder's modes are
        seconds = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            results = [r for r in calls[mode]() if r.a.GlobalId != r.b.GlobalId]
            seconds = min(seconds, time.perf_counter() - t0)
        pairs = set()
        for r in results:
            i, j = index.get(r.a.GlobalId), index.get(r.b.GlobalId)
            if i is not None and j is not None and i != j:
                pairs.add((min(i, j), max(i, j)))
        row: dict[str, Any] = {"system": "IfcClash", "mode": mode, "value": value,
                               "clash_s": seconds, "tessellation_s": tessellation}
        # IfcClash's collision mode answers "do they touch or overlap": scored as the default
        # query (never a pair apart by its tolerance).
        row.update(score(truth, pairs, mode, value, names))
        rows.append(row)
    return rows


def run_real(folder: str | Path, models: Sequence[RealModel] = MODELS, *, depth: float = DEPTH,
             clearance: float = CLEARANCE, repeats: int = REPEATS, peers: bool = True,
             progress: Say | None = None) -> dict[str, Any]:
    """Run the benchmark on the models whose files are in ``folder``.

    Returns
    -------
    dict
        ``depth``, ``clearance``, ``adapter``, ``models`` (per model: ``name``, ``source``,
        ``files``, ``elements``, ``status`` ("ran" or "missing: FILE"), ``tessellation_s``,
        ``truth`` (pairs in the truth, by kind) and ``rows``), and ``totals`` (per system and
        mode, the clash seconds summed over the models that ran).
    """
    from pycinder.bim.ifc import read_ifc
    from pycinder.gpu.device import get_gpu

    say = progress or (lambda text: None)
    folder = Path(folder)
    out: dict[str, Any] = {"depth": depth, "clearance": clearance, "models": [],
                           "adapter": get_gpu().description}
    for m in models:
        entry: dict[str, Any] = {"name": m.name, "source": m.source, "files": list(m.files)}
        out["models"].append(entry)
        paths = [folder / f for f in m.files]
        missing = [p.name for p in paths if not p.exists()]
        if missing:
            entry["status"] = f"missing: {', '.join(missing)}"
            continue
        say(f"real models: reading {m.name}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            model = read_ifc(paths, cache=False)
            entry["tessellation_s"] = time.perf_counter() - t0
            names = [f"{b.ifc_class} {b.name}" for b in model.bodies]
            say(f"real models: exact truth of {m.name}")
            truth = exact_truth(model, MARGIN, [depth], progress=say)
            kinds: dict[str, int] = {}
            for p in truth.values():
                kinds[p.kind] = kinds.get(p.kind, 0) + 1
            entry.update(status="ran", elements=len(model.bodies), truth=kinds)
            rows = _pycinder_rows(model, truth, names, depth, clearance, repeats, say)
            if peers:
                rows += _ifcclash_rows(model, paths, truth, names, depth, clearance, repeats,
                                       say)
        entry["rows"] = rows
    totals: dict[str, dict[str, float]] = {}
    for entry in out["models"]:
        for row in entry.get("rows", []):
            system = totals.setdefault(row["system"], {})
            system[row["mode"]] = system.get(row["mode"], 0.0) + row["clash_s"]
    out["totals"] = totals
    return out


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:,.0f}" if seconds >= 0.1 else f"{seconds * 1e3:.1f}"


def markdown(r: dict[str, Any]) -> list[str]:
    """The benchmark as Markdown: a table of the models, one of the runs, the totals."""
    d, c = r["depth"], r["clearance"]
    lines = ["## Buildings as they are: real IFC models against IfcClash", "",
             f"Adapter: {r['adapter']}. Hard clashes at d = {d * 1e3:g} mm, clearance at "
             f"c = {c * 1e3:g} mm; the default query at its tolerance (1% of the smaller "
             "element's size). Every reported pair scored against exact geometry "
             "(`pycinder.testing.realtruth`: python-fcl distances, manifold3d overlap "
             "volumes). Reproduce: `python -m benchmarks.buildingreal --models DIR`.",
             "", "| model | elements | source | pairs in the truth |", "|---|---|---|---|"]
    for m in r["models"]:
        truth = ", ".join(f"{n} {k}" for k, n in sorted(m.get("truth", {}).items()))
        lines.append(f"| {m['name']} | {m.get('elements', '-')} | {m['source']} | "
                     f"{truth or m['status']} |")
    lines += ["", "| model | mode | system | clash ms | reported | must | found | false | "
                  "either | with rules | set aside | groups (largest, span) |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in r["models"]:
        for row in m.get("rows", []):
            mode = row["mode"] + (f" {row['value'] * 1e3:g} mm" if row["value"] else "")
            aside = ", ".join(f"{k} {v}" for k, v in row.get("set_aside", {}).items() if v)
            groups = (f"{row['groups']} ({row['largest_group']}, {row['group_span']:.2f} m)"
                      if "groups" in row else "-")
            lines.append(
                f"| {m['name']} | {mode} | {row['system']} | {_ms(row['clash_s'])} | "
                f"{row['reported']} | {row['must']} | {row['found']} | {row['false']} | "
                f"{row['either']} | {row.get('with_rules', '-')} | {aside or '-'} | "
                f"{groups} |")
    lines += ["", "The clash step, pycinder's time over IfcClash's, model by model:", "",
              "| model | default | min_depth | clearance |", "|---|---|---|---|"]
    for m in r["models"]:
        seconds = {(row["system"], row["mode"]): row["clash_s"] for row in m.get("rows", [])}
        if ("IfcClash", "default") not in seconds:
            continue
        ratios = [seconds[("pycinder", mode)] / max(seconds[("IfcClash", mode)], 1e-9)
                  for mode in ("default", "min_depth", "clearance")]
        lines.append(f"| {m['name']} | " + " | ".join(f"{x:.1f}x" for x in ratios) + " |")
    lines += ["", "| system | default ms | min_depth ms | clearance ms | min_depth / default | "
                  "clearance / default |", "|---|---|---|---|---|---|"]
    for system, t in r["totals"].items():
        base = t.get("default", 0.0) or float("nan")
        lines.append(f"| {system} | {_ms(t.get('default', 0.0))} | "
                     f"{_ms(t.get('min_depth', 0.0))} | {_ms(t.get('clearance', 0.0))} | "
                     f"{t.get('min_depth', 0.0) / base:.2f} | "
                     f"{t.get('clearance', 0.0) / base:.2f} |")
    lines += ["", "must: pairs the mode must report by exact geometry (hard clashes: an overlap "
              "holding a ball of diameter over d; clearance: closer than c; default: an overlap "
              "holding a ball of radius 0.71 t). false: pairs reported that the mode must never "
              "report (apart or touching; at most d/2 deep by a separating translation; farther "
              "than 9c/8). either: reported pairs between the two. Rows with no rules score "
              "every pair; 'with rules' is the default clash rules' count, 'set aside' what "
              "they set aside, and the groups are the default rules' clashes grouped by 3 m.", ""]
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.buildingreal",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--models", required=True, metavar="DIR",
                        help="the folder holding the models' files (see MODELS)")
    parser.add_argument("--only", nargs="*", default=None, help="model names to run")
    parser.add_argument("--no-ifcclash", action="store_true")
    parser.add_argument("--repeats", type=int, default=REPEATS)
    parser.add_argument("--out", default=None, help="write the Markdown here too")
    parser.add_argument("--json", default=None, help="write the figures here as JSON")
    args = parser.parse_args(argv)
    chosen = [m for m in MODELS if args.only is None or m.name in args.only]
    r = run_real(args.models, chosen, repeats=args.repeats, peers=not args.no_ifcclash,
                 progress=lambda text: print(text, file=sys.stderr, flush=True))
    text = "\n".join(markdown(r))
    print(text)
    if args.out:
        Path(args.out).write_text(text, encoding="utf-8")
    if args.json:
        Path(args.json).write_text(json.dumps(r, indent=1, default=float) + "\n",
                                   encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())


__all__ = ["CLEARANCE", "DEPTH", "MARGIN", "MODELS", "RealModel", "markdown", "run_real"]

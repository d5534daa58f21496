"""The ``building`` benchmark: generated IFC buildings with exact truth, pycinder against
IfcClash, at the origin and in map coordinates.

    generate (pycinder.testing.buildings) -> three federated IFC4 files, at the origin and moved
        -> pycinder (read_ifc, find_clashes) and IfcClash (its tree) in each mode
        -> each answer scored against the exact truth (pycinder.testing.buildingscore),
           grouped, timed
        -> `pycinder check ... --json` run as a user runs it, compared with find_clashes

Each size is generated once (:func:`~pycinder.testing.buildings.generate`) and written twice as
three federated files (architecture, structure, MEP): at the origin, and in map coordinates, its
site placed at :data:`MAP_OFFSET` (500 km, 500 km, 0), so that every element's world coordinates
move by it while its coordinates in the file stay the same
(:func:`~pycinder.testing.buildings.write_ifc`). Both systems read the same files. The runs
(:data:`PYCINDER_RUNS`, :data:`IFCCLASH_RUNS`):

* at the origin, the original table: pycinder's default query, ``min_depth`` 10 mm and
  ``clearance`` 50 mm; IfcClash's intersection (tolerance 10 mm), collision and clearance
  (50 mm) modes;
* at the origin and in map coordinates: pycinder's ``min_depth`` 2 mm and 1 mm and
  ``clearance`` 2 mm; IfcClash's intersection mode at tolerances of 2 mm and 1 mm and its
  clearance mode at 2 mm.

Every answer is scored against the exact truth (:func:`~pycinder.testing.buildingscore.score`:
every pair deeper than ``d`` found, no touching, grazing or apart pair reported), pycinder's
depths and distances are checked against the true ones within their stated bounds, and the
clashes are grouped (pycinder's :func:`~pycinder.bim.groups.group_clashes` at 3 m, IfcClash's
smart grouping at 3 m, :func:`smart_group_count`). For the sizes in ``cli_sizes``, ``pycinder
check architecture.ifc structure.ifc mep.ifc --min-depth 0.002 --json`` runs in a process of its
own at both placements, and its pairs are compared with those of
:func:`~pycinder.bim.ifc.find_clashes`. The report leaves a row for the dense-mesh case
(:func:`dense_entry`).

``python -m benchmarks.building --elements 3000 20000``, from a checkout with the ``bench``
extra, runs it and prints its Markdown; ``pycinder bench building`` runs the same two sizes and
writes JSON and Markdown. The names of :mod:`pycinder.testing.buildings` (the building and its
truth) and :mod:`pycinder.testing.buildingscore` (the scoring) are importable from here too.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from pycinder.testing.buildings import (CASES, CIRCLE_SEGMENTS, DISCIPLINES, ELEMENTS_PER_CELL,
                                        EXACT, GRAZE, MARGIN, PITCH, SHALLOW, SLAB, Building, D,
                                        H, Part, Relation, W, chord_error, generate, relation,
                                        write_federated, write_ifc)
from pycinder.testing.buildingscore import (CLEARANCE, DEPTH, check_depths, check_distances,
                                            group_counts, must_not_report, must_report, score,
                                            truth_classes)
from pycinder.util.optional import require

__all__ = ["CASES", "CIRCLE_SEGMENTS", "CLEARANCE", "CLI_DEPTH", "DENSE_JSON", "DEPTH",
           "DISCIPLINES", "ELEMENTS_PER_CELL", "EXACT", "FINE_CLEARANCE", "FINE_DEPTHS",
           "GRAZE", "IFCCLASH_RUNS", "MAP_OFFSET", "MARGIN", "PITCH", "PLACEMENTS",
           "PYCINDER_RUNS", "SHALLOW", "SLAB", "Building", "D", "H", "Part", "Relation", "W",
           "check_depths", "check_distances", "chord_error", "cli_check", "dense_entry",
           "generate", "group_counts", "ifcclash_tree", "main", "markdown", "must_not_report",
           "must_report", "relation", "run_building", "score", "smart_group_count",
           "truth_classes", "write_federated", "write_ifc"]

MAP_OFFSET = (500_000.0, 500_000.0, 0.0)
"""Where the building's site is placed in map coordinates (metres): 707 km from the origin."""
PLACEMENTS = (("origin", (0.0, 0.0, 0.0)), ("map", MAP_OFFSET))
"""Each placement's name and its site's offset."""
FINE_DEPTHS = (0.002, 0.001)
"""Hard-clash depths ``d`` run at both placements (metres)."""
FINE_CLEARANCE = 0.002
"""Clearance ``c`` run at both placements (metres)."""
_FINE = [("min_depth", d) for d in FINE_DEPTHS] + [("clearance", FINE_CLEARANCE)]
PYCINDER_RUNS: dict[str, list[tuple[str, float]]] = {
    "origin": [("default", DEPTH), ("min_depth", DEPTH), ("clearance", CLEARANCE), *_FINE],
    "map": list(_FINE)}
"""pycinder's runs at each placement: the mode and its figure (``d``, or ``c`` for clearance;
the default query is scored against ``d``)."""
_IFCCLASH_FINE = [("intersection", d) for d in FINE_DEPTHS] + [("clearance", FINE_CLEARANCE)]
IFCCLASH_RUNS: dict[str, list[tuple[str, float]]] = {
    "origin": [("intersection", DEPTH), ("collision", DEPTH), ("clearance", CLEARANCE),
               *_IFCCLASH_FINE],
    "map": list(_IFCCLASH_FINE)}
"""IfcClash's runs at each placement: the intersection mode's tolerance, the clearance, or
(collision, which takes no figure) the ``d`` it is scored against."""
CLI_DEPTH = 0.002
"""``--min-depth`` of the command-line runs (metres)."""
DENSE_JSON = Path("benchmarks") / "results" / "dense.json"
"""Where the dense-mesh benchmark (:mod:`benchmarks.dense`) leaves its figures,
relative to the working folder: the building report shows them in its dense-mesh row."""

Say = Callable[[str], None]


def _key(a: str, b: str) -> tuple[str, str]:
    return (a, b) if a <= b else (b, a)


def _scored(building: Building, reported: set[tuple[str, str]], mode: str,
            value: float) -> dict[str, Any]:
    """:func:`score` of a run: ``value`` is ``c`` for clearance, else ``d``."""
    if mode == "clearance":
        return score(building, reported, mode, clearance=value)
    return score(building, reported, mode, depth=value)


def _classes(building: Building, mode: str, value: float) -> dict[str, int]:
    """:func:`truth_classes` of a mode and its figure (``c`` for clearance, else ``d``)."""
    if mode == "clearance":
        return truth_classes(building, mode, clearance=value)
    return truth_classes(building, mode, depth=value)


def _pycinder_runs(model: Any, building: Building, placement: str,
                   say: Say) -> tuple[list[dict[str, Any]], dict[float, list[Any]]]:
    """pycinder's runs of ``placement`` on a read model; the rows, and the clashes of each
    ``min_depth`` run by its depth (for :func:`cli_check`)."""
    from pycinder.bim import ifc

    rows, hard = [], {}
    for mode, value in PYCINDER_RUNS[placement]:
        say(f"building: pycinder {mode} {value * 1e3:g} mm, {placement}, "
            f"{len(model.bodies):,} elements")
        options = {} if mode == "default" else {mode: value}
        t0 = time.perf_counter()
        clashes = ifc.find_clashes(model, **options)  # type: ignore[arg-type]
        clash_s = time.perf_counter() - t0
        reported = {_key(c.a.global_id, c.b.global_id) for c in clashes}
        row: dict[str, Any] = {"system": "pycinder", "mode": mode, "value": value,
                               "placement": placement, "clash_s": clash_s,
                               "tessellation_s": model.seconds["tessellation"]}
        row.update(_scored(building, reported, mode, value))
        t0 = time.perf_counter()
        row.update(group_counts(clashes))
        row["grouping_s"] = time.perf_counter() - t0
        if mode == "min_depth":
            row.update(check_depths(building, clashes))
            hard[value] = clashes
        elif mode == "clearance":
            row.update(check_distances(building, clashes))
        rows.append(row)
    return rows, hard


def ifcclash_tree(paths: Sequence[Path]) -> tuple[Any, list[Any], float]:
    """IfcClash's first step (:class:`ifcclash.Clasher`): its iterator tessellates every element
    of the files (but features) into one tree.

    Returns
    -------
    tree : ifcopenshell.geom.tree
    elements : list
        The elements, one per GlobalId (IfcClash keys them by GlobalId alone).
    seconds : float
        How long the tree took.
    """
    import logging

    require("ifcopenshell", "the building benchmark", "bim")
    import ifcopenshell.geom
    try:
        from ifcclash.ifcclash import Clasher, ClashSettings
    except ImportError as exc:
        raise ImportError("the building benchmark's IfcClash runs need ifcclash: pip install "
                          "ifcclash") from exc
    settings = ClashSettings()
    settings.logger = logging.getLogger("ifcclash")
    clasher = Clasher(settings)
    t0 = time.perf_counter()
    clasher.tree = ifcopenshell.geom.tree(backend="opencascade.trianglebvh")
    clasher.create_group("a")
    for p in paths:
        clasher.add_collision_objects("a", clasher.load_ifc(str(p)), {"file": str(p)})
    seconds = time.perf_counter() - t0
    return clasher.tree, list(clasher.groups["a"]["elements"].values()), seconds


def smart_group_count(results: Sequence[Any], distance: float = 3.0) -> int:
    """How many smart groups IfcClash makes of its results (``Clasher.smart_group_clashes``:
    scikit-learn's OPTICS, ``min_samples=2``, ``max_eps`` the distance, on the midpoints of each
    clash's ``p1`` and ``p2``; a clash it leaves unclustered is a group of its own).

    Parameters
    ----------
    results : sequence
        IfcOpenShell's clash results (``ifcopenshell.geom.tree.clash_*_many``), an element's
        clash with itself left out.
    distance : float
        ``max_clustering_distance`` in metres.
    """
    import logging

    from ifcclash.ifcclash import Clasher, ClashSettings

    if not results:
        return 0
    settings = ClashSettings()
    settings.logger = logging.getLogger("ifcclash")
    clashes = {f"{r.a.GlobalId}-{r.b.GlobalId}": {
        "a_global_id": r.a.GlobalId, "b_global_id": r.b.GlobalId,
        "p1": list(r.p1), "p2": list(r.p2)} for r in results}
    if len(clashes) == 1:  # OPTICS needs two points
        return 1
    grouped = Clasher(settings).smart_group_clashes(
        [{"name": "building", "a": [], "mode": "intersection", "clashes": clashes}],
        distance)
    return len(grouped["building"][0])


def _ifcclash_runs(paths: Sequence[Path], building: Building, placement: str,
                   say: Say) -> list[dict[str, Any]]:
    """IfcClash's runs of ``placement``, with its own steps (:class:`ifcclash.Clasher`): its
    iterator fills one tree (tessellation), then each mode clashes the elements against
    themselves (an element's clash with itself left out), and its smart grouping groups the
    clashes."""
    say(f"building: IfcClash's tree, {placement}")
    tree, elements, tess = ifcclash_tree(paths)
    calls = {"intersection": lambda v: tree.clash_intersection_many(
                elements, elements, tolerance=v, check_all=True),
             "collision": lambda v: tree.clash_collision_many(
                elements, elements, allow_touching=False),
             "clearance": lambda v: tree.clash_clearance_many(
                elements, elements, clearance=v, check_all=True)}
    rows = []
    for mode, value in IFCCLASH_RUNS[placement]:
        say(f"building: IfcClash {mode} {value * 1e3:g} mm, {placement}, "
            f"{len(elements):,} elements")
        t0 = time.perf_counter()
        results = [r for r in calls[mode](value) if r.a.GlobalId != r.b.GlobalId]
        clash_s = time.perf_counter() - t0
        reported = {_key(r.a.GlobalId, r.b.GlobalId) for r in results}
        row: dict[str, Any] = {"system": "IfcClash", "mode": mode, "value": value,
                               "placement": placement, "tessellation_s": tess,
                               "clash_s": clash_s}
        row.update(_scored(building, reported, mode, value))
        t0 = time.perf_counter()
        row["smart_groups"] = smart_group_count(results)
        row["grouping_s"] = time.perf_counter() - t0
        rows.append(row)
    return rows


def cli_check(folder: Path, building: Building, api: Sequence[Any], placement: str,
              min_depth: float = CLI_DEPTH) -> dict[str, Any]:
    """Run ``pycinder check architecture.ifc structure.ifc mep.ifc --min-depth D --json`` in a
    process of its own, in ``folder``, as a user runs it (its tessellation cache in an empty
    temporary folder), and compare its pairs with the API's.

    Parameters
    ----------
    folder : Path
        Holds the three files of :func:`~pycinder.testing.buildings.write_federated`.
    building : Building
    api : sequence of Clash
        :func:`~pycinder.bim.ifc.find_clashes` of the same files at ``min_depth``.
    placement : str
    min_depth : float

    Returns
    -------
    dict
        ``command``, ``placement``, ``elements``, ``exit`` (the exit status), ``wall_s``,
        ``pairs`` (how many), ``api_pairs``, ``same_pairs`` (the same GlobalId pairs as
        ``api``), ``depth_diff`` (the largest difference between the two answers' depths of
        one pair, metres), ``depth_bound`` (the largest ``depth_error`` of either, metres),
        ``groups`` (how many the JSON lists), and :func:`score`'s figures of its pairs; or,
        where it printed no JSON, ``same_pairs`` False and ``error``.
    """
    names = [f"{d}.ifc" for d in DISCIPLINES]
    args = ["check", *names, "--min-depth", f"{min_depth:g}", "--json"]
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "PYCINDER_CACHE_DIR": cache}
        t0 = time.perf_counter()
        run = subprocess.run([sys.executable, "-m", "pycinder", *args], cwd=folder, env=env,
                             capture_output=True, text=True, timeout=3600, check=False)
        wall = time.perf_counter() - t0
    out: dict[str, Any] = {"command": "pycinder " + " ".join(args), "placement": placement,
                           "exit": run.returncode, "wall_s": wall,
                           "elements": len(building.parts), "min_depth": min_depth}
    try:
        report = json.loads(run.stdout)
    except json.JSONDecodeError:
        out.update(same_pairs=False, error=(run.stderr or run.stdout).strip()[-500:])
        return out
    cli = {_key(p["a_global_id"], p["b_global_id"]): p for p in report["pairs"]}
    mine = {_key(c.a.global_id, c.b.global_id): c for c in api}
    both = cli.keys() & mine.keys()
    out.update(pairs=len(cli), api_pairs=len(mine), same_pairs=cli.keys() == mine.keys(),
               groups=len(report.get("groups", [])),
               depth_diff=max((abs(cli[k]["depth"] - mine[k].depth) for k in both),
                              default=0.0),
               depth_bound=max((max(cli[k]["depth_error"], mine[k].depth_error or 0.0)
                                for k in both), default=0.0))
    out.update(score(building, set(cli), "min_depth", depth=min_depth))
    return out


def dense_entry(path: str | os.PathLike[str] | None = DENSE_JSON) -> dict[str, Any]:
    """The dense-mesh case's row of the building report: the figures the dense-mesh benchmark
    (:mod:`benchmarks.dense`, two overlapping meshes of 20,000 faces each) wrote to
    ``path``, or ``{"status": "not run"}`` where there is no such file.

    Returns
    -------
    dict
        ``status`` (``"run"``, ``"not run"`` or ``"unreadable"``, then with ``why``),
        ``source`` (the path), and where run ``rows``: the file's ``rows`` (or the file's
        object as one row), each row's plain values (numbers, strings, booleans) only.
    """
    if path is None or not Path(path).is_file():
        return {"status": "not run", "source": None if path is None else os.fspath(path)}
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        return {"status": "unreadable", "source": os.fspath(path), "why": str(exc)}
    rows = data.get("rows", [data]) if isinstance(data, dict) else data
    plain = (int, float, str, bool)
    rows = [{k: v for k, v in row.items() if isinstance(v, plain)}
            for row in (rows if isinstance(rows, list) else []) if isinstance(row, dict)]
    return {"status": "run", "source": os.fspath(path), "rows": rows}


def _versions() -> dict[str, str]:
    from importlib import metadata

    out = {}
    for name in ("pycinder", "ifcopenshell", "ifcclash", "scikit-learn", "wgpu"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def run_building(sizes: Sequence[int] = (3000, 20000), *,
                 progress: Callable[[str], None] | None = None, peers: bool = True,
                 cli_sizes: Sequence[int] = (3000,),
                 dense: str | os.PathLike[str] | None = DENSE_JSON) -> dict[str, Any]:
    """The building benchmark: each size generated, written as three IFC4 files at each
    placement (:data:`PLACEMENTS`), read and checked by pycinder and by IfcClash in each of
    their runs (:data:`PYCINDER_RUNS`, :data:`IFCCLASH_RUNS`), in the same process.

    Parameters
    ----------
    sizes : sequence of int
        Elements wanted (:func:`~pycinder.testing.buildings.generate`).
    progress : callable, optional
        Called with a line of text before each step.
    peers : bool
        Run IfcClash too.
    cli_sizes : sequence of int
        Sizes (as given in ``sizes``) at which ``pycinder check`` runs too (:func:`cli_check`).
    dense : path, optional
        The dense-mesh benchmark's JSON (:func:`dense_entry`).

    Returns
    -------
    dict
        ``rows`` (one per size, placement, system, mode and figure: ``value`` (``d`` or ``c``),
        :func:`score`'s figures, ``tessellation_s``, ``clash_s``, groups and ``grouping_s``,
        and pycinder's depth or distance checks), ``sizes`` (per size: ``elements``,
        ``triangles``, ``truth`` counts and ``classes``: the truth's must, never and either
        counts of each figure), ``cli`` (:func:`cli_check`'s answers), ``dense``
        (:func:`dense_entry`), ``left_out`` (IfcClash's reason, when it could not run),
        ``offset``, ``depth``, ``clearance``, ``adapter``, ``versions``.
    """
    from pycinder.bim import ifc

    say = progress or (lambda msg: None)
    out: dict[str, Any] = {"depth": DEPTH, "clearance": CLEARANCE, "offset": list(MAP_OFFSET),
                           "rows": [], "sizes": [], "cli": [], "left_out": {}}
    figures = [("min_depth", v) for v in (DEPTH, *FINE_DEPTHS)] + [
        ("clearance", v) for v in (CLEARANCE, FINE_CLEARANCE)]
    for n in sizes:
        say(f"building: generating {n:,} elements")
        building = generate(n)
        size: dict[str, Any] = {
            "elements": len(building.parts), "truth": building.counts(),
            "classes": [{"mode": m, "value": v, **_classes(building, m, v)} for m, v in figures]}
        rows: list[dict[str, Any]] = []
        with tempfile.TemporaryDirectory() as root:
            for placement, offset in PLACEMENTS:
                folder = Path(root) / placement
                paths = write_federated(building, folder, offset=offset)
                say(f"building: pycinder reads {len(building.parts):,} elements, {placement}")
                with tempfile.TemporaryDirectory() as cache:
                    model = ifc.read_ifc(paths, cache=cache)
                size.setdefault("triangles", sum(len(b.mesh.faces) for b in model.bodies))
                got, hard = _pycinder_runs(model, building, placement, say)
                rows += got
                del model
                if n in cli_sizes and CLI_DEPTH in hard:
                    say(f"building: pycinder check --min-depth {CLI_DEPTH:g} --json, "
                        f"{placement}")
                    out["cli"].append(cli_check(folder, building, hard[CLI_DEPTH], placement))
                if peers and "IfcClash" not in out["left_out"]:
                    try:
                        rows += _ifcclash_runs(paths, building, placement, say)
                    except ImportError as exc:
                        out["left_out"]["IfcClash"] = str(exc)
        for row in rows:
            row["elements"] = len(building.parts)
        out["rows"] += rows
        out["sizes"].append(size)
    from pycinder.gpu.device import get_gpu

    out["adapter"] = get_gpu().description
    out["versions"] = _versions()
    out["dense"] = dense_entry(dense)
    return out


# -- the report -----------------------------------------------------------------------------


def _mm(value: float) -> str:
    return f"{value * 1e3:g}"


def _figure(row: dict[str, Any]) -> str:
    """A row's figure in words: ``d = 2 mm`` or ``c = 50 mm``."""
    return f"{'c' if row['mode'] == 'clearance' else 'd'} = {_mm(row['value'])} mm"


def _score_table(rows: Sequence[dict[str, Any]]) -> list[str]:
    lines = [("| elements | placement | system | mode | d or c (mm) | must find | found | "
              "recall | touching reported | grazes (<= d/2) reported | near reported | "
              "either way | false | reported | clash s |"), "|" + "---|" * 15]
    for row in rows:
        lines.append(
            f"| {row['elements']:,} | {row['placement']} | {row['system']} | {row['mode']} | "
            f"{_mm(row['value'])} | {row['must']:,} | {row['found']:,} | {row['recall']:.1%} | "
            f"{row['touching']:,} | {row['grazes']:,} | {row['near']:,} | {row['either']:,} | "
            f"{row['false']:,} | {row['reported']:,} | {row['clash_s']:.1f} |")
    return lines


def _group_table(rows: Sequence[dict[str, Any]]) -> list[str]:
    lines = [("| elements | placement | system | mode | d or c (mm) | clashes | groups (3 m) | "
              "groups by element | grouping s |"), "|" + "---|" * 9]
    for row in rows:
        groups = row.get("groups", row.get("smart_groups"))
        if groups is None:
            continue
        by_element = row.get("groups_by_element")
        lines.append(
            f"| {row['elements']:,} | {row['placement']} | {row['system']} | {row['mode']} | "
            f"{_mm(row['value'])} | {row['reported']:,} | {groups:,} | "
            f"{'-' if by_element is None else f'{by_element:,}'} | "
            f"{row.get('grouping_s', 0.0):.1f} |")
    return lines


def _checks(rows: Sequence[dict[str, Any]]) -> list[str]:
    lines = []
    for row in rows:
        for figure, plural in (("depth", "depths"), ("distance", "distances")):
            if f"{plural}_checked" in row:
                lines.append(
                    f"- pycinder {row['mode']} {_figure(row)}, {row['elements']:,} elements, "
                    f"{row['placement']}: {row[f'{plural}_checked']:,} {plural} checked against "
                    f"the truth, {row[f'{plural}_outside']:,} outside their bounds, largest "
                    f"difference {row[f'{figure}_worst'] * 1e3:.3g} mm.")
    return lines


def _failures(rows: Sequence[dict[str, Any]]) -> list[str]:
    lines = []
    for row in rows:
        for what, key in (("missed", "missed"), ("reported that must not be", "wrong")):
            if row.get(key):
                count = (row["must"] - row["found"]) if key == "missed" else row["false"]
                lines.append(f"- {row['system']} {row['mode']} {_figure(row)}, "
                             f"{row['elements']:,} elements, {row['placement']}: {count:,} "
                             f"{what}, among them: " + "; ".join(row[key]) + ".")
    return lines


def _cli_lines(entries: Sequence[dict[str, Any]]) -> list[str]:
    lines = []
    for c in entries:
        head = f"- `{c['command']}`, {c['elements']:,} elements, {c['placement']}: "
        if "pairs" not in c:
            lines.append(head + f"exit {c['exit']}, no JSON: {c.get('error', '')}")
            continue
        same = "the same pairs as" if c["same_pairs"] else "NOT the same pairs as"
        lines.append(
            head + f"exit {c['exit']}, {c['pairs']:,} pairs in {c['groups']:,} groups, {same} "
            f"`find_clashes(model, min_depth={c['min_depth']:g})` ({c['api_pairs']:,}); their "
            f"depths differ by at most {c['depth_diff'] * 1e3:.3g} mm (bounds up to "
            f"{c['depth_bound'] * 1e3:.3g} mm); against the truth: {c['found']:,} of "
            f"{c['must']:,} found, {c['touching']:,} touching, {c['grazes']:,} grazes, "
            f"{c['false']:,} false; {c['wall_s']:.1f} s wall, reading the files included.")
    return lines


def _dense_lines(dense: dict[str, Any] | None) -> list[str]:
    head = "Dense meshes (two overlapping 20,000-face meshes, `benchmarks.dense`): "
    dense = dense or {"status": "not run", "source": None}
    if dense["status"] != "run":
        why = dense.get("why") or f"no {dense.get('source')}"
        return [head + f"{dense['status']} ({why})."]
    lines = [head + f"from `{Path(dense['source']).name}`:", "",
             "| case | query | first query s | prepared query s | reported | right |",
             "|---|---|---:|---:|---|---|"]
    for row in dense["rows"]:
        if {"case", "option", "first_s", "s"} <= row.keys():
            lines.append(f"| {row['case']} | {row['option']} | {row['first_s']:.2f} | "
                         f"{row['s']:.2f} | {'yes' if row.get('reported') else 'no'} | "
                         f"{row.get('right', '')} |")
        else:  # a file of another shape: its plain values as they are
            lines.append("| " + ", ".join(f"{k} {v}" for k, v in row.items()) + " | | | | | |")
    return lines


def markdown(r: dict[str, Any]) -> list[str]:
    """The report's section for the building benchmark (:func:`run_building`'s answer)."""
    rows = [{"placement": "origin", "either": 0,
             "value": r["clearance"] if row["mode"] == "clearance" else r["depth"], **row}
            for row in r["rows"]]
    offset = r.get("offset", MAP_OFFSET)
    far = sum(v * v for v in offset) ** 0.5
    lines = ["## Building: IFC in, clash modes, against IfcClash", "",
             (f"Adapter: {r.get('adapter', '?')}. Generated IFC4 buildings, three federated "
              "files, exact truth (`pycinder.testing.buildings`), at the origin and in map "
              "coordinates (placement `map`: the same files with the site placed at "
              f"({', '.join(f'{v / 1e3:g} km' for v in offset)}), {far / 1e3:.0f} km out). "
              "d: the hard-clash depth (pycinder's `min_depth`, IfcClash's intersection "
              "tolerance); c: the clearance.")]
    if r.get("versions"):
        lines += ["", "Versions: " + ", ".join(f"{k} {v}" for k, v in r["versions"].items())
                  + "."]
    lines.append("")
    for s in r["sizes"]:
        counts = ", ".join(f"{v:,} {k}" for k, v in sorted(s["truth"].items()))
        tri = f", {s['triangles']:,} triangles" if "triangles" in s else ""
        lines.append(f"- {s['elements']:,} elements{tri}; pairs within 0.2 m: {counts}")
        lines += [f"  - {'c' if k['mode'] == 'clearance' else 'd'} = {_mm(k['value'])} mm: "
                  f"{k['must']:,} must be reported, {k['either']:,} either way, "
                  f"{k['never']:,} must not" for k in s.get("classes", [])]
    lines += ["", *_score_table(rows)]
    for name, why in r.get("left_out", {}).items():
        lines += ["", f"{name} was left out: {why}"]
    tess = {(row["elements"], row["placement"], row["system"]): row["tessellation_s"]
            for row in rows}
    lines += ["", ("Tessellation (reading the three files: IfcOpenShell's iterator, and "
                   "pycinder's bodies or IfcClash's tree):"), "",
              "| elements | placement | system | tessellation s |", "|---|---|---|---|"]
    lines += [f"| {n:,} | {p} | {s} | {t:.1f} |" for (n, p, s), t in tess.items()]
    lines += ["", ("Groups: pycinder's `group_clashes` (DBSCAN at 3 m, and clashes sharing an "
                   "element); IfcClash's smart grouping (`Clasher.smart_group_clashes`, OPTICS "
                   "at 3 m); by element: pycinder's groups of clashes sharing an element alone."),
              "", *_group_table(rows), "", *_checks(rows)]
    lines += ["", "Scoring failures (pairs missed, pairs reported that must not be):",
              *(_failures(rows) or ["- none."])]
    if r.get("cli"):
        lines += ["", ("The command line, run as a user runs it (a process of its own, its "
                       "tessellation cache empty):"), "", *_cli_lines(r["cli"])]
    lines += ["", *_dense_lines(r.get("dense"))]
    lines += ["", ("must find: for default, min_depth and IfcClash's intersection and collision "
                   "modes, the pairs deeper than d (beyond the tessellation's error); for "
                   "clearance, the pairs closer than c. false: pairs reported that the mode must "
                   "never report (apart for the default and collision; apart, touching or at "
                   "most d/2 deep for the hard-clash modes; farther than 9c/8 for clearance). "
                   "either way: reported pairs that are neither (for the hard-clash modes, "
                   "deeper than d/2 and at most d deep: at d = 1 mm, the 1 mm grazes). grazes: "
                   "pairs more than 0 and at most d/2 deep (d = 10 mm for the clearance rows). "
                   "The default mode promises only its tolerance contract (pairs at least t "
                   "apart never reported, pairs at least 2t deep always, t = 1% of the smaller "
                   "body's size): touching pairs may go either way.")]
    return [*lines, ""]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.building",
                                     description="The building benchmark, as Markdown.")
    parser.add_argument("--elements", type=int, nargs="+", default=[3000])
    parser.add_argument("--no-ifcclash", action="store_true")
    parser.add_argument("--cli-elements", type=int, nargs="*", default=[3000],
                        help="sizes at which `pycinder check` runs too (default 3000)")
    parser.add_argument("--dense", default=str(DENSE_JSON),
                        help=f"the dense-mesh benchmark's JSON (default {DENSE_JSON})")
    parser.add_argument("--out", default=None, help="write the Markdown here too")
    parser.add_argument("--json", default=None, help="write the figures here as JSON")
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = run_building(args.elements, peers=not args.no_ifcclash,
                         cli_sizes=args.cli_elements, dense=args.dense,
                         progress=lambda m: print(m, file=sys.stderr, flush=True))
    text = "\n".join(markdown(r))
    print(text)
    if args.out:
        Path(args.out).write_text(text, encoding="utf-8")
    if args.json:
        Path(args.json).write_text(json.dumps(r, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())

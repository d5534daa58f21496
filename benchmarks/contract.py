"""The contract sweep: closed solids at the contract's own margins, holed and thin-walled bodies,
and open bodies, each answered by pycinder and by python-fcl and scored against a truth fixed by
the construction or by exact geometry (``pycinder bench contract``).

python-fcl tests surfaces: it reports a pair whose surfaces meet and nothing else, so it misses
solids nested inside others, and a pair of solids it calls apart can still be one pycinder must
report. The table says so per group rather than hiding it in one number.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import trimesh

from pycinder.testing import (first_contact, ground_truth, holed_plate, holed_scene,
                              open_body_cases, random_rotation, surface_distance)

TOLERANCE = 0.01
"""World tolerance of every case (bodies are about 1 across)."""


def _margin_cases(t: float) -> list[tuple[str, list, list, bool]]:
    """Solids brought to first contact along a direction (python-fcl's exact distance), then set
    exactly ``t`` apart (never to be reported) and ``2 t`` deep (always)."""
    out = []
    shapes = {
        "box-box": (trimesh.creation.box((1.0, 0.8, 0.6)), trimesh.creation.box((0.5, 0.5, 0.5))),
        "sphere-box": (trimesh.creation.icosphere(subdivisions=3, radius=0.45),
                       trimesh.creation.box((0.6, 0.5, 0.4))),
        "torus-sphere": (trimesh.creation.torus(major_radius=0.5, minor_radius=0.15,
                                                major_sections=48, minor_sections=24),
                         trimesh.creation.icosphere(subdivisions=3, radius=0.3)),
        "holed plate-cylinder": (holed_plate(1.0, 3),
                                 trimesh.creation.cylinder(radius=0.2, height=0.6, sections=32)),
    }
    for k, (name, (a, b)) in enumerate(shapes.items()):
        rot = random_rotation(np.random.default_rng(k + 1))
        world = b.copy()
        world.apply_transform(rot)
        d = np.array([1.0, 0.4 + 0.2 * k, 0.3])
        d /= np.linalg.norm(d)
        for label, s, expected in (("t apart", first_contact(a, world, d, gap=t), False),
                                   ("2t deep", first_contact(a, world, d) - 2 * t * (1 + 1e-6),
                                    True)):
            pose = rot.copy()
            pose[:3, 3] += s * d
            out.append((f"{name}, {label}", [a, b], [np.eye(4), pose], expected))
    return out


def run_contract(seeds: int = 3) -> list[dict[str, Any]]:
    """Every group's cases answered by pycinder and python-fcl, one row per group."""
    from pycinder.detector import Detector

    t = TOLERANCE
    groups: dict[str, list[tuple[str, list, list, bool]]] = {
        "closed solids at the margins (t apart, 2t deep)": _margin_cases(t),
        "open bodies as surfaces": open_body_cases(t),
    }
    rows = []
    for group, cases in groups.items():
        scores = {"pycinder": [], "python-fcl": []}
        for name, meshes, transforms, expected in cases:
            det = Detector(tolerance=t)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # open bodies are announced; expected here
                ours = len(det.find_collisions(meshes, transforms).pairs) > 0
            theirs = surface_distance(meshes[0], meshes[1], transforms) <= 0.0
            scores["pycinder"].append((name, ours == expected))
            scores["python-fcl"].append((name, theirs == expected))
        rows.append({"group": group, "cases": len(cases),
                     **{k: {"right": sum(ok for _, ok in v),
                            "wrong": [n for n, ok in v if not ok]} for k, v in scores.items()}})
    # Holed and thin-walled bodies at random poses, scored against manifold3d's exact geometry.
    ours_row = {"right": 0, "wrong": []}
    fcl_row = {"right": 0, "wrong": []}
    cases = 0
    for seed in range(seeds):
        meshes, transforms = holed_scene(12, 100 + seed)
        truth = ground_truth(meshes, transforms, tolerance=t)
        found = {tuple(p) for p in Detector(tolerance=t).find_collisions(meshes, transforms)
                 .pairs.tolist()}
        worlds = []
        for m, pose in zip(meshes, transforms):
            w = m.copy()
            w.apply_transform(pose)
            worlds.append(w)
        for pairs, must in ((truth.overlap, True), (truth.separate, False)):
            for i, j in pairs.tolist():
                cases += 1
                meet = surface_distance(worlds[i], worlds[j]) <= 0.0
                for row, answer in ((ours_row, (i, j) in found), (fcl_row, meet)):
                    if answer == must:
                        row["right"] += 1
                    else:
                        row["wrong"].append(f"seed {seed}: bodies {i}, {j}")
    rows.append({"group": "holed and thin-walled solids at random poses (exact geometry)",
                 "cases": cases, "pycinder": ours_row, "python-fcl": fcl_row})
    return rows


def markdown(rows: list[dict[str, Any]]) -> list[str]:
    lines = ["## The contract sweep", "",
             f"Tolerance {TOLERANCE}; bodies about 1 across. A case is right when a pair that must "
             "be reported is, and a pair at least a tolerance apart is not (python-fcl: its "
             "surfaces meet). python-fcl tests surfaces, so solids inside others are no "
             "collision to it.", "",
             "| group | cases | pycinder right | python-fcl right | pycinder wrong |",
             "|---|---|---|---|---|"]
    for r in rows:
        wrong = "; ".join(r["pycinder"]["wrong"]) or "-"
        lines.append(f"| {r['group']} | {r['cases']} | {r['pycinder']['right']} | "
                     f"{r['python-fcl']['right']} | {wrong} |")
    return lines + [""]

"""The building benchmark's hard clashes at fine depths, at the origin and in map coordinates.

The building of :mod:`benchmarks.building` (slabs up to 84 m across, exact truth for
every pair) is written as IFC, read back, and checked with ``min_depth`` of 2 mm and 1 mm, as
read and moved by a translation (500 km by default, as a model in map coordinates). Each run is
scored against the exact truth: every pair deeper than ``d`` found, no touching, grazing
(at most ``d / 2`` deep) or apart pair reported, and every reported depth within its stated
bound of the truth (the clash's ``depth_error`` plus the tessellation's error).

Run it with::

    python -m benchmarks.buildingscale --elements 3000 --out results.md
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pycinder.testing.buildings import generate, write_federated
from pycinder.testing.buildingscore import score

DEPTHS = (0.002, 0.001)
"""``min_depth`` of the runs (metres)."""
OFFSETS = ((0.0, 0.0, 0.0), (5e5, 5e5, 0.0))
"""Translations the model is checked at: as read, and 500 km out along x and y."""


def run(elements: int = 3000, depths: Sequence[float] = DEPTHS,
        offsets: Sequence[Sequence[float]] = OFFSETS) -> dict[str, Any]:
    """Generate the building, read it from IFC and check it at each depth and offset.

    Returns
    -------
    dict
        ``rows``: per depth and offset, :func:`~pycinder.testing.buildingscore.score`'s figures,
        ``depths_checked``, ``depths_outside``, ``depth_worst`` and ``clash_s``; ``adapter``.
    """
    import pycinder
    from pycinder.files import ifc

    building = generate(elements)
    with tempfile.TemporaryDirectory() as folder:
        paths = write_federated(building, folder)
        with tempfile.TemporaryDirectory() as cache:
            model = ifc.read_ifc([Path(p) for p in paths], cache=cache)
    meshes = [b.mesh for b in model.bodies]
    ids = [b.global_id for b in model.bodies]
    rows = []
    for d in depths:
        detector = pycinder.Detector(min_depth=d)
        for offset in offsets:
            move = np.eye(4)
            move[:3, 3] = offset
            t0 = time.perf_counter()
            result = detector.find_collisions(meshes, [move] * len(meshes))
            clash_s = time.perf_counter() - t0
            pairs = result.pairs.reshape(-1, 2).tolist()
            reported = {tuple(sorted((ids[i], ids[j]))) for i, j in pairs}
            row: dict[str, Any] = {"elements": len(meshes), "min_depth": d,
                                   "offset_km": float(np.linalg.norm(offset)) / 1e3,
                                   "clash_s": clash_s}
            row.update(score(building, reported, "min_depth", depth=d))  # type: ignore[arg-type]
            checked = outside = 0
            worst = 0.0
            for (i, j), depth, error in zip(pairs, result.depths, result.depth_errors):
                truth = building.truth.get(tuple(sorted((ids[i], ids[j]))))
                if truth is None:
                    continue
                checked += 1
                off = abs(float(depth) - truth.depth)
                worst = max(worst, off)
                outside += off > float(error) + truth.error
            row.update(depths_checked=checked, depths_outside=outside, depth_worst=worst)
            rows.append(row)
    from pycinder.gpu.device import get_gpu

    return {"rows": rows, "adapter": get_gpu().description}


def markdown(r: dict[str, Any]) -> list[str]:
    """The results as a Markdown table."""
    lines = [f"Adapter: {r['adapter']}.", "",
             ("| elements | min_depth (mm) | offset (km) | must | found | touching | grazes | "
              "false | reported | depths checked | depths outside bound | worst depth error "
              "(mm) | clash s |"),
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for row in r["rows"]:
        lines.append(
            f"| {row['elements']:,} | {row['min_depth'] * 1e3:g} | {row['offset_km']:g} | "
            f"{row['must']} | {row['found']} | {row['touching']} | {row['grazes']} | "
            f"{row['false']} | {row['reported']} | {row['depths_checked']} | "
            f"{row['depths_outside']} | {row['depth_worst'] * 1e3:.3g} | {row['clash_s']:.1f} |")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.buildingscale",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--elements", type=int, default=3000)
    parser.add_argument("--out", default=None, help="write the Markdown here too")
    args = parser.parse_args(argv)
    text = "\n".join(markdown(run(args.elements))) + "\n"
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

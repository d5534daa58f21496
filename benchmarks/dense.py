"""Dense meshes: hard clashes and clearance of two 20,000-face meshes that meet, against truth.

Each case is two meshes of about ``faces`` faces (icospheres of radius 1, 20,480 faces; a torus
of 20,000): two spheres overlapping deeply (as placed, and turned), grazing (pressed
:data:`GRAZE` together) and apart by :data:`NEAR_MISS`, and a torus through a sphere. Each is
queried with ``min_depth`` :data:`D` and ``clearance`` :data:`C`: the first query of a new
detector (its pipelines made and its shapes uploaded), then ``repeat`` queries of prepared
bodies (the median is reported), in wall and CPU seconds.

Truth: coal's EPA penetration depth of the two convex sphere meshes and python-fcl's distance of
every pair (0 where the surfaces meet). A hard clash is right when the pair is reported if
deeper than ``d``, not reported if at most ``d / 2`` deep, and its depth lies within its
``depth_error`` above the exact one (up to rounding); a clearance when the pair is reported if
closer than ``c``, and its distance lies within its ``distance_error`` of the exact one. The
torus is not convex: its hard clash is checked only to be reported (it crosses the sphere by
far more than ``d``).

``--before SRC`` runs the same queries (each once, a new detector each) with the pycinder of
another source tree, such as a checkout of an earlier commit, in a subprocess.

Run it with::

    python -m benchmarks.dense --out benchmarks/results/dense.md
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pycinder.util.environ import path_first

D = 0.01
"""``min_depth`` of the hard-clash queries (1% of the spheres' radius)."""
C = 0.1
"""``clearance`` of the clearance queries."""
GRAZE = 0.004
"""How far the grazing spheres are pressed together (at most ``D / 2``: never a hard clash)."""
NEAR_MISS = 0.005
"""How far apart the near-miss spheres are (within ``C``: a clearance, with its distance)."""


@dataclass
class Case:
    """Two meshes, each (vertices (V, 3), faces (F, 3)), and their world-from-body matrices
    (2, 4, 4); ``convex`` where coal's EPA gives the exact depth."""

    name: str
    meshes: list[tuple[np.ndarray, np.ndarray]]
    transforms: np.ndarray
    convex: bool = True


def _turn(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def cases(faces: int = 20000) -> list[Case]:
    """The benchmark's cases, with meshes of about ``faces`` faces each."""
    import trimesh

    level = max(0, round(np.log(faces / 20) / np.log(4)))
    ball = trimesh.creation.icosphere(subdivisions=level, radius=1.0)
    sections = max(8, round(np.sqrt(faces / 2)))
    ring = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=sections,
                                  minor_sections=sections)
    sphere = (np.asarray(ball.vertices), np.asarray(ball.faces))
    torus = (np.asarray(ring.vertices), np.asarray(ring.faces))
    direction = np.array([0.6, 0.64, 0.48])

    def placed(centre: Any, turned: bool = False) -> np.ndarray:
        t = np.stack([np.eye(4), np.eye(4)])
        if turned:
            t[0, :3, :3], t[1, :3, :3] = _turn(1), _turn(2)
        t[1, :3, 3] = centre
        return t

    return [
        Case("spheres overlapping", [sphere, sphere], placed((0.7, 0.3, 0.2))),
        Case("spheres overlapping, turned", [sphere, sphere], placed((0.7, 0.3, 0.2), True)),
        Case("spheres grazing", [sphere, sphere], placed((2 - GRAZE) * direction, True)),
        Case("spheres near miss", [sphere, sphere], placed((2 + NEAR_MISS) * direction, True)),
        Case("torus through sphere", [torus, sphere], placed((1.0, 0.2, 0.1)), convex=False),
    ]


def truth(case: Case) -> dict[str, float | None]:
    """The exact depth (coal's EPA, convex pairs only: else None) and distance (python-fcl)."""
    import trimesh

    from pycinder.testing import coal_depth, surface_distance

    meshes = [trimesh.Trimesh(v, f, process=False) for v, f in case.meshes]
    distance = max(surface_distance(meshes[0], meshes[1], list(case.transforms)), 0.0)
    depth = None
    if case.convex:
        depth = coal_depth(meshes[0], case.transforms[0], meshes[1], case.transforms[1])
    return {"depth": depth, "distance": distance}


def measure(case: Case, option: str, repeat: int) -> dict[str, Any]:
    """One query kind on one case: the first query of a new detector, then ``repeat`` of
    prepared bodies; the last one's answer."""
    import pycinder

    def timed(call: Any) -> tuple[float, float, Any]:
        t0, c0 = time.perf_counter(), time.process_time()
        result = call()
        return time.perf_counter() - t0, time.process_time() - c0, result

    value = D if option == "min_depth" else C
    detector = pycinder.Detector(**{option: value})
    meshes, transforms = case.meshes, list(case.transforms)
    first_s, first_cpu, _ = timed(lambda: detector.find_collisions(meshes, transforms))
    prepared = detector.prepare(meshes)
    runs = [timed(lambda: detector.find_collisions(prepared, transforms))
            for _ in range(repeat)]
    result = runs[-1][2]
    figure = result.depths if option == "min_depth" else result.distances
    error = result.depth_errors if option == "min_depth" else result.distance_errors
    reported = result.pairs.reshape(-1, 2).tolist() == [[0, 1]]
    return {"first_s": first_s, "first_cpu_s": first_cpu,
            "s": statistics.median(r[0] for r in runs),
            "cpu_s": statistics.median(r[1] for r in runs), "reported": reported,
            "figure": float(figure[0]) if reported else None,
            "error": float(error[0]) if reported else None}


def judge(row: dict[str, Any], option: str, exact: dict[str, float | None]) -> str:
    """Whether an answer keeps the query's contract against the truth: "yes", "no" or "yes
    (reported)" for a hard clash without an exact depth."""
    rounding = 2.0**-16 * 8  # ERROR_SCALE times a bound of the pairs' reach
    if option == "min_depth":
        depth = exact["depth"]
        if depth is None:
            return "yes (reported)" if row["reported"] else "no"
        if (depth > D and not row["reported"]) or (depth <= D / 2 and row["reported"]):
            return "no"
        if row["reported"] and not (row["figure"] - row["error"] - rounding <= depth
                                    <= row["figure"] + rounding):
            return "no"
        return "yes"
    distance = exact["distance"]
    assert distance is not None
    if distance < C and not row["reported"]:
        return "no"
    if row["reported"] and abs(row["figure"] - distance) > row["error"] + 1e-9:
        return "no"
    return "yes"


_BEFORE = """
import json, sys, time
import numpy as np
import pycinder
data = np.load(sys.argv[1])
out = []
for k in range(int(data["count"])):
    meshes = [(data[f"v{k}_{i}"], data[f"f{k}_{i}"]) for i in range(2)]
    transforms = list(data[f"t{k}"])
    for option, value in (("min_depth", float(data["d"])), ("clearance", float(data["c"]))):
        detector = pycinder.Detector(**{option: value}, timeout=float(data["timeout"]))
        t0, c0 = time.perf_counter(), time.process_time()
        result = detector.find_collisions(meshes, transforms)
        row = {"s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
               "reported": result.pairs.reshape(-1, 2).tolist() == [[0, 1]]}
        figure = result.depths if option == "min_depth" else result.distances
        error = result.depth_errors if option == "min_depth" else result.distance_errors
        row["figure"] = float(figure[0]) if row["reported"] else None
        row["error"] = float(error[0]) if row["reported"] else None
        out.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)
json.dump(out, open(sys.argv[2], "w"))
"""


def before(cases: list[Case], source: str, timeout: float) -> list[dict[str, Any]]:
    """The queries with the pycinder of source tree ``source`` (its ``src`` folder), once
    each, a new detector each (allowing the GPU ``timeout`` seconds a submission), in a
    subprocess: per case, min_depth then clearance."""
    with tempfile.TemporaryDirectory() as folder:
        arrays: dict[str, Any] = {"count": len(cases), "d": D, "c": C, "timeout": timeout}
        for k, case in enumerate(cases):
            for i, (v, f) in enumerate(case.meshes):
                arrays[f"v{k}_{i}"], arrays[f"f{k}_{i}"] = v, f
            arrays[f"t{k}"] = case.transforms
        data, out = Path(folder) / "cases.npz", Path(folder) / "out.json"
        np.savez(data, **arrays)
        env = path_first(Path(source) / "src")
        subprocess.run([sys.executable, "-c", _BEFORE, str(data), str(out)], env=env,
                       check=True, timeout=timeout)
        return json.loads(out.read_text())


def run(faces: int = 20000, repeat: int = 3, source: str | None = None,
        timeout: float = 3600.0, earlier: list[dict[str, Any]] | None = None
        ) -> dict[str, Any]:
    """Every case and query kind, with its truth and, with ``source``, the earlier tree's (or
    ``earlier``: its rows as an earlier run measured them, per case min_depth then clearance)."""
    from pycinder.gpu.device import get_gpu

    rows = []
    chosen = cases(faces)
    if source:
        earlier = before(chosen, source, timeout)
    for k, case in enumerate(chosen):
        exact = truth(case)
        for q, option in enumerate(("min_depth", "clearance")):
            row = {"case": case.name, "faces": [len(f) for _, f in case.meshes],
                   "option": option, **measure(case, option, repeat), "exact": exact}
            row["right"] = judge(row, option, exact)
            if earlier is not None:
                row["before"] = earlier[2 * k + q]
                row["before"]["right"] = judge(row["before"], option, exact)
            rows.append(row)
    return {"rows": rows, "adapter": get_gpu().description, "load": os.getloadavg(),
            "cpus": os.cpu_count(), "d": D, "c": C}


def markdown(r: dict[str, Any]) -> list[str]:
    """The results as a Markdown table."""
    has_before = any("before" in row for row in r["rows"])
    head = (f"Adapter: {r['adapter']}; {r['cpus']} CPU cores; load average at the end "
            f"{r['load'][0]:.1f}. min_depth {r['d']:g}, clearance {r['c']:g} (spheres of "
            "radius 1).")
    columns = ("| case | faces | query | first query s (CPU s) | prepared query s (CPU s) | "
               "reported | figure | exact | right |")
    rule = "|---|---:|---|---:|---:|---|---:|---:|---|"
    if has_before:
        columns += " before: s (CPU s) | before: right |"
        rule += "---:|---|"
    lines = [head, "", columns, rule]
    for row in r["rows"]:
        exact = row["exact"]["depth" if row["option"] == "min_depth" else "distance"]
        figure = "" if row["figure"] is None else f"{row['figure']:.6g} ± {row['error']:.2g}"
        line = (f"| {row['case']} | {' + '.join(f'{n:,}' for n in row['faces'])} | "
                f"{row['option']} | {row['first_s']:.2f} ({row['first_cpu_s']:.2f}) | "
                f"{row['s']:.2f} ({row['cpu_s']:.2f}) | {'yes' if row['reported'] else 'no'} | "
                f"{figure} | {'—' if exact is None else f'{exact:.6g}'} | {row['right']} |")
        if has_before:
            b = row["before"]
            line += f" {b['s']:.1f} ({b['cpu_s']:.1f}) | {b['right']} |"
        lines.append(line)
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.dense",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--faces", type=int, default=20000, help="faces per mesh (about)")
    parser.add_argument("--repeat", type=int, default=3, help="prepared queries per case")
    parser.add_argument("--before", default=None, metavar="SRC",
                        help="also run the queries with the pycinder of this source tree")
    parser.add_argument("--timeout", type=float, default=3600.0,
                        help="seconds the --before run may take")
    parser.add_argument("--out", default=None, help="write the Markdown here too")
    parser.add_argument("--json", default=None, help="write the results as JSON here")
    parser.add_argument("--before-json", default=None, metavar="JSON",
                        help="take the earlier tree's rows from this earlier --json output "
                             "instead of running them again")
    args = parser.parse_args(argv)
    earlier = None
    if args.before_json:
        earlier = [row["before"] for row in json.loads(Path(args.before_json).read_text())["rows"]]
    results = run(args.faces, args.repeat, args.before, args.timeout, earlier)
    text = "\n".join(markdown(results)) + "\n"
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

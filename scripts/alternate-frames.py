#!/usr/bin/env python3
"""Frame times and host milliseconds before submission of this checkout against another one,
alternated in one run (a refactor must not be slower than the code before it).

    python scripts/alternate-frames.py OTHER_CHECKOUT [--rounds 3]

OTHER_CHECKOUT is another working tree of pycinder (for example ``git worktree add ../before
HEAD~10``); each measurement runs in a fresh process, the two checkouts taking turns, on the
scenes Stairs (250 spheres), 1000 bodies and 16 deforming bunnies (fresh arrays every frame).
It prints a Markdown table of the medians.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent
FRAMES = {"stairs": 12, "many": 6, "deforming": 12}

CHILD = r"""
import json, statistics, sys, time
import numpy as np
import pycinder
from pycinder.testing.scenes import DeformingBunnies, ManyBodies, Stairs
name, frames = sys.argv[1], int(sys.argv[2])
scene = {"stairs": lambda: Stairs(250, frames), "many": lambda: ManyBodies(1000, frames),
         "deforming": lambda: DeformingBunnies(16, frames)}[name]().cached()
det = pycinder.Detector(records="none")
walls, before = [], []
for k in range(frames):
    bodies, transforms = scene.bodies(k)
    if scene.deforming:
        bodies = [(np.array(v), f) for v, f in bodies]
    t0 = time.perf_counter()
    result = det.find_collisions(bodies, transforms)
    walls.append((time.perf_counter() - t0) * 1e3)
    before.append(result.stats.submitted_ms)
print(json.dumps({"frame_ms": statistics.median(walls[2:]),
                  "before_submit_ms": statistics.median(before[2:]), "pairs": len(result.pairs)}))
"""


def measure(src: Path, scene: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src / "src"), XDG_RUNTIME_DIR=os.environ.get(
        "XDG_RUNTIME_DIR", "/tmp"))
    out = subprocess.run([sys.executable, "-W", "ignore", "-c", CHILD, scene,
                          str(FRAMES[scene])], env=env, capture_output=True, text=True,
                         timeout=600, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("other", type=Path)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    runs: dict[tuple[str, str], list[dict]] = {}
    for _ in range(args.rounds):
        for scene in FRAMES:
            for label, src in (("other", args.other.resolve()), ("this", HERE)):
                runs.setdefault((scene, label), []).append(measure(src, scene))
    print("| scene | checkout | frame ms (median of rounds) | host ms before submission | pairs |")
    print("|---|---|---|---|---|")
    for (scene, label), rows in runs.items():
        frame = statistics.median(r["frame_ms"] for r in rows)
        before = statistics.median(r["before_submit_ms"] for r in rows)
        print(f"| {scene} | {label} | {frame:.1f} | {before:.2f} | {rows[0]['pairs']} |")


if __name__ == "__main__":
    main()

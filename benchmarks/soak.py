"""The memory soak: the loops users write, run for many frames, with resident memory sampled.

``fresh``: three small bodies are passed as fresh ``(vertices, faces)`` arrays every frame, one of
them moving, to a detector kept across frames. ``deforming``: a ball whose vertices change every
frame (a new shape each frame, its GPU slot overwritten), touching a box. Prints one line of JSON.
Run by ``pycinder bench soak`` in a process of its own:
``python -m benchmarks.soak --frames 100000 --mode deforming``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from typing import Any

import numpy as np


def rss_bytes() -> int:
    """Resident set size of this process (Linux), 0 where it cannot be read."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError):
        return 0


MODES = ("fresh", "deforming")


def soak(frames: int = 100_000, every: int = 1000, mode: str = "fresh") -> dict[str, Any]:
    import trimesh

    from pycinder.detector import Detector

    det = Detector()
    if mode == "fresh":
        shapes = [trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(subdivisions=2),
                  trimesh.creation.cylinder(radius=0.4, height=1.0)]
        transforms = np.tile(np.eye(4), (3, 1, 1))
        transforms[1, 0, 3], transforms[2, 1, 3] = 1.2, 1.2
    elif mode == "deforming":
        ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
        ball_vertices, ball_faces = np.array(ball.vertices), np.array(ball.faces)
        box = trimesh.creation.box((0.4, 0.4, 0.4))
        transforms = np.tile(np.eye(4), (2, 1, 1))
        transforms[1, 0, 3] = 0.6
    else:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    samples, hits = [], 0
    start = time.perf_counter()
    for k in range(frames):
        if mode == "fresh":
            transforms[1, 0, 3] = 1.2 + 0.3 * np.sin(k * 0.01)
            bodies = [(np.array(s.vertices), np.array(s.faces)) for s in shapes]
        else:
            bodies = [(ball_vertices * (1 + 0.05 * np.sin(0.01 * k)), ball_faces), box]
        hits += len(det.find_collisions(bodies, transforms).pairs)
        if k % every == 0 or k == frames - 1:
            samples.append((k, rss_bytes()))
    rss = np.array([r for _, r in samples], dtype=np.float64)
    settled = rss[max(1, len(rss) // 10):] if len(rss) > 1 else rss  # after start-up
    return {"mode": mode, "frames": frames, "samples": samples, "pairs_found": hits,
            "seconds": time.perf_counter() - start,
            "rss_start_mib": float(settled[0] / 2**20),
            "rss_end_mib": float(rss[-1] / 2**20),
            "rss_growth_mib": float((settled.max() - settled[0]) / 2**20),
            "topology_builds": det.shapes.topologies.builds,
            "cache_bytes": det.shapes.nbytes + det.shapes.topologies.nbytes}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=100_000)
    parser.add_argument("--every", type=int, default=1000)
    parser.add_argument("--mode", choices=MODES, default="fresh")
    args = parser.parse_args()
    print(json.dumps(soak(args.frames, args.every, args.mode)))


if __name__ == "__main__":
    main()

"""The broad phase on the GPU against the NumPy reference: ``pycinder bench broadphase``.

Drifting spheres (:func:`pycinder.testing.scenes.drifting_spheres`) as in the ``many`` scene
(0.1 across, about 1,160 per unit volume, so that their volumes add up to 0.6 of the box's;
random orientations; drifting a little every frame), at 1,000, 10,000 and 100,000 bodies. Per
frame, interleaved (the first of the two alternates): the NumPy reference
(:func:`pycinder.focused.broad.reference_pairs`: ``world_boxes``, ``sweep_and_prune``) and
:class:`pycinder.focused.broad.GpuBroadPhase` (upload, one submission, one map, the sort of the
pairs on the host), both from the same NumPy arrays to the sorted (K, 2) pairs. Every frame's
answers are compared: every reference pair must be found; extra pairs (boxes within the padding)
are counted.
"""

from __future__ import annotations

import re
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from pycinder.testing.scenes import drifting_spheres

COUNTS = (1_000, 10_000, 100_000)
"""Bodies of the benchmark's scenes (:func:`pycinder.testing.scenes.drifting_spheres`)."""


def run_broadphase(counts: Sequence[int] = COUNTS, frames: int = 5,
                   progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Median milliseconds per frame of both, with the answers compared (module doc)."""
    from pycinder.scene.bodies import world_boxes
    from pycinder.gpu.device import get_gpu
    from pycinder.focused.broad import GpuBroadPhase, reference_pairs

    gpu = GpuBroadPhase()
    rows = []
    for count in counts:
        if progress:
            progress(f"broadphase: {count} bodies")
        lo, hi, r, poses = drifting_spheres(count, frames)
        gpu.pairs(lo, hi, r, poses[0])  # warm-up: pipelines, buffers grown to this size
        times: dict[str, list[float]] = {"numpy": [], "gpu": []}
        pairs, extra, missed, trips = [], [], [], []
        for k, t in enumerate(poses):
            order = ("numpy", "gpu") if k % 2 == 0 else ("gpu", "numpy")
            found = {}
            for name in order:
                t0 = time.perf_counter()
                found[name] = reference_pairs(lo, hi, r, t) if name == "numpy" \
                    else gpu.pairs(lo, hi, r, t)
                times[name].append((time.perf_counter() - t0) * 1e3)
            st = gpu.stats
            trips.append((st.submissions, st.maps, st.reruns))
            ref = {tuple(p) for p in found["numpy"].tolist()}
            got = {tuple(p) for p in found["gpu"].tolist()}
            pairs.append(len(ref))
            missed.append(len(ref - got))
            extra.append(len(got - ref))
        med = {n: statistics.median(v) for n, v in times.items()}
        # What the reference's sweep faces: boxes starting within each box's extent on its axis.
        wlo, whi = world_boxes(lo, hi, r, poses[0])
        axis = int(np.argmax((0.5 * (wlo + whi)).var(axis=0)))
        starts = np.sort(wlo[:, axis])
        beside = np.searchsorted(starts, whi[:, axis], side="right") \
            - np.searchsorted(starts, wlo[:, axis], side="left") - 1
        rows.append({"bodies": count, "frames": frames, "median_ms": med, "times_ms": times,
                     "ratio": med["numpy"] / med["gpu"], "pairs": int(statistics.median(pairs)),
                     "axis_neighbours": float(np.median(beside)),
                     "missed_pairs": int(sum(missed)), "extra_pairs": int(sum(extra)),
                     "submissions_maps_reruns": [list(x) for x in sorted(set(trips))]})
    about = re.sub(r":\w+:`", "`", __doc__.split("\n\n")[1]).replace("``", "`")
    return {"description": about.replace("\n", " ").strip(),
            "adapter": get_gpu().description, "rows": rows}


def markdown(r: dict[str, Any]) -> list[str]:
    """The report's section for ``pycinder bench broadphase``."""
    lines = ["## Broad phase: GPU sort and sweep against the NumPy reference", "",
             r["description"], "",
             f"Adapter: {r['adapter']}. Median milliseconds per frame; NumPy's time over the "
             "GPU stage's (above 1: the GPU stage is faster). The GPU stage's time includes the "
             "upload, its one submission and map, and sorting the pairs on the host.", "",
             "| bodies | frames | pairs | boxes beside each along the axis | NumPy ms | GPU ms | "
             "NumPy / GPU | missed pairs | extra pairs (within the padding) | "
             "(submissions, maps, reruns) per frame |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for row in r["rows"]:
        med = row["median_ms"]
        trips = "; ".join(str(tuple(x)) for x in row["submissions_maps_reruns"])
        lines.append(f"| {row['bodies']} | {row['frames']} | {row['pairs']} | "
                     f"{row['axis_neighbours']:.0f} | {med['numpy']:.1f} | {med['gpu']:.1f} | "
                     f"{row['ratio']:.2f} | "
                     f"{row['missed_pairs']} | {row['extra_pairs']} | {trips} |")
    lines += ["", "The two differ in algorithm as well as in device: the NumPy reference tests "
              "each box against every box that starts within its extent along the sweep axis "
              "(the median count is in the table), the GPU stage only those in its own and the "
              "neighbouring columns of a grid across the axis (see "
              "`pycinder.focused.broad`). Where the first count is large, most of the ratio "
              "is that difference of algorithm."]
    if "CPU" in r["adapter"]:
        lines += ["", "This adapter implements the GPU API in software: the GPU stage's passes run "
                  "on the same CPU cores as NumPy, so its times here say what the stage costs "
                  "without a GPU, not what a GPU makes of it."]
    return lines + [""]

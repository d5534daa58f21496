"""The cost floor: what the first query of a process costs, and the least a query costs, with
python-fcl's in the same process.

In a fresh process (so that nothing is cached): the time to import pycinder, to make a
:class:`~pycinder.Detector` (adapter, device, pipelines), its first query, and then the median of
``calls`` queries of two small bodies (a unit box and a 320-triangle sphere), apart (the broad
phase alone) and touching (one pair through the GPU passes and back), with the default options.
python-fcl does the same two pairs: building both ``BVHModel``s and the first ``collide``, then
the median ``collide``. Prints one line of JSON. Run by ``pycinder bench floor`` in a fresh
interpreter per backend (:data:`COMMAND`, which also times ``import pycinder``); by hand:
``WGPU_BACKEND_TYPE=OpenGL python -m benchmarks.floor --calls 100``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from typing import Any

import numpy as np


def _median_ms(fn: Any, calls: int) -> float:
    times = []
    for _ in range(calls):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times)


COMMAND = ("import sys, time; t0 = time.perf_counter(); import pycinder; "
           "ms = (time.perf_counter() - t0) * 1e3; "
           "from benchmarks.floor import main; main(sys.argv[1:], ms)")
"""A fresh interpreter's command that times ``import pycinder`` and then runs :func:`main`."""


def floor(calls: int = 100, import_ms: float | None = None) -> dict[str, Any]:
    """The measurements of the module's doc; ``import_ms``: what importing pycinder took."""
    import trimesh

    import pycinder

    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    poses = {"apart": np.stack([np.eye(4), trimesh.transformations.translation_matrix((3, 0, 0))]),
             "touching": np.stack([np.eye(4),
                                   trimesh.transformations.translation_matrix((0.6, 0, 0))])}
    t0 = time.perf_counter()
    det = pycinder.Detector()
    detector_ms = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    first = det.find_collisions([box, ball], poses["touching"])
    first_ms = (time.perf_counter() - t0) * 1e3
    assert first.pairs.tolist() == [[0, 1]]
    out: dict[str, Any] = {
        "adapter": first.stats.adapter, "calls": calls, "import_ms": import_ms,
        "detector_ms": detector_ms, "first_call_ms": first_ms,
        "pycinder_ms": {name: _median_ms(lambda t=t: det.find_collisions([box, ball], t), calls)
                        for name, t in poses.items()},
    }
    try:
        import fcl
    except ImportError:
        out["python-fcl"] = None
        return out
    t0 = time.perf_counter()
    objects = []
    for mesh in (box, ball):
        model = fcl.BVHModel()
        model.beginModel(len(mesh.vertices), len(mesh.faces))
        model.addSubModel(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int32))
        model.endModel()
        objects.append(fcl.CollisionObject(model, fcl.Transform()))
    request = fcl.CollisionRequest()

    def collide(t: np.ndarray) -> bool:
        objects[1].setTransform(fcl.Transform(t[1, :3, :3], t[1, :3, 3]))
        return bool(fcl.collide(objects[0], objects[1], request, fcl.CollisionResult()))

    assert collide(poses["touching"])
    fcl_first = (time.perf_counter() - t0) * 1e3
    out["python-fcl"] = {"first_call_ms": fcl_first,
                         "ms": {name: _median_ms(lambda t=t: collide(t), calls)
                                for name, t in poses.items()}}
    return out


def main(argv: list[str] | None = None, import_ms: float | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--calls", type=int, default=100)
    args = parser.parse_args(argv)
    print(json.dumps(floor(args.calls, import_ms)))


if __name__ == "__main__":
    main()

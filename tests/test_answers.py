"""Answers stored before a refactor, compared bit for bit: pairs, records and contacts of the
benchmark scenes and the test scenes, for both strategies and every entry point.

A refactor of the passes or of the host around them must not change one bit of what a query
answers on the device that stored the answers. Another device (another driver, a real GPU) may
round differently, so the comparison runs only where the adapter is the one that stored them
and is skipped, saying so, elsewhere.

Store the answers again only when a change is meant to change them, and say why in its commit::

    python tests/test_answers.py --write                             # Vulkan (lavapipe)
    WGPU_BACKEND_TYPE=OpenGL python tests/test_answers.py --write    # OpenGL (llvmpipe)
"""

from __future__ import annotations

import hashlib
import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.benchmarks.scenes import (DeformingBunnies, ManyBodies, NarrowPhase, SpreadPairs,
                                        Stairs)
from pycinder.testing import holed_scene, nested_scene, open_body_cases, random_scene

DATA = Path(__file__).parent / "data" / "answers"

Answer = dict[str, np.ndarray]


def _digest(*arrays: np.ndarray) -> np.ndarray:
    """A SHA-256 of arrays' bytes, dtypes and shapes (records run to millions of rows: their
    digest is stored, not their bytes)."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.descr}{a.shape}".encode())
        h.update(a.tobytes())
    return np.array(h.hexdigest())


def _arrays(result: pycinder.CollisionResult, exact: bool = False,
            contacts: bool = True) -> Answer:
    """The parts of a result that must not change: its pairs, and with ``exact`` (a query that
    kept every record: which records ``"found"`` keeps first depends on the order threads
    finish) its records (every field, every bit) and its contacts' fields."""
    out = {"pairs": np.asarray(result.pairs, dtype=np.int64)}
    if exact:
        out["records"] = _digest(result.records)
        out["record count"] = np.array(len(result.records))
    if exact and contacts and len(result.pairs):
        c = result.contacts()
        out["contacts"] = _digest(*(np.asarray(getattr(c, name)) for name in
                                    ("pair", "point", "normal", "depth", "face", "deepest",
                                     "samples")))
    return out


def _frames(scene, frames: int, **options) -> Iterator[tuple[str, Answer]]:
    det = pycinder.Detector(**options)
    for k in range(frames):
        bodies, transforms = scene.bodies(k)
        yield f"{scene.name}/{k}", _arrays(det.find_collisions(bodies, transforms),
                                           options.get("records") == "all")


def _benchmark_scenes() -> Iterator[tuple[str, Answer]]:
    yield from _frames(Stairs(250, frames=3), 3)
    yield from _frames(Stairs(60, frames=2), 2, records="all")
    yield from _frames(DeformingBunnies(16, frames=3), 3)
    yield from _frames(DeformingBunnies(4, frames=2), 2, records="all")
    yield from _frames(ManyBodies(1000, frames=1), 1)
    yield from _frames(NarrowPhase(4), 4)
    yield from _frames(SpreadPairs(1000.0, frames=1), 1)


def _test_scenes() -> Iterator[tuple[str, Answer]]:
    det = pycinder.Detector(tolerance=0.01)
    for seed in range(3):
        meshes, transforms = random_scene(40, seed)
        yield f"random-{seed}", _arrays(det.find_collisions(meshes, transforms))
        yield f"random-{seed}/all", _arrays(det.find_collisions(meshes, transforms,
                                                                 records="all"), True)
        yield f"random-{seed}/none", _arrays(det.find_collisions(meshes, transforms,
                                                                  records="none"))
    meshes, transforms = nested_scene()
    yield "nested", _arrays(det.find_collisions(meshes, transforms))
    meshes, transforms = holed_scene(12, 0)
    yield "holed", _arrays(det.find_collisions(meshes, transforms, records="all"), True)
    t = 0.01
    for name, meshes, transforms, _ in open_body_cases(t):
        yield f"open/{name}", _arrays(pycinder.find_collisions(meshes, transforms, tolerance=t,
                                                               records="all"), True)
    meshes, transforms = random_scene(24, 7)
    groups = np.arange(len(meshes)) % 3
    yield "groups", _arrays(det.find_collisions(meshes, transforms, groups=groups))
    yield "in_collision", {"found": np.array([det.in_collision(meshes, transforms)])}


def _entry_points() -> Iterator[tuple[str, Answer]]:
    det = pycinder.Detector(tolerance=0.01)
    scenes = [random_scene(8, seed) for seed in range(6)]
    for k, result in enumerate(det.find_collisions_batch(scenes, records="all")):
        yield f"batch/{k}", _arrays(result, True)
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    manager = pycinder.CollisionManager(tolerance=0.01)
    for k, x in enumerate((0.0, 0.9, 1.5, 2.0)):
        manager.add_object(f"box{k}", box, trimesh.transformations.translation_matrix((x, 0, 0)))
    hit, names, data = manager.in_collision_internal(return_names=True, return_data=True)
    yield "manager", {"hit": np.array([hit]), "names": np.array(sorted(map(sorted, names))),
                      "depths": np.array(sorted(d.depth for d in data))}
    scene = pycinder.Detector(strategy="scene", resolution=512)
    bodies, transforms = Stairs(40, frames=1).bodies(0)
    yield "scene-strategy", _arrays(scene.find_collisions(bodies, transforms), True, False)


SOURCES: dict[str, Callable[[], Iterator[tuple[str, Answer]]]] = {
    "benchmark": _benchmark_scenes, "tests": _test_scenes, "entry": _entry_points}


def _info() -> dict:
    return dict(pycinder.Detector().gpu.adapter.info)


def _backend_file() -> Path:
    return DATA / f"{str(_info().get('backend_type', 'unknown')).lower()}.npz"


def _stored(path: Path) -> tuple[dict[str, np.ndarray], str]:
    with np.load(path, allow_pickle=False) as d:
        return {k: d[k] for k in d.files if k != "__adapter__"}, str(d["__adapter__"])


def _adapter() -> str:
    info = _info()
    return f"{info.get('device', '')} | {info.get('backend_type', '')} | {info.get('driver', '')}"


@pytest.mark.parametrize("source", sorted(SOURCES))
def test_answers_are_unchanged(source):
    path = _backend_file()
    if not path.exists():
        pytest.skip(f"no answers stored for this backend ({path.name})")
    stored, adapter = _stored(path)
    if adapter != _adapter():
        pytest.skip(f"answers were stored on {adapter!r}, this is {_adapter()!r}")
    seen = set()
    for name, answer in SOURCES[source]():
        for field, value in answer.items():
            key = f"{source}:{name}:{field}"
            seen.add(key)
            assert key in stored, f"{key}: no stored answer"
            want = stored[key]
            assert value.dtype == want.dtype and value.shape == want.shape, \
                f"{key}: {value.dtype}{value.shape} against stored {want.dtype}{want.shape}"
            assert np.array_equal(value, want, equal_nan=value.dtype.kind == "f"), \
                f"{key} differs from the stored answer"
    missing = {k for k in stored if k.startswith(f"{source}:")} - seen
    assert not missing, f"stored answers no longer produced: {sorted(missing)[:5]}"


def write() -> Path:
    out: dict[str, np.ndarray] = {"__adapter__": np.array(_adapter())}
    for source, make in SOURCES.items():
        for name, answer in make():
            for field, value in answer.items():
                out[f"{source}:{name}:{field}"] = value
    path = _backend_file()
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **out)
    return path


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit(__doc__)
    print(f"wrote {write()}")

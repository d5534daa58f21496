"""Answers stored before a refactor, compared with what the code answers now: pairs, records and
contacts of the benchmark scenes and the test scenes, for both strategies and every entry point.

Two comparisons, chosen by the machine that runs them:

* **bit for bit**, where the machine is the one that stored the answers: the same adapter,
  driver and backend, and the same CPU (vendor and the instruction sets that decide how a
  software driver such as lavapipe rounds: see :func:`cpu_key`). Every field of every record
  and contact must be the same bits (their SHA-256 digests are stored). A refactor of the passes
  or of the host around them must pass this one.
* **within bounds**, anywhere else. Another CPU or driver rounds single-precision arithmetic
  differently (a fresh clone on an AMD EPYC, with the very same adapter string, failed the bit
  for bit comparison), so a record whose pixel-centre ray meets a surface within rounding of a
  region's edge may be kept on one machine and not on another. What must hold everywhere:

  - **exactly**: the pairs of every query, and every integer answer that is not a count of
    samples (``in_collision``, the manager's names and verdict, the pairs that have contacts);
  - **record counts** of each ordered pair (penetrating, penetrated) within
    ``B(n) = 8 sqrt(n) + 8`` of the stored ``n``: a record flips only at a region's boundary,
    and a compact region of ``n`` pixels has about ``4 sqrt(n)`` boundary pixels; twice that
    allows a pair's samples to lie in a few regions;
  - **record centroids** of each ordered pair within ``2 t + (B(n) / n) D``: ``t`` is the pair's
    tolerance (the focused strategy's pixels are ``t`` wide, request.py's contract), so two
    samplings of one surface point differ by less than ``2 t``, and ``B(n)`` flipped records out
    of ``n`` move the mean by at most ``B(n) / n`` of the records' extent ``D`` (the diagonal of
    their bounding box);
  - **contacts** per pair: their samples within ``B``; the deepest contact's depth within
    ``2 t`` (a depth is "within about a tolerance" of the overlap's width, contacts.py); the
    samples-weighted mean contact normal within ``asin(min(1, 2 B / N)) + 2`` degrees of the
    stored one (``N`` samples, ``B(N)`` of them flipped; 2 degrees for the rounding of normals
    measured in single precision), and the samples-weighted mean contact point within the
    centroid's bound. How many contact regions a pair has is not compared there: one flipped
    record can join two regions (their grid cells are four tolerances wide);
  - **manager depths** within ``2 t``.

  The whole-scene strategy's pixel is the scene's extent over its resolution (no promise in
  world units): its bounds use that pixel as ``t``.

Each test says which comparison it made: in its assertion messages, as the ``comparison``
property of its report (``record_property``), and in the line the suite's terminal summary
prints per test (``tests/conftest.py``).

Store the answers again only when a change is meant to change them, and say why in its commit::

    python tests/test_answers.py --write                             # Vulkan (lavapipe)
    WGPU_BACKEND_TYPE=OpenGL python tests/test_answers.py --write    # OpenGL (llvmpipe)
"""

from __future__ import annotations

import functools
import hashlib
import math
import os
import platform
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
from pycinder.testing import (holed_scene, nested_scene, open_body_cases, pair_tolerances,
                              random_scene)

DATA = Path(__file__).parent / "data" / "answers"
KEY = "__key__"
"""The stored answers' machine key (:func:`machine_key` of the machine that wrote them)."""

Answer = dict[str, np.ndarray]

CPU_FLAGS = ("sse4_1", "sse4_2", "avx", "f16c", "fma", "avx2", "avx512f", "avx512dq",
             "avx512bw", "avx512vl", "avx512_fp16")
"""The instruction sets that decide how a CPU driver's JIT (llvmpipe's LLVM) compiles shaders'
float arithmetic: vector width, fused multiply-add, half floats."""

DIGESTS = ("records", "contacts")
"""Fields stored as SHA-256 digests: compared bit for bit, only on the machine that stored them."""
EXACT = ("pairs", "found", "hit", "names", "contact pairs")
"""Fields compared exactly on every machine."""
ANGLE_FLOOR_DEG = 2.0
"""Degrees a samples-weighted mean normal may turn from rounding alone (see the docstring)."""


def count_bound(n: np.ndarray) -> np.ndarray:
    """``B(n) = 8 sqrt(n) + 8``: how many of ``n`` records may flip between machines."""
    return 8.0 * np.sqrt(np.asarray(n, np.float64)) + 8.0


def cpu_key() -> str:
    """The CPU as far as it decides float bits: vendor, family and model, and which of
    :data:`CPU_FLAGS` it has (from ``/proc/cpuinfo`` where there is one)."""
    fields: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                name, _, value = line.partition(":")
                name = name.strip()
                if name in ("vendor_id", "cpu family", "model", "flags", "CPU implementer",
                            "Features"):
                    fields.setdefault(name, value.strip())
                if not line.strip() and fields:
                    break  # the first processor is enough
    except OSError:
        pass
    flags = set((fields.get("flags") or fields.get("Features") or "").split())
    vendor = fields.get("vendor_id") or fields.get("CPU implementer") or platform.processor()
    return (f"{platform.machine()} {vendor} family {fields.get('cpu family', '?')} "
            f"model {fields.get('model', '?')} [{' '.join(f for f in CPU_FLAGS if f in flags)}]")


def _info() -> dict:
    return dict(pycinder.Detector().gpu.adapter.info)


def machine_key() -> str:
    """What decides the bits of an answer: adapter, backend, driver and CPU (:func:`cpu_key`)."""
    info = _info()
    return " | ".join(str(info.get(k, "")) for k in ("device", "backend_type", "driver",
                                                      "description")) + f" | {cpu_key()}"


def _digest(*arrays: np.ndarray) -> np.ndarray:
    """A SHA-256 of arrays' bytes, dtypes and shapes (records run to millions of rows: their
    digest is stored, not their bytes)."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.descr}{a.shape}".encode())
        h.update(a.tobytes())
    return np.array(h.hexdigest())


def _record_summary(records: np.ndarray, tolerance: Callable[[np.ndarray], np.ndarray]
                    ) -> Answer:
    """Per ordered pair (penetrating, penetrated) of ``records``: count, centroid, extent (the
    diagonal of the points' bounding box) and tolerance (``tolerance`` of the (P, 2) pairs)."""
    keys = np.stack([records["penetrating"], records["penetrated"]], axis=1).astype(np.int64)
    pairs, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    points = np.asarray(records["point"], np.float64)
    centroid = np.stack([np.bincount(inverse, points[:, k], len(pairs)) for k in range(3)],
                        axis=1) / np.maximum(counts, 1)[:, None]
    lo = np.full((len(pairs), 3), np.inf)
    hi = np.full((len(pairs), 3), -np.inf)
    np.minimum.at(lo, inverse, points)
    np.maximum.at(hi, inverse, points)
    extent = np.linalg.norm(hi - lo, axis=1) if len(pairs) else np.zeros(0)
    return {"record pairs": pairs, "record counts": counts.astype(np.int64),
            "record centroids": centroid, "record extents": extent,
            "record tolerances": np.asarray(tolerance(pairs), np.float64).reshape(-1)}


def _contact_summary(c: pycinder.Contacts) -> Answer:
    """Per pair of ``c``: samples, deepest depth, samples-weighted mean normal and point."""
    pairs, inverse = np.unique(np.asarray(c.pair, np.int64), axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    w = np.asarray(c.samples, np.float64)
    samples = np.bincount(inverse, w, len(pairs))
    depth = np.full(len(pairs), -np.inf)
    np.maximum.at(depth, inverse, np.asarray(c.depth, np.float64))

    def weighted(v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, np.float64)
        return np.stack([np.bincount(inverse, w * v[:, k], len(pairs)) for k in range(3)],
                        axis=1)

    normal = weighted(c.normal)
    normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
    point = weighted(c.point) / np.maximum(samples, 1)[:, None]
    return {"contact pairs": pairs, "contact samples": samples.astype(np.int64),
            "contact depths": depth, "contact normals": normal, "contact points": point}


def _arrays(result: pycinder.CollisionResult, exact: bool = False, contacts: bool = True,
            tolerance: Callable[[np.ndarray], np.ndarray] | None = None) -> Answer:
    """The parts of a result that must not change: its pairs, and with ``exact`` (a query that
    kept every record: which records ``"found"`` keeps first depends on the order threads
    finish) its records and contacts: their digests (every field, every bit) and their
    summaries per pair (see the module's docstring). ``tolerance`` gives the tolerance of
    (P, 2) body pairs."""
    out = {"pairs": np.asarray(result.pairs, dtype=np.int64)}
    if exact:
        out["records"] = _digest(result.records)
        out.update(_record_summary(result.records, tolerance))
    if exact and contacts and len(result.pairs):
        c = result.contacts()
        out["contacts"] = _digest(*(np.asarray(getattr(c, name)) for name in
                                    ("pair", "point", "normal", "depth", "face", "deepest",
                                     "samples")))
        out.update(_contact_summary(c))
    return out


def _tolerances(meshes, transforms, tolerance: float | None) -> Callable[[np.ndarray], np.ndarray]:
    return lambda pairs: pair_tolerances(meshes, transforms, np.asarray(pairs, np.int64),
                                         tolerance)


def _pixel(meshes, transforms, resolution: int) -> Callable[[np.ndarray], np.ndarray]:
    """The whole-scene strategy's pixel: the scene's extent (bounding-box diagonal of every
    vertex in the world) over the resolution, for every pair."""
    world = [trimesh.transform_points(np.asarray(m[0] if isinstance(m, tuple) else m.vertices,
                                                 np.float64), t)
             for m, t in zip(meshes, transforms, strict=True)]
    points = np.concatenate(world)
    pixel = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0))) / resolution
    return lambda pairs: np.full(len(pairs), pixel)


def _frames(scene, frames: int, **options) -> Iterator[tuple[str, Answer]]:
    det = pycinder.Detector(**options)
    for k in range(frames):
        bodies, transforms = scene.bodies(k)
        exact = options.get("records") == "all"
        yield f"{scene.name}/{k}", _arrays(det.find_collisions(bodies, transforms), exact,
                                           tolerance=_tolerances(bodies, transforms, None)
                                           if exact else None)


def _benchmark_scenes() -> Iterator[tuple[str, Answer]]:
    yield from _frames(Stairs(250, frames=3), 3)
    yield from _frames(Stairs(60, frames=2), 2, records="all")
    yield from _frames(DeformingBunnies(16, frames=3), 3)
    yield from _frames(DeformingBunnies(4, frames=2), 2, records="all")
    yield from _frames(ManyBodies(1000, frames=1), 1)
    yield from _frames(NarrowPhase(4), 4)
    yield from _frames(SpreadPairs(1000.0, frames=1), 1)


def _test_scenes() -> Iterator[tuple[str, Answer]]:
    t = 0.01
    det = pycinder.Detector(tolerance=t)
    for seed in range(3):
        meshes, transforms = random_scene(40, seed)
        yield f"random-{seed}", _arrays(det.find_collisions(meshes, transforms))
        yield f"random-{seed}/all", _arrays(det.find_collisions(meshes, transforms,
                                                                 records="all"), True,
                                            tolerance=_tolerances(meshes, transforms, t))
        yield f"random-{seed}/none", _arrays(det.find_collisions(meshes, transforms,
                                                                  records="none"))
    meshes, transforms = nested_scene()
    yield "nested", _arrays(det.find_collisions(meshes, transforms))
    meshes, transforms = holed_scene(12, 0)
    yield "holed", _arrays(det.find_collisions(meshes, transforms, records="all"), True,
                           tolerance=_tolerances(meshes, transforms, t))
    for name, meshes, transforms, _ in open_body_cases(t):
        yield f"open/{name}", _arrays(pycinder.find_collisions(meshes, transforms, tolerance=t,
                                                               records="all"), True,
                                      tolerance=_tolerances(meshes, transforms, t))
    meshes, transforms = random_scene(24, 7)
    groups = np.arange(len(meshes)) % 3
    yield "groups", _arrays(det.find_collisions(meshes, transforms, groups=groups))
    yield "in_collision", {"found": np.array([det.in_collision(meshes, transforms)])}


MANAGER_TOLERANCE = 0.01


def _entry_points() -> Iterator[tuple[str, Answer]]:
    t = 0.01
    det = pycinder.Detector(tolerance=t)
    scenes = [random_scene(8, seed) for seed in range(6)]
    for k, result in enumerate(det.find_collisions_batch(scenes, records="all")):
        yield f"batch/{k}", _arrays(result, True, tolerance=_tolerances(*scenes[k], t))
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    manager = pycinder.CollisionManager(tolerance=MANAGER_TOLERANCE)
    for k, x in enumerate((0.0, 0.9, 1.5, 2.0)):
        manager.add_object(f"box{k}", box, trimesh.transformations.translation_matrix((x, 0, 0)))
    hit, names, data = manager.in_collision_internal(return_names=True, return_data=True)
    yield "manager", {"hit": np.array([hit]), "names": np.array(sorted(map(sorted, names))),
                      "depths": np.array(sorted(d.depth for d in data))}
    resolution = 512
    scene = pycinder.Detector(strategy="scene", resolution=resolution)
    bodies, transforms = Stairs(40, frames=1).bodies(0)
    yield "scene-strategy", _arrays(scene.find_collisions(bodies, transforms), True, False,
                                    tolerance=_pixel(bodies, transforms, resolution))


SOURCES: dict[str, Callable[[], Iterator[tuple[str, Answer]]]] = {
    "benchmark": _benchmark_scenes, "tests": _test_scenes, "entry": _entry_points}


@functools.cache
def answers(source: str) -> dict[str, Answer]:
    """What the code answers now for ``source``, by answer name (computed once per session)."""
    return dict(SOURCES[source]())


def _backend_file() -> Path:
    return DATA / f"{str(_info().get('backend_type', 'unknown')).lower()}.npz"


def stored(path: Path, source: str) -> tuple[dict[str, Answer], str]:
    """The answers of ``source`` stored in ``path``, by answer name, and their machine key."""
    out: dict[str, Answer] = {}
    with np.load(path, allow_pickle=False) as d:
        for k in d.files:
            if k.startswith(f"{source}:"):
                _, name, field = k.split(":", 2)
                out.setdefault(name, {})[field] = d[k]
        return out, str(d[KEY])


def _shapes(name: str, new: Answer, old: Answer, fields) -> list[str]:
    return [f"{name}:{f}: {new[f].dtype}{new[f].shape} against stored "
            f"{old[f].dtype}{old[f].shape}" for f in fields
            if new[f].dtype != old[f].dtype or new[f].shape != old[f].shape]


def compare_bits(name: str, new: Answer, old: Answer) -> list[str]:
    """Every field of ``new`` equal to ``old``'s, bit for bit (NaN equal to NaN)."""
    problems = _shapes(name, new, old, new)
    if problems:
        return problems
    return [f"{name}:{f} differs from the stored answer (bit for bit)" for f in new
            if not np.array_equal(new[f], old[f], equal_nan=new[f].dtype.kind == "f")]


def _by_pair(pairs: np.ndarray, values: dict[str, np.ndarray], wanted: np.ndarray
             ) -> dict[str, np.ndarray]:
    """``values`` (rows per row of ``pairs``) at the rows of ``wanted`` pairs; zeros where a
    wanted pair is not among ``pairs``."""
    index = {tuple(p): k for k, p in enumerate(pairs.tolist())}
    rows = np.array([index.get(tuple(p), -1) for p in wanted.tolist()], dtype=np.int64)
    out = {}
    for key, v in values.items():
        padded = np.concatenate([v, np.zeros((1, *v.shape[1:]), v.dtype)])
        out[key] = padded[rows]
    return out


def compare_within_bounds(name: str, new: Answer, old: Answer) -> list[str]:
    """``new`` against ``old`` as another machine may answer (the module docstring's bounds)."""
    exact = [f for f in EXACT if f in new]
    problems = _shapes(name, new, old, exact) or [
        f"{name}:{f} differs from the stored answer (compared exactly)" for f in exact
        if not np.array_equal(new[f], old[f])]
    if "record pairs" in new:
        problems += _compare_records(name, new, old)
    if "contact pairs" in new and not any(":contact pairs" in p for p in problems):
        problems += _compare_contacts(name, new, old)
    if "depths" in new:
        if new["depths"].shape != old["depths"].shape:
            problems.append(f"{name}:depths: {len(new['depths'])} against stored "
                            f"{len(old['depths'])}")
        else:
            worst = float(np.max(np.abs(new["depths"] - old["depths"]), initial=0.0))
            if worst > 2 * MANAGER_TOLERANCE:
                problems.append(f"{name}:depths differ by {worst:g}, over 2 t = "
                                f"{2 * MANAGER_TOLERANCE:g}")
    return problems


def _compare_records(name: str, new: Answer, old: Answer) -> list[str]:
    keys = np.unique(np.concatenate([new["record pairs"], old["record pairs"]]), axis=0)
    fields = ("record counts", "record centroids", "record extents", "record tolerances")
    a = _by_pair(new["record pairs"], {f: new[f] for f in fields}, keys)
    b = _by_pair(old["record pairs"], {f: old[f] for f in fields}, keys)
    n = np.maximum(a["record counts"], b["record counts"])
    bound = count_bound(n)
    problems = []
    off = np.abs(a["record counts"] - b["record counts"]) > bound
    for k in np.flatnonzero(off)[:3]:
        problems.append(f"{name}: records of {tuple(keys[k])}: {a['record counts'][k]} against "
                        f"stored {b['record counts'][k]}, more than B(n) = {bound[k]:.0f} apart")
    both = (a["record counts"] > 0) & (b["record counts"] > 0)
    t = np.maximum(a["record tolerances"], b["record tolerances"])
    extent = np.maximum(a["record extents"], b["record extents"])
    allowed = 2 * t + bound / np.maximum(n, 1) * extent
    moved = np.linalg.norm(a["record centroids"] - b["record centroids"], axis=1)
    for k in np.flatnonzero(both & (moved > allowed))[:3]:
        problems.append(f"{name}: the records of {tuple(keys[k])} moved by {moved[k]:g}, over "
                        f"2 t + B/n D = {allowed[k]:g}")
    return problems


def _compare_contacts(name: str, new: Answer, old: Answer) -> list[str]:
    """Contacts per pair (the pairs themselves were compared exactly)."""
    problems = []
    # the pair's tolerance: the larger of its two ordered record pairs'
    tol = {}
    for p, t in zip(old["record pairs"].tolist(), old["record tolerances"].tolist(),
                    strict=True):
        key = tuple(sorted(p))
        tol[key] = max(tol.get(key, 0.0), t)
    extent = {}
    for p, d in zip(old["record pairs"].tolist(), old["record extents"].tolist(), strict=True):
        key = tuple(sorted(p))
        extent[key] = max(extent.get(key, 0.0), d)
    for k, pair in enumerate(old["contact pairs"].tolist()):
        key = tuple(pair)
        t, d = tol.get(tuple(sorted(pair)), 0.0), extent.get(tuple(sorted(pair)), 0.0)
        n = max(int(new["contact samples"][k]), int(old["contact samples"][k]))
        bound = float(count_bound(n))
        if abs(int(new["contact samples"][k]) - int(old["contact samples"][k])) > bound:
            problems.append(f"{name}: contacts of {key}: {new['contact samples'][k]} samples "
                            f"against stored {old['contact samples'][k]}, more than "
                            f"B(n) = {bound:.0f} apart")
        depth = abs(float(new["contact depths"][k] - old["contact depths"][k]))
        if depth > 2 * t:
            problems.append(f"{name}: the deepest contact of {key} differs by {depth:g}, over "
                            f"2 t = {2 * t:g}")
        cos = float(np.clip(np.dot(new["contact normals"][k], old["contact normals"][k]), -1, 1))
        angle = math.degrees(math.acos(cos))
        allowed = math.degrees(math.asin(min(1.0, 2 * bound / max(n, 1)))) + ANGLE_FLOOR_DEG
        if angle > allowed:
            problems.append(f"{name}: the contact normal of {key} turned by {angle:.2f} degrees, "
                            f"over {allowed:.2f}")
        moved = float(np.linalg.norm(new["contact points"][k] - old["contact points"][k]))
        allowed = 2 * t + bound / max(n, 1) * d
        if moved > allowed:
            problems.append(f"{name}: the contact point of {key} moved by {moved:g}, over "
                            f"2 t + B/n D = {allowed:g}")
    return problems


def compare(source: str, path: Path, key: str) -> tuple[str, list[str]]:
    """Compare what the code answers now for ``source`` with the answers stored in ``path`` on
    a machine whose key is ``key`` here.

    Returns
    -------
    comparison : str
        ``"bit for bit"`` (this machine stored them) or ``"within bounds"`` (another did), with
        the two keys where they differ.
    problems : list of str
        One line per difference; empty when the answers hold.
    """
    old, stored_key = stored(path, source)
    bits = stored_key == key
    comparison = "bit for bit" if bits else \
        f"within bounds (stored on {stored_key!r}, this is {key!r})"
    new = answers(source)
    problems = [f"{source}:{name}: stored answer no longer produced"
                for name in sorted(set(old) - set(new))]
    for name, answer in new.items():
        if name not in old:
            problems.append(f"{source}:{name}: no stored answer")
        elif set(answer) != set(old[name]):
            problems.append(f"{source}:{name}: fields {sorted(answer)} against stored "
                            f"{sorted(old[name])}")
        elif bits:
            problems += compare_bits(f"{source}:{name}", answer, old[name])
        else:
            problems += compare_within_bounds(f"{source}:{name}", answer, old[name])
    return comparison, problems


def _stored_path() -> Path:
    path = _backend_file()
    if not path.exists():
        pytest.skip(f"no answers stored for this backend ({path.name})")
    return path


@pytest.mark.parametrize("source", sorted(SOURCES))
def test_answers_are_unchanged(source, record_property):
    comparison, problems = compare(source, _stored_path(), machine_key())
    record_property("comparison", comparison)
    assert not problems, f"compared {comparison}:\n" + "\n".join(problems[:20])


def test_another_cpu_compares_within_bounds_and_still_catches_a_change(monkeypatch,
                                                                       record_property):
    """On a machine with another CPU key the bounded comparison is made: it passes on this
    machine's own answers, and fails where a stored count, centroid, depth or pair moves past
    its bound."""
    path = _stored_path()
    monkeypatch.setattr(sys.modules[__name__], "cpu_key", lambda: "another CPU [avx2 fma]")
    comparison, problems = compare("tests", path, machine_key())
    record_property("comparison", comparison)
    assert comparison.startswith("within bounds") and "another CPU" in comparison
    assert not problems, f"compared {comparison}:\n" + "\n".join(problems[:20])
    old, _ = stored(path, "tests")
    name = "random-0/all"
    new = answers("tests")[name]
    assert not compare_within_bounds(name, new, old[name])
    n = int(old[name]["record counts"][0])
    t = float(old[name]["record tolerances"][0])
    extent = float(old[name]["record extents"][0])
    changes = {
        "record counts": lambda a: a.__setitem__(0, 4 * n + 100),  # B(4n + 100) < 3n + 100
        "record centroids": lambda a: a.__setitem__(
            (0, 0), a[0, 0] + 2 * t + float(count_bound(n)) / n * extent + t),
        "contact depths": lambda a: a.__setitem__(0, a[0] + 3 * t),
        "pairs": lambda a: a.__setitem__((0, 1), a[0, 1] + 1),
    }
    for field, change in changes.items():
        changed = {f: v.copy() for f, v in old[name].items()}
        change(changed[field])
        assert compare_within_bounds(name, new, changed), \
            f"{field} moved past its bound, and the bounded comparison did not see it"


def test_the_other_backends_answers_hold_within_bounds(record_property):
    """The other backend's stored answers (another driver: other bits, other record counts)
    hold within the bounds against this backend's answers: the bounds are wide enough for a
    real difference of rounding, on every source."""
    here = _backend_file()
    others = [p for p in sorted(DATA.glob("*.npz")) if p != here]
    if not others:
        pytest.skip("answers are stored for one backend only")
    record_property("comparison", f"within bounds (against {others[0].name})")
    for source in sorted(SOURCES):
        comparison, problems = compare(source, others[0], "another backend")
        assert not problems, f"compared {comparison}:\n" + "\n".join(problems[:20])


def test_this_machine_compares_bit_for_bit(record_property):
    """Where the key is the one stored, a digest that differs (one changed bit) fails."""
    path = _stored_path()
    old, stored_key = stored(path, "tests")
    if stored_key != machine_key():
        pytest.skip(f"answers were stored on {stored_key!r}, this is {machine_key()!r}")
    record_property("comparison", "bit for bit")
    name = "random-0/all"
    new = answers("tests")[name]
    assert not compare_bits(name, new, old[name])
    changed = dict(old[name], records=np.array("0" * 64))
    assert compare_bits(name, new, changed)


def write() -> Path:
    """Store what the code answers now for this backend, keyed by :func:`machine_key`."""
    out: dict[str, np.ndarray] = {KEY: np.array(machine_key())}
    for source in SOURCES:
        for name, answer in answers(source).items():
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

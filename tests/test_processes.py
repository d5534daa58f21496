"""Results as plain data across processes: pickling (pairs, records and contacts read back equal),
process pools with either start method, and a process forked after its parent used the GPU (a
working detector of its own where the parent's driver works after a fork, else a clear error
raised before the child calls the driver: never a hang, never an abort).

Every wait on another process has a deadline, so a hang fails the test instead of blocking the
suite. The deadlines of all the tests together (:data:`WORST_CASE_SECONDS`) fit the budget that
``scripts/gpu-check.sh`` gives this file (``PROCESSES_S``), so that every test's verdict comes
back even when each of them hangs.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.gpu.device import FORK_PROBE_SECONDS, get_gpu, survives_fork
from pycinder.testing import ground_truth

SPAWN_DEADLINE = 30.0
"""Seconds a pool of fresh workers may take to answer (each imports pycinder, makes its device
and compiles its pipelines: a few seconds on lavapipe)."""
FORK_DEADLINE = 3 * FORK_PROBE_SECONDS
"""Seconds a forked child may take to answer or to be refused: its device's round trip
(:data:`~pycinder.gpu.device.FORK_PROBE_SECONDS`) and its first query, or a refusal at once."""
WORST_CASE_SECONDS = 3 * (SPAWN_DEADLINE + 5) + 4 * (FORK_DEADLINE + 5) + 30
"""The longest this file can run when every wait reaches its deadline: three spawned pools, four
forking tests (each with one deadline), a few seconds each to stop them, and half a minute for
the tests that wait on nothing (under a second each)."""

SURVIVES_FORK = survives_fork(get_gpu().adapter.info)
"""Whether this device's driver works in a forked child (else the child is refused)."""


def scene(gap: float) -> tuple[list[trimesh.Trimesh], np.ndarray]:
    """A unit box, a ball of radius 0.4 whose centre is 0.9 + ``gap`` from the box's (``gap``
    apart, or ``-gap`` deep), and a second ball far from both."""
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.4)
    transforms = np.tile(np.eye(4), (3, 1, 1))
    transforms[1, 0, 3] = 0.9 + gap
    transforms[2, 0, 3] = 10.0
    return [box, ball, ball], transforms


def query(gap: float) -> pycinder.CollisionResult:
    """A query with names, asked for its contacts, as a pool worker would return it (its
    contacts computed there)."""
    meshes, transforms = scene(gap)
    result = pycinder.find_collisions(meshes, transforms, names=["box", "ball", "far"],
                                      tolerance=0.005, contacts=True)
    result.contacts()
    return result


def query_plain(gap: float) -> pycinder.CollisionResult:
    """:func:`query` returned with its contacts not yet computed: the parent reduces them."""
    meshes, transforms = scene(gap)
    return pycinder.find_collisions(meshes, transforms, names=["box", "ball", "far"],
                                    tolerance=0.005, contacts=True)


def driver_called() -> bool:
    """Whether this process has asked wgpu-native for an instance of its own (a forked child's
    hook forgets the parent's)."""
    from wgpu.backends.wgpu_native import _helpers

    return _helpers._the_instance is not None


def answer(gap: float) -> tuple[int, object, object]:
    """What a forked worker reports: its process, and its pairs and their names; or, refused,
    ``"refused"``, the message, and whether the driver was called before the refusal."""
    try:
        result = query(gap)
    except pycinder.ForkedProcessError as exc:
        return os.getpid(), "refused", (str(exc), driver_called())
    return os.getpid(), result.pairs.tolist(), sorted(result.pair_names())


def assert_same_result(a: pycinder.CollisionResult, b: pycinder.CollisionResult) -> None:
    """The same answer: pairs, names, records, contacts, and what the query did (its times
    aside)."""
    np.testing.assert_array_equal(a.pairs, b.pairs)
    assert a.records.dtype == b.records.dtype
    for name in a.records.dtype.names:
        np.testing.assert_array_equal(a.records[name], b.records[name], err_msg=name)
    ca, cb = a.contacts(), b.contacts()
    for name in ("pair", "point", "normal", "depth", "face", "deepest", "samples"):
        np.testing.assert_array_equal(getattr(ca, name), getattr(cb, name), err_msg=name)
    assert [repr(c) for c in ca] == [repr(c) for c in cb]
    assert a.names == b.names and a.pair_names() == b.pair_names()
    assert a.stats.tiles == b.stats.tiles and a.stats.records == b.stats.records
    assert a.stats.detail.tolerance == b.stats.detail.tolerance
    assert a.stats.detail.candidates == b.stats.detail.candidates
    assert repr(a) == repr(b)


def test_box_and_ball_truth() -> None:
    """The scenes these tests send between processes, against exact geometry at their tolerance:
    0.1 deep must be reported, 0.05 apart never."""
    for gap, colliding in ((-0.1, True), (0.05, False)):
        meshes, transforms = scene(gap)
        truth = ground_truth(meshes, transforms, tolerance=0.005)
        assert truth.overlap.tolist() == ([[0, 1]] if colliding else [])
        assert [0, 1] in truth.separate.tolist() or colliding


def test_result_pickles_with_records_contacts_and_stats() -> None:
    """A result asked for contacts pickles as it is and reads back equal: pairs, every field of
    every record, every array of its contacts, names and stats."""
    result = query(-0.1)
    assert result.pairs.tolist() == [[0, 1]] and len(result.contacts())
    assert result.records_kept == "all" and not hasattr(result, "query")
    copy = pickle.loads(pickle.dumps(result))
    assert copy._contacts is not None  # the contacts travelled with it
    assert_same_result(result, copy)
    assert copy.records_kept == "all"
    assert copy.stats == result.stats and copy.stats.wall_ms == result.stats.wall_ms
    assert pickle.loads(pickle.dumps(result.stats)) == result.stats
    contacts = pickle.loads(pickle.dumps(result.contacts()))
    np.testing.assert_array_equal(contacts.point, result.contacts().point)
    assert contacts.names == ["box", "ball", "far"]


def test_pickled_result_computes_contacts_from_every_record() -> None:
    """A result asked for contacts reduces them in the copy, without a GPU, as the original
    does."""
    result = query_plain(-0.1)
    copy = pickle.loads(pickle.dumps(result))
    assert copy._contacts is None
    assert_same_result(result, copy)


def test_pickled_result_without_every_record_says_how_to_get_contacts() -> None:
    meshes, transforms = scene(-0.1)
    result = pycinder.find_collisions(meshes, transforms, tolerance=0.005)  # records="found"
    copy = pickle.loads(pickle.dumps(result))
    np.testing.assert_array_equal(copy.records["point"], result.records["point"])
    for r in (result, copy):
        with pytest.raises(ValueError, match=r"records='found'.*contacts=True"):
            r.contacts()


@pytest.mark.parametrize("method", ["spawn", "forkserver"])
def test_pool_returns_equal_results(method: str) -> None:
    """Results come back from a pool whose workers start afresh, equal to the same query here."""
    here = {gap: query(gap) for gap in (-0.1, 0.05)}
    with multiprocessing.get_context(method).Pool(2) as pool:
        there = pool.map_async(query, list(here)).get(SPAWN_DEADLINE)
    for (gap, mine), theirs in zip(here.items(), there):
        assert_same_result(mine, theirs)
    assert there[0].pair_names() == {("ball", "box")} and not there[1]


def test_pool_returns_results_whose_contacts_are_reduced_here() -> None:
    """A result asked for contacts, sent back before they were computed, reduces them here
    from its own records: equal to the same query's here."""
    here = query(-0.1)
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        (there,) = pool.map_async(query_plain, [-0.1]).get(SPAWN_DEADLINE)
    assert there._contacts is None
    assert_same_result(here, there)


def test_fork_after_the_parent_used_the_gpu() -> None:
    """Workers forked after this process ran queries (and after earlier tests shared wgpu's
    default device with pygfx) answer with devices of their own where the driver works after a
    fork; elsewhere each raises ForkedProcessError naming the fix, before it calls the driver
    (NVIDIA's Vulkan driver aborts a forked child that asks it for an adapter). Never a hang:
    the pool's answers have a deadline."""
    query(0.05)  # this process has a device, pipelines and a shared detector
    gaps = [-0.1, 0.05, -0.1]
    expected = {-0.1: ([[0, 1]], [("ball", "box")]), 0.05: ([], [])}
    with multiprocessing.get_context("fork").Pool(2) as pool:
        replies = pool.map_async(answer, gaps).get(FORK_DEADLINE)
    assert all(pid != os.getpid() for pid, *_ in replies)
    for gap, (_, first, second) in zip(gaps, replies, strict=True):
        if first == "refused":
            message, called = second
            assert "forked" in message and "'spawn'" in message, message
            # where the driver is not known to work after a fork, it was never called
            assert SURVIVES_FORK or not called, message
        else:
            assert SURVIVES_FORK, "a driver not known to work after a fork was used in a child"
            assert (first, second) == expected[gap]
    assert query(-0.1).pairs.tolist() == [[0, 1]]  # the parent's device still works


FORKING_PROGRAM = """
import os, sys, trimesh, pycinder
if sys.argv[1] == "shared":
    pycinder.share_default_device()   # as the demos do, to render with pygfx
box = trimesh.creation.box((1, 1, 1))
ball = trimesh.creation.icosphere(radius=0.4).apply_translation((0.6, 0, 0))
assert pycinder.find_collisions([box, ball]).pairs.tolist() == [[0, 1]]
pid = os.fork()
if pid == 0:
    try:
        print("child", pycinder.find_collisions([box, ball]).pairs.tolist(), flush=True)
    except pycinder.ForkedProcessError as exc:
        from wgpu.backends.wgpu_native import _helpers
        print("child refused:", exc, "| driver called:", _helpers._the_instance is not None,
              flush=True)
    os._exit(0)
os.waitpid(pid, 0)
print("parent", pycinder.find_collisions([box, ball]).pairs.tolist())
"""


@pytest.mark.parametrize("device", ["own", "shared"])
def test_forked_child_makes_its_own_device(device: str) -> None:
    """In a small program that forks after its first query, on its own device or on wgpu's
    default device shared with pygfx: where the driver works after a fork (lavapipe) the child
    answers on a device of its own; with any other driver (NVIDIA's Vulkan, llvmpipe's OpenGL)
    it is refused, naming the fix, without calling the driver."""
    done = subprocess.run([sys.executable, "-c", FORKING_PROGRAM, device], capture_output=True,
                          text=True, timeout=FORK_DEADLINE)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[-1] == "parent [[0, 1]]", done.stdout
    if SURVIVES_FORK:
        assert lines[0] == "child [[0, 1]]", done.stdout + done.stderr
    else:
        assert lines[0].startswith("child refused:") and "'spawn'" in lines[0], done.stdout
        assert lines[0].endswith("| driver called: False"), done.stdout


def _use_inherited(detector: pycinder.Detector, manager: pycinder.CollisionManager,
                   conn) -> None:
    """In a forked child: the parent's detector refuses before anything reaches the driver; its
    manager makes a detector of its own, or is refused where the driver does not work after a
    fork."""
    try:
        meshes, transforms = scene(-0.1)
        try:
            detector.find_collisions(meshes, transforms)
            conn.send(("detector answered", None))
        except pycinder.ForkedProcessError as exc:
            conn.send(("refused", (str(exc), driver_called())))
        try:
            conn.send(("manager", manager.in_collision_internal(return_names=True)))
        except pycinder.ForkedProcessError as exc:
            conn.send(("manager refused", (str(exc), driver_called())))
    finally:
        conn.close()


def test_objects_made_before_a_fork() -> None:
    meshes, transforms = scene(-0.1)
    detector = pycinder.Detector()
    manager = pycinder.CollisionManager()
    for name, mesh, transform in zip(("box", "ball"), meshes, transforms):
        manager.add_object(name, mesh, transform)
    assert detector.find_collisions(meshes, transforms).pairs.tolist() == [[0, 1]]
    assert manager.in_collision_internal()
    assert detector.in_this_process
    ctx = multiprocessing.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    process = ctx.Process(target=_use_inherited, args=(detector, manager, child))
    process.start()
    child.close()
    deadline = time.monotonic() + FORK_DEADLINE  # one deadline for the child's two answers
    try:
        assert parent.poll(FORK_DEADLINE), "the forked child did not answer"
        kind, (message, called) = parent.recv()
        assert kind == "refused"
        assert "made in a parent process" in message and "'spawn'" in message
        assert not called  # refused before anything reached the driver
        assert parent.poll(max(deadline - time.monotonic(), 0.0)), \
            "the forked child's manager did not answer"
        kind, value = parent.recv()
        if kind == "manager":
            assert SURVIVES_FORK
            assert value == (True, {("ball", "box")})
        else:  # a driver not known to work after a fork (or one that did not answer): said
            message, called = value
            assert kind == "manager refused" and "'spawn'" in message
            assert SURVIVES_FORK or not called, message
    finally:
        process.join(max(deadline - time.monotonic(), 1.0))
        if process.is_alive():
            process.kill()
            process.join()
    assert process.exitcode == 0
    assert detector.find_collisions(meshes, transforms).pairs.tolist() == [[0, 1]]


def test_the_deadlines_fit_the_gpu_check_budget() -> None:
    """Every default budget ``scripts/gpu-check.sh`` gives this file holds all of its deadlines
    (:data:`WORST_CASE_SECONDS`), so that each test's verdict comes back before the step stops."""
    script = (Path(__file__).resolve().parents[1] / "scripts" / "gpu-check.sh").read_text()
    budgets = [int(b) for b in re.findall(r"processes_s=\$\{PROCESSES_S:-(\d+)\}", script)]
    assert budgets, "gpu-check.sh gives the process tests no default budget"
    assert min(budgets) >= WORST_CASE_SECONDS, (budgets, WORST_CASE_SECONDS)

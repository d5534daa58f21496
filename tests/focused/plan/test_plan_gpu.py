"""The GPU tile planner (``planner="gpu"``, :mod:`pycinder.focused.plan.plan_gpu`) against the NumPy
planner it ports and against exact geometry: whole plans compared tile by tile on random scenes
(rotated, scaled, sheared, mirrored, far and tiny bodies), and the answers of queries planned
either way."""

import warnings

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing.scenes import ManyBodies, Stairs
from pycinder.errors import GpuMemoryError, PrecisionWarning
from pycinder.gpu.device import get_gpu
from pycinder.focused.plan.plan_gpu import GpuPlanner
from pycinder.testing import ground_truth, holed_scene, nested_scene, random_boxes, random_scene
from pycinder.focused.plan.plan_numpy import plan_tiles, tiles_of_windows

from conftest import assert_matches_truth

T = trimesh.transformations.translation_matrix


@pytest.fixture(scope="module")
def planner() -> GpuPlanner:
    return GpuPlanner(get_gpu())


@pytest.fixture(scope="module")
def gpu_detector() -> pycinder.Detector:
    return pycinder.Detector(planner="gpu")


def _compare(gpu, ref, *, context: str) -> None:
    """The same tiles in the same places and rounds (integers exactly), with the same views and
    depth ranges up to the rounding of float64 sums (``ref`` is the NumPy planner's packing of
    the GPU's own windows)."""
    assert len(gpu) == len(ref), context
    assert gpu.separated == ref.separated, context
    assert gpu.atlas_width == ref.atlas_width, context
    assert list(gpu.round_rows) == list(ref.round_rows), context
    for name in ("pair", "bodies", "window", "round", "flags"):
        np.testing.assert_array_equal(getattr(gpu, name), getattr(ref, name),
                                      err_msg=f"{context}: {name}")
    np.testing.assert_array_equal(gpu.pixel, ref.pixel, err_msg=context)
    np.testing.assert_array_equal(gpu.axes, ref.axes, err_msg=context)
    np.testing.assert_array_equal(gpu.slab, ref.slab, err_msg=context)
    off = np.abs(gpu.origin - ref.origin).max(axis=1)
    scale = np.abs(ref.origin).max(axis=1) + ref.pixel * ref.window[:, 2:].max(axis=1)
    assert (off <= 1e-14 * scale).all(), f"{context}: origins {off.max()} apart"


def _inputs_args(inputs: dict) -> tuple:
    return (inputs["pairs"], inputs["pair_tolerances"], inputs["local_lo"], inputs["local_hi"],
            inputs["world_lo"], inputs["world_hi"], inputs["transforms"])


SCENES = [
    # (seed, bodies, scale, offset from the world's origin)
    (1, 60, 1.0, 0.0), (2, 200, 1.0, 0.0), (3, 60, 1e-3, 0.0), (4, 60, 1e3, 0.0),
    (5, 60, 1.0, 1e7), (6, 60, 1e3, 1e13), (7, 400, 0.05, -3.0),
]


@pytest.mark.parametrize("seed,n,scale,offset", SCENES)
@pytest.mark.parametrize("budget", [2**22, 2**14])
def test_plans_equal_the_numpy_planner(planner, seed, n, scale, offset, budget):
    """Random scenes of rotated, scaled, sheared and mirrored boxes, flat ones and equal ones,
    open and dense bodies, near the origin and far from it, at three scales, with a budget that
    holds the plan in one round and one that cuts it into many."""
    inputs = random_boxes(n, seed, scale=scale, offset=offset)
    args = _inputs_args(inputs)
    kw = dict(budget_pixels=budget, probe=True, open_bodies=inputs["open_bodies"],
              faces=inputs["faces"])
    gpu, words = planner.plan(*args, **kw)
    assert words is planner.words.tiles.buffer
    # The GPU's windows (pass P1 again: the same values) packed by the NumPy planner.
    cat = planner.windows.run(*args, open_bodies=inputs["open_bodies"])
    ref = tiles_of_windows(cat, inputs["pairs"], inputs["pair_tolerances"], budget_pixels=budget,
                           faces=inputs["faces"])
    context = f"seed {seed}, {len(inputs['pairs'])} pairs, budget {budget}"
    assert len(gpu) > n // 2, context
    _compare(gpu, ref, context=context)
    # The whole NumPy planner: the same windows up to single precision's rounding.
    numpy_plan = plan_tiles(*args, **kw)
    assert numpy_plan.separated == gpu.separated, context
    if len(numpy_plan) == len(gpu) and (numpy_plan.window == gpu.window).all():
        np.testing.assert_array_equal(numpy_plan.pair, gpu.pair, err_msg=context)
        np.testing.assert_array_equal(numpy_plan.round, gpu.round, err_msg=context)
        assert numpy_plan.round_rows == gpu.round_rows, context
    else:
        # A window of almost a whole number of pixels may round to one more or one fewer.
        k = len(inputs["pairs"])
        pixels = [np.bincount(p.pair, p.window[:, 2] * p.window[:, 3], k)
                  for p in (numpy_plan, gpu)]
        differ = np.flatnonzero(pixels[0] != pixels[1])
        assert len(differ) <= max(1, len(gpu) // 500), f"{context}: {len(differ)} windows differ"


def test_a_plan_of_many_pieces_grows_its_buffers(planner):
    """Large windows cut into many pieces: more tiles than the first guess holds, so the
    passes run again with larger buffers, and the plan is still the NumPy planner's."""
    inputs = random_boxes(12, 8, scale=1.0)
    inputs["pair_tolerances"] = np.full(len(inputs["pairs"]), 5e-4)
    args = _inputs_args(inputs)
    fresh = GpuPlanner(get_gpu())
    gpu, _ = fresh.plan(*args, budget_pixels=2**22, faces=inputs["faces"])
    assert len(gpu) > 2 * len(inputs["pairs"]) + 16
    assert fresh.atlas.capacity >= len(gpu)
    cat = fresh.windows.run(*args)
    ref = tiles_of_windows(cat, inputs["pairs"], inputs["pair_tolerances"], budget_pixels=2**22,
                           faces=inputs["faces"])
    _compare(gpu, ref, context="many pieces")


def test_every_pair_apart_and_no_pair(planner):
    inputs = random_boxes(30, 9, spread=50.0)
    far = inputs["pairs"][:0]
    empty, none = planner.plan(far, np.zeros(0), *_inputs_args(inputs)[2:], budget_pixels=2**22)
    assert len(empty) == 0 and empty.separated == 0 and none is None
    # Two boxes whose world boxes meet but whose oriented boxes are apart.
    lo, hi = np.zeros((2, 3)), np.ones((2, 3))
    transforms = np.stack([np.eye(4)] * 2)
    rot = trimesh.transformations.rotation_matrix(np.pi / 4, (0, 0, 1))
    transforms[1] = T((1.6, 0.5, 0)) @ rot
    world_lo = np.array([[0.0, 0, 0], [1.6 - 0.7072, 0.5, 0]])
    world_hi = np.array([[1.0, 1, 1], [1.6 + 0.7072, 0.5 + 1.4143, 1]])
    plan, _ = planner.plan(np.array([[0, 1]]), np.array([0.01]), lo, hi, world_lo, world_hi,
                        transforms, budget_pixels=2**22)
    assert len(plan) == 0 and plan.separated == 1


def test_too_many_pixels_are_refused_as_the_numpy_planner_refuses_them(planner):
    inputs = random_boxes(40, 10)
    args = _inputs_args(inputs)
    with pytest.raises(GpuMemoryError) as numpy_error:
        plan_tiles(*args, budget_pixels=2**22, max_pixels=1000)
    with pytest.raises(GpuMemoryError) as gpu_error:
        planner.plan(*args, budget_pixels=2**22, max_pixels=1000)
    assert str(gpu_error.value).split("(largest")[0] == str(numpy_error.value).split("(largest")[0]
    assert "a tolerance about" in str(gpu_error.value)


# Queries planned on the GPU, against exact geometry.

@pytest.mark.parametrize("n,seed,size", [(60, 31, 1.0), (60, 32, 0.01), (60, 33, 100.0),
                                         (120, 5, 1.0)])
def test_random_scenes_against_exact_geometry(gpu_detector, n, seed, size):
    meshes, transforms = random_scene(n, seed, size=size)
    truth = ground_truth(meshes, transforms)
    result = gpu_detector.find_collisions(meshes, transforms)
    assert 0 < result.stats.waited_ms < result.stats.submitted_ms
    assert_matches_truth(result.pairs, truth, context=f"{n} bodies, seed {seed}, size {size}")
    other = pycinder.Detector(planner="numpy").find_collisions(meshes, transforms)
    assert {tuple(p) for p in other.pairs.tolist()} ^ {tuple(p) for p in result.pairs.tolist()} \
        <= {tuple(p) for p in truth.ambiguous.tolist()}


def test_nested_holed_and_mirrored_scenes(gpu_detector):
    meshes, transforms = nested_scene()
    assert gpu_detector.find_collisions(meshes, transforms).pairs.tolist() == [[0, 1]]
    meshes, transforms = holed_scene(24, 3)
    assert_matches_truth(gpu_detector.find_collisions(meshes, transforms).pairs,
                         ground_truth(meshes, transforms), context="holed plates")
    meshes, transforms = random_scene(40, 7)
    mirror = np.diag([1.0, -1.0, 1.0, 1.0])
    mirrored = [mirror @ t if k % 2 else t for k, t in enumerate(transforms)]
    meshes = [m.copy() for m in meshes]
    for k in range(1, len(meshes), 2):  # mirrored bodies, the same world shapes
        meshes[k].apply_transform(mirror)
        meshes[k].invert()
    assert_matches_truth(gpu_detector.find_collisions(meshes, mirrored).pairs,
                         ground_truth(meshes, mirrored), context="mirrored")


def test_far_and_tiny_bodies(gpu_detector):
    box = trimesh.creation.box((1, 1, 1))
    far = box.copy()
    far.apply_translation((1e7, 0, 0))
    assert gpu_detector.find_collisions([far, far], [np.eye(4), T((0.8, 0, 0))]).pairs.tolist() \
        == [[0, 1]]
    assert gpu_detector.find_collisions([far, far], [np.eye(4), T((1.05, 0, 0))]).pairs.tolist() \
        == []
    ball = trimesh.creation.icosphere(radius=0.5)
    for at in (1e7, 1e13):  # far from the origin: the tolerance is raised as the policy says
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PrecisionWarning)
            moved = [T((at, at, 0)), T((at + 0.9, at, 0))]
            result = gpu_detector.find_collisions([ball, ball], moved)
            assert result.pairs.tolist() == [[0, 1]]
            assert result.stats.tolerance == \
                pycinder.find_collisions([ball, ball], moved).stats.tolerance
            moved = [T((at, at, 0)), T((at + 1.1, at, 0))]
            assert gpu_detector.find_collisions([ball, ball], moved).pairs.tolist() == []
    # A tiny body inside a huge one, at the tolerance single precision resolves there.
    small = trimesh.creation.box((1e-6,) * 3)
    big = trimesh.creation.box((1e6,) * 3)
    with pytest.warns(PrecisionWarning, match="raised to what the GPU resolves"):
        result = gpu_detector.find_collisions([big, small], [np.eye(4), T((5e5 - 0.1, 0, 0))])
    assert result.pairs.tolist() == [[0, 1]]
    with pytest.raises(ValueError, match=r"tolerance 1e-08 is too fine.*body 0 and body 1"):
        pycinder.find_collisions([big, small], [np.eye(4), T((5e5 - 0.1, 0, 0))],
                                 tolerance=1e-8, planner="gpu")
    for size in (1e19, 1e29):
        huge = trimesh.creation.box((size,) * 3)
        assert gpu_detector.find_collisions([huge, huge], [np.eye(4), T((0.9 * size, 0, 0))]
                                            ).pairs.tolist() == [[0, 1]]
        assert gpu_detector.find_collisions([huge, huge], [np.eye(4), T((1.1 * size, 0, 0))]
                                            ).pairs.tolist() == []


def test_every_entry_point_plans_on_the_gpu():
    meshes, transforms = random_scene(30, 11)
    truth = ground_truth(meshes, transforms)
    found = pycinder.find_collisions(meshes, transforms, planner="gpu")
    assert_matches_truth(found.pairs, truth, context="find_collisions")
    det = pycinder.Detector(planner="gpu", records="all", contacts=True)
    step = det.find_collisions(meshes, transforms)
    assert_matches_truth(step.pairs, truth, context="contacts")
    assert len(step.contacts()) >= len(truth.overlap)
    assert det.in_collision(meshes, transforms) == bool(len(truth.overlap))
    scenes = [random_scene(20, s) for s in (12, 13)]
    batch = pycinder.Detector(planner="gpu").find_collisions_batch(scenes)
    for (m, t), r in zip(scenes, batch):
        assert_matches_truth(r.pairs, ground_truth(m, t), context="batch")


def test_ManyBodies_and_Stairs_answer_as_with_the_numpy_planner(gpu_detector):
    for scene in (ManyBodies(300, 1, seed=2), Stairs(60, 1)):
        verts, transforms = scene.frame(0)
        bodies = list(zip(verts, scene.faces))
        mine = gpu_detector.find_collisions(bodies, transforms)
        other = pycinder.Detector().find_collisions(bodies, transforms)
        assert mine.stats.tiles == other.stats.tiles, scene.name
        differ = {tuple(p) for p in mine.pairs.tolist()} ^ {tuple(p) for p in other.pairs.tolist()}
        if differ:  # a close call rounded the other way: it must be one the contract leaves open
            meshes = [trimesh.Trimesh(v, f, process=False) for v, f in bodies]
            truth = ground_truth(meshes, list(transforms))
            assert differ <= {tuple(p) for p in truth.ambiguous.tolist()}, scene.name


def test_tile_views_are_gathered_only_when_read(monkeypatch):
    """A GPU plan gathers its tiles' views on the host only when they are read: a query of
    pairs only never does, one whose records are decoded does, and the views are those gathered
    at once (the plan compares with the NumPy planner's packing above either way)."""
    from pycinder.focused.plan import plan_gpu

    gathered = []
    real = plan_gpu._Views.gather
    monkeypatch.setattr(plan_gpu._Views, "gather",
                        lambda self: gathered.append(1) or real(self))
    scene = ManyBodies(120, 1, seed=4)
    verts, transforms = scene.frame(0)
    bodies = list(zip(verts, scene.faces))
    pairs_only = pycinder.Detector(planner="gpu", records="none")
    found = pairs_only.find_collisions(bodies, transforms)
    assert found.stats.planner == "gpu" and len(found.pairs) and not gathered
    with_records = pycinder.Detector(planner="gpu", records="found")
    result = with_records.find_collisions(bodies, transforms)
    assert not gathered  # decoded only when read
    assert len(result.records) and gathered
    np.testing.assert_array_equal(result.pairs, found.pairs)
    inputs = random_boxes(40, 3)
    plan, _ = GpuPlanner(get_gpu()).plan(*_inputs_args(inputs), budget_pixels=2**20)
    assert plan._gathered is None
    views = real(plan._views)
    for k, name in enumerate(("axes", "origin", "pixel", "slab")):
        np.testing.assert_array_equal(getattr(plan, name), views[k], err_msg=name)


def test_the_option_is_checked():
    with pytest.raises(ValueError, match="planner"):
        pycinder.Detector(planner="cuda")
    with pytest.raises(ValueError, match="planner applies to strategy='focused'"):
        pycinder.Detector(strategy="scene", planner="gpu")


def test_a_frame_run_again_composes_its_tiles_on_the_host():
    """The frame copies the planner's tile words on the GPU; a frame run again (its records
    outgrew their buffer) composes them on the host instead (a later plan may have replaced the
    planner's): the same pairs and records either way."""
    box, ball = trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)
    scene = ([box, ball], [np.eye(4), T((0.6, 0, 0))])
    det = pycinder.Detector(planner="gpu", records="all", tolerance=0.01)
    once = det.find_collisions(*scene)
    assert once.stats.reruns == 0 and len(once.records) > 64
    det.strategy.frames.buffers.caps.records = 64
    again = det.find_collisions(*scene)
    assert again.stats.reruns >= 1
    assert again.pairs.tolist() == once.pairs.tolist() == [[0, 1]]
    key = ["edge", "penetrating", "penetrated"]
    assert np.array_equal(np.sort(again.records[key]), np.sort(once.records[key]))
    np.testing.assert_allclose(np.sort(again.records["point"], axis=0),
                               np.sort(once.records["point"], axis=0), atol=1e-5)


def test_a_timeout_while_planning_names_the_plan_and_leaves_the_detector_usable(monkeypatch):
    from pycinder.errors import GpuTimeoutError
    from pycinder.gpu import buffers

    box, ball = trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)
    scene = ([box, ball], [np.eye(4), T((0.8, 0, 0))])
    det = pycinder.Detector(planner="gpu")
    monkeypatch.setattr(buffers, "wait_for", lambda promise, timeout: False)
    with pytest.raises(GpuTimeoutError, match=r"did not finish the tile plan of 1 candidate pair "
                                              r"within 60 s.*detector was reset"):
        det.find_collisions(*scene)
    monkeypatch.undo()
    assert det.find_collisions(*scene).pairs.tolist() == [[0, 1]]


def test_queries_the_gpu_does_not_plan_compose_their_tiles_on_the_host(monkeypatch):
    """A query of more candidate pairs than the GPU planner takes, after one it planned, and a
    query that stops at its first pair (its lead pairs and its stop flag are the host's): each
    frame gets the tiles of its own plan, never the planner's last ones."""
    import pycinder.focused.plan.plan_gpu

    meshes, transforms = random_scene(40, 14)
    truth = ground_truth(meshes, transforms)
    det = pycinder.Detector(planner="gpu")
    assert_matches_truth(det.find_collisions(meshes, transforms).pairs, truth, context="gpu")
    assert det.strategy._planner.waited_ms > 0
    monkeypatch.setattr(pycinder.focused.plan.plan_gpu, "MAX_PAIRS", 8)
    result = det.find_collisions(meshes, transforms)
    assert result.stats.candidates > 8 and det.strategy._planner.waited_ms == 0
    assert_matches_truth(result.pairs, truth, context="more pairs than the planner takes")
    monkeypatch.undo()
    fresh = pycinder.Detector(planner="gpu")
    box, ball = trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)
    assert fresh.in_collision([box, ball], [np.eye(4), T((0.8, 0, 0))])
    assert not fresh.in_collision([box, ball], [np.eye(4), T((1.0, 0, 0))])
    assert fresh.strategy._planner is None


def test_two_queries_in_flight_keep_their_own_tiles():
    """Two queries submitted before either is read, the second's plan larger than the first's
    (the planner's buffers grow under the first frame): each answers its own scene."""
    det = pycinder.Detector(planner="gpu")
    small, small_t = random_scene(20, 15)
    large, large_t = random_scene(120, 16)
    first = det.submit(small, small_t)
    second = det.submit(large, large_t)
    assert second.result().stats.tiles > 2 * first.result().stats.tiles
    assert_matches_truth(first.result().pairs, ground_truth(small, small_t), context="first")
    assert_matches_truth(second.result().pairs, ground_truth(large, large_t), context="second")


def test_auto_plans_on_the_gpu_from_its_pair_count(monkeypatch):
    """``planner="auto"`` (the default) plans on the GPU from ``GPU_PLANNER_PAIRS`` candidate
    pairs (the CPU adapter's count on a CPU adapter), on the host below it and for a query that
    stops at its first pair; ``stats.planner`` says which, and the pairs are those of the NumPy
    planner, right against the truth."""
    import pycinder.request as request

    gpu = get_gpu()
    key = "cpu" if gpu.cpu_adapter else "gpu"
    meshes, transforms = random_scene(24, 4)
    truth = ground_truth(meshes, transforms)
    reference = pycinder.Detector(planner="numpy").find_collisions(meshes, transforms)
    pairs = reference.stats.candidates
    assert pairs >= 4
    for threshold, where in ((pairs, "gpu"), (pairs + 1, "numpy")):
        monkeypatch.setitem(request.GPU_PLANNER_PAIRS, key, threshold)
        result = pycinder.Detector().find_collisions(meshes, transforms)
        assert result.stats.planner == where
        # The planners may round a close decision differently: only in the contract's band.
        assert {tuple(p) for p in result.pairs.tolist()} ^ \
            {tuple(p) for p in reference.pairs.tolist()} <= \
            {tuple(p) for p in truth.ambiguous.tolist()}
    assert reference.stats.planner == "numpy"
    assert pycinder.Detector(planner="gpu").find_collisions(meshes, transforms).stats.planner \
        == "gpu"
    monkeypatch.setitem(request.GPU_PLANNER_PAIRS, key, 0)  # stops at its first: the host's
    assert pycinder.Detector().in_collision(meshes, transforms) == (len(reference.pairs) > 0)
    assert_matches_truth(reference.pairs, truth)
    with pytest.raises(ValueError, match="planner applies to strategy='focused'"):
        pycinder.Detector(strategy="scene", planner="gpu")
    assert pycinder.Detector(strategy="scene").request.planner == "auto"

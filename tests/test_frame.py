"""What one query costs the host in GPU round trips: one submission and one map for records
"none" and "found" (the passes, their timestamps and the readback travel together)."""

import sys

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.gpu.buffers import Readback
from pycinder.gpu.layout import COUNTERS


class _Count:
    def __init__(self, monkeypatch):
        self.submits = self.maps = 0
        queue_type = type(pycinder.Detector().gpu.device.queue)
        submit = queue_type.submit
        start = Readback.start  # every map of pycinder's is asked for here

        def counted_submit(queue, *args, **kwargs):
            # wgpu-py itself submits an empty command buffer before a buffer's first map for
            # reading (a driver workaround); count pycinder's own submissions.
            if "pycinder" in sys._getframe(1).f_code.co_filename:
                self.submits += 1
            return submit(queue, *args, **kwargs)

        def counted_map(readback, *args, **kwargs):
            self.maps += 1
            return start(readback, *args, **kwargs)

        monkeypatch.setattr(queue_type, "submit", counted_submit)
        monkeypatch.setattr(Readback, "start", counted_map)


@pytest.mark.parametrize("records", ["none", "found"])
@pytest.mark.parametrize("profile", [False, True])
def test_one_submission_and_one_map_per_query(monkeypatch, records, profile):
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    det = pycinder.Detector(records=records, profile=profile)
    poses = np.stack([np.eye(4)] * 40)
    poses[:, 0, 3] = 0.8 * np.arange(40)
    det.find_collisions([ball] * 40, poses)               # warm-up: buffers grow here
    count = _Count(monkeypatch)
    for k in range(3):
        poses[:, 1, 3] = 0.01 * k
        vertices = np.array(ball.vertices) * (1 + 0.01 * k)  # deforming: F0 runs too
        result = det.find_collisions([(vertices, np.array(ball.faces))] * 40, poses)
        assert result.pairs.tolist() == [[i, i + 1] for i in range(39)]
        if records == "none" and not profile:
            # What comes back: the counters and one flag per candidate pair (decided on the
            # GPU, whatever the number of tiles), nothing per tile.
            flags = 4 * (COUNTERS + result.stats.candidates)
            assert result.stats.bytes_read == -(-flags // 16) * 16
            assert result.stats.tiles > result.stats.candidates
    assert (count.submits, count.maps) == (3, 3)


def comb(teeth: int = 6) -> trimesh.Trimesh:
    """One closed body of ``teeth`` thin parallel slabs: rays through it cross many faces."""
    slabs = []
    for k in range(teeth):
        slab = trimesh.creation.box((1.0, 1.0, 0.04))
        slab.apply_translation((0, 0, 0.12 * k))
        slabs.append(slab)
    return trimesh.util.concatenate(slabs)


def test_two_queries_in_flight_answer_as_one_at_a_time():
    """Frame k+1 is submitted (its deformed vertices uploaded) before frame k is read; frame k
    needs retries of undecided tiles, which must still see frame k's vertices."""
    teeth = comb()
    v0, f = np.array(teeth.vertices), np.array(teeth.faces)
    box = trimesh.creation.box((0.3, 0.3, 1.0))
    poses = [np.eye(4), trimesh.transformations.translation_matrix((0.0, 0.0, 0.3))]
    frames = [v0, v0 + [2.0, 0, 0], v0 * [1, 1, 1.5], v0 + [0.6, 0, 0]]
    one_at_a_time = pycinder.Detector(tolerance=0.005, records="all")
    expected = [one_at_a_time.find_collisions([(v, f), box], poses) for v in frames]
    assert [len(r.pairs) for r in expected] == [1, 0, 1, 1]
    assert expected[0].stats.retries > 0              # the comb overflows the crossing lists
    det = pycinder.Detector(tolerance=0.005, records="all")
    pending = [det.submit([(v, f), box], poses) for v in frames[:2]]
    results = [pending[0].result()]
    pending.append(det.submit([(frames[2], f), box], poses))
    pending.append(det.submit([(frames[3], f), box], poses))   # waits for frame 1's GPU work
    results += [p.result() for p in pending[1:]]
    for got, want in zip(results, expected):
        assert got.pairs.tolist() == want.pairs.tolist()
        assert got.stats.retries == want.stats.retries
        # retried tiles' records come from the frame's own vertices
        assert np.array_equal(np.sort(got.records["point"], axis=0),
                              np.sort(want.records["point"], axis=0))
    assert all(p.ready for p in pending)


def comb_of(teeth: int, z0: float, thickness: float = 0.04, pitch: float = 0.12,
            width: float = 3.0
            ) -> trimesh.Trimesh:
    """``comb`` with its teeth from ``z0`` at ``pitch``: rays along z cross 2 faces per tooth."""
    slabs = []
    for k in range(teeth):
        slab = trimesh.creation.box((width, width, thickness))
        slab.apply_translation((0, 0, z0 + pitch * k))
        slabs.append(slab)
    return trimesh.util.concatenate(slabs)


@pytest.mark.parametrize("records", ["none", "found"])
@pytest.mark.parametrize("capacity", [8, 2])
def test_undecided_tiles_are_retried_inside_the_submission(monkeypatch, records, capacity):
    """A comb between the teeth of a wider one: every ray of their tile crosses 24 faces in the
    box, more than a pixel's list holds. The frame retries those tiles with longer lists itself, in its one
    submission; where even those overflow (lists of 2, then 8), the host cuts the boxes. The
    answers are those of exact geometry: teeth 0.02 apart (4 t) are apart, teeth 0.03 deep (6 t)
    collide."""
    from pycinder.focused.frame.frames import FocusedFrames
    from pycinder.testing import ground_truth, surface_distance

    t = 0.005
    base = comb_of(6, 0.0)
    det = pycinder.Detector(tolerance=t, records=records)
    if capacity != 8:
        det.strategy.frames = FocusedFrames(det.gpu, list_capacity=capacity)
    for shift, apart in ((0.06, True), (0.11, False)):
        other = comb_of(6, shift, width=0.3)
        meshes = [base, other]
        if apart:
            assert surface_distance(base, other) > 3.9 * t
        truth = ground_truth(meshes, None, tolerance=t)
        det.find_collisions(meshes)                        # warm-up: buffers grow here
        count = _Count(monkeypatch)
        result = det.find_collisions(meshes)
        assert result.pairs.tolist() == ([] if apart else [[0, 1]])
        assert result.pairs.tolist() == truth.overlap.tolist()
        stats = result.stats
        assert stats.undecided > 0 and stats.possibly_lost == 0
        if not apart:
            if capacity == 8:
                # Found by some sample although others were undecided: nothing to retry.
                assert stats.retries == 0 and (count.submits, count.maps) == (1, 1)
        elif capacity == 8:
            # Lists of 32 decide every pixel: the retry ran inside the frame.
            assert stats.retries == 1 and (count.submits, count.maps) == (1, 1)
            assert stats.tiles == len(result.tiles)
        else:
            # Lists of 8 still overflow: the host cuts the boxes, in frames of their own.
            assert stats.retries > 1 and count.submits > 1
        monkeypatch.undo()


@pytest.mark.parametrize("planner,submissions", [("numpy", 1), ("gpu", 2)])
def test_wgpu_py_calls_per_query_do_not_grow_with_bodies_pairs_or_rounds(planner, submissions):
    """Prepared bodies, new transforms: from 2 bodies to 1,500 (1 pair to over 1,000, 1 tile to
    thousands, one round to several on lavapipe) a query makes the same wgpu-py calls,
    submissions and maps. The frame's compute and render passes are recorded through
    wgpu-native's C functions (pycinder.gpu.native): those grow with the rounds (and the retry
    rounds) only, by at most a fixed number a round."""
    from pycinder.benchmarks import hostcpu

    rng = np.random.default_rng(3)
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    rows = []
    for n in (2, 40, 300, 1500):
        det = pycinder.Detector(planner=planner, broad_phase="numpy")
        bodies = det.prepare([ball] * n)
        poses = np.tile(np.eye(4), (n, 1, 1))
        poses[:, :3, 3] = rng.uniform(0, (n / 0.3) ** (1 / 3), (n, 3))
        poses[1, :3, 3] = poses[0, :3, 3] + 0.9  # at least one pair
        for _ in range(3):  # buffers grow to the scene, and both frame slots are made
            det.find_collisions(bodies, poses)
        with hostcpu.count_wgpu_calls(det.gpu.device) as counts:
            result = det.find_collisions(bodies, poses)
        calls = hostcpu.summarise_calls(counts, 1)
        assert (calls["submissions"], calls["maps"]) == (submissions, submissions)
        st = result.stats
        rows.append((calls["wgpu_calls"] - calls["direct_calls"], calls["direct_calls"],
                     st.rounds + st.retries, st.candidates))
    wgpu_py, direct, rounds, pairs = zip(*rows)
    assert len(set(wgpu_py)) == 1 and wgpu_py[0] <= 8 * submissions, rows
    assert pairs[0] == 1 and pairs[-1] > 1000, rows
    for d, r in zip(direct, rounds):
        assert direct[0] <= d <= direct[0] + 64 * (r - rounds[0]), rows


@pytest.mark.parametrize("planner", ["numpy", "gpu"])
def test_a_query_after_retries_plans_rounds_its_retries_fit(monkeypatch, planner):
    """A pair whose lists overflow, in rounds too large for retry rounds (lists four times
    longer) to fit the memory budget: a query after a larger plan runs its undecided tiles again
    in a frame of its own; the next ones, planned in rounds of the retry's budget
    (again.plan_budget), retry them inside their one frame, with the same answer (exact
    geometry's: apart)."""
    from pycinder.focused.frame.again import RETRY_PLAN_ROUNDS
    from pycinder.focused.frame.atlas import ENTRY_BYTES, LIST_CAPACITY, PIXEL_BYTES, RETRY_LISTS
    from pycinder.testing import ground_truth, surface_distance

    t = 0.001
    meshes = [comb_of(6, 0.0), comb_of(6, 0.06, width=0.3)]
    assert surface_distance(*meshes) > 4 * t
    assert ground_truth(meshes, None, tolerance=t).overlap.tolist() == []
    probe = pycinder.Detector(tolerance=t, records="none", planner=planner)
    probe.find_collisions(meshes)
    plan = probe.strategy.recent_pixels  # the first frame's atlas pixels
    # A budget of 3.2 times the plan: its largest round (6/7 of it here) fits the budget, not a
    # retry round's quarter of it; RETRY_PLAN_ROUNDS quarters hold the plan.
    budget = int(3.2 * plan)
    retry_budget = budget // RETRY_LISTS
    assert plan <= RETRY_PLAN_ROUNDS * retry_budget
    per_pixel = PIXEL_BYTES + ENTRY_BYTES * LIST_CAPACITY
    det = pycinder.Detector(tolerance=t, records="none", planner=planner,
                            memory_budget=budget * per_pixel)
    assert det.strategy.budget_pixels == budget
    planned = 1 if planner == "numpy" else 2  # submissions of a query's plan and frame
    det.find_collisions(meshes)  # warm-up: buffers grow here
    assert det.strategy.recently_retried
    det.strategy.recent_pixels = RETRY_PLAN_ROUNDS * retry_budget + 1  # after a larger plan
    count = _Count(monkeypatch)
    first = det.find_collisions(meshes)
    assert first.pairs.tolist() == [] and first.stats.retries == 1
    assert max(first.tiles.round_rows) * first.tiles.atlas_width > retry_budget
    # a frame of its own (and a read of the tiles' counts to choose its tiles)
    assert count.submits > planned and count.maps > planned
    monkeypatch.undo()
    det.find_collisions(meshes)  # its rounds of the retry's budget: buffers grow here
    count = _Count(monkeypatch)
    again = det.find_collisions(meshes)
    assert again.pairs.tolist() == [] and again.stats.possibly_lost == 0
    assert again.stats.retries == 1 and again.stats.reruns == 0
    assert max(again.tiles.round_rows) * again.tiles.atlas_width <= retry_budget
    assert (count.submits, count.maps) == (planned, planned)  # retried inside the frame
    assert det.strategy.recently_retried


def test_plan_budget_chooses_the_retry_budget_only_where_retries_then_fit():
    """again.plan_budget: the retry rounds' budget after a query that ran tiles again, whose
    plan fills at most RETRY_PLAN_ROUNDS of its rounds and whose bands fit one; else the
    budget (and never with records of every tile)."""
    from pycinder.focused.frame.again import RETRY_PLAN_ROUNDS, plan_budget
    from pycinder.focused.plan.tiles import HEIGHT_CLASSES
    from pycinder.request import record_mode

    none, every = record_mode("none"), record_mode("all")
    retry, budget = 128 * 1024, 4 * 128 * 1024
    fits = RETRY_PLAN_ROUNDS * retry
    assert plan_budget(True, none, fits, 1024, budget, retry) == retry
    assert plan_budget(True, record_mode("found"), 1, 64, budget, retry) == retry
    assert plan_budget(True, none, fits + 1, 1024, budget, retry) == budget  # too many rounds
    assert plan_budget(False, none, fits, 1024, budget, retry) == budget  # nothing ran again
    assert plan_budget(True, every, fits, 1024, budget, retry) == budget  # every tile's records
    wide = retry // HEIGHT_CLASSES[-1] + 1  # a band of that width holds more than a round
    assert plan_budget(True, none, 1, wide, budget, retry) == budget
    assert plan_budget(True, none, 1, wide - 1, budget, retry) == retry


def test_a_query_that_plans_no_tile_leaves_the_last_plans_size():
    """A query whose pairs are all apart (no tile) is no plan to size the next one by."""
    det = pycinder.Detector(records="none")
    det.find_collisions([trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)],
                        np.stack([np.eye(4), np.eye(4)]))
    pixels, width = det.strategy.recent_pixels, det.strategy.recent_width
    assert pixels > 0 and width > 0
    far = np.stack([np.eye(4), np.eye(4)])
    far[1, 0, 3] = 5.0
    result = det.find_collisions([trimesh.creation.box((1, 1, 1)),
                                  trimesh.creation.icosphere(radius=0.4)], far)
    assert result.pairs.tolist() == []
    assert (det.strategy.recent_pixels, det.strategy.recent_width) == (pixels, width)

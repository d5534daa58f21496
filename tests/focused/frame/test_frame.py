"""What one query costs the host in GPU round trips: one submission and one map for records
"none" and "found" (the passes, their timestamps and the readback travel together)."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.gpu.layout import COUNTERS

from conftest import CommandCount


@pytest.mark.parametrize("records", ["none", "found"])
@pytest.mark.parametrize("profile", [False, True])
def test_one_submission_and_one_map_per_query(monkeypatch, records, profile):
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    det = pycinder.Detector(records=records, profile=profile)
    poses = np.stack([np.eye(4)] * 40)
    poses[:, 0, 3] = 0.8 * np.arange(40)
    det.find_collisions([ball] * 40, poses)               # warm-up: buffers grow here
    count = CommandCount(monkeypatch)
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
    box, more than a pixel's list holds. The frame retries those tiles with longer lists itself, in
    its one submission; where even those overflow (lists of 2, then 8), the host cuts the boxes. The
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
        count = CommandCount(monkeypatch)
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


@pytest.mark.parametrize("planner", ["numpy", "gpu"])
def test_a_collision_only_the_retry_round_finds_is_found_inside_the_frame(monkeypatch, planner):
    """Teeth 0.03 deep between the teeth of a wider comb: no sample of the frame's rounds finds
    the pair (every one inside the other body lies at a pixel whose list overflowed), so its
    tiles run again; after a query that ran tiles again, its retry round finds it, in the one
    submission (exact geometry: they collide)."""
    from pycinder.testing import ground_truth

    t = 0.005
    meshes = [comb_of(6, 0.0), comb_of(6, 0.03, width=0.3)]
    assert ground_truth(meshes, None, tolerance=t).overlap.tolist() == [[0, 1]]
    det = pycinder.Detector(tolerance=t, records="none", planner=planner)
    first = det.find_collisions(meshes)  # the host runs the tiles again
    assert first.pairs.tolist() == [[0, 1]] and first.stats.retries == 1
    planned = 1 if planner == "numpy" else 2
    for _ in range(2):  # buffers grow to the retry round in the first
        count = CommandCount(monkeypatch)
        result = det.find_collisions(meshes)
        monkeypatch.undo()
    assert result.pairs.tolist() == [[0, 1]] and result.stats.retries == 1
    assert result.stats.undecided > 0 and result.stats.possibly_lost == 0
    assert (count.submits, count.maps) == (planned, planned)


@pytest.mark.parametrize("planner,submissions", [("numpy", 1), ("gpu", 2)])
def test_wgpu_py_calls_per_query_do_not_grow_with_bodies_pairs_or_rounds(planner, submissions):
    """Prepared bodies, new transforms: from 2 bodies to 1,500 (1 pair to over 1,000, 1 tile to
    thousands, one round to several on lavapipe) a query makes the same wgpu-py calls,
    submissions and maps. The frame's compute and render passes are recorded through
    wgpu-native's C functions (pycinder.gpu.native): those grow with the rounds (and the retry
    rounds) only, by at most a fixed number a round."""
    from benchmarks import hostcpu

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


def _combs_apart_and_deep(pairs: int = 6):
    """``pairs`` combs, each between the teeth of a wider one, 10 apart: every third pair's teeth
    0.03 deep (they collide), the others' 0.02 apart. Rays through their tiles cross 24 faces in
    the box: lists of 8 overflow."""
    base, other = comb_of(6, 0.0), comb_of(6, 0.06, width=0.3)
    meshes, poses = [], []
    for k in range(pairs):
        for mesh in (base, other):
            pose = np.eye(4)
            pose[0, 3] = 10.0 * k
            if mesh is other and k % 3 == 2:
                pose[2, 3] = 0.03
            meshes.append(mesh)
            poses.append(pose)
    return meshes, np.stack(poses)


@pytest.mark.parametrize("planner", ["numpy", "gpu"])
def test_retry_rounds_hold_tiles_of_several_rounds_as_many_as_the_last_query_needed(
        monkeypatch, planner):
    """18 comb pairs whose tiles overflow their lists, in rounds of a small memory budget:
    after a query that ran tiles again, pass F7 lays the undecided tiles of every round out anew
    in retry rounds of a quarter of the budget. One retry round holds too few of them: the rest
    run again on the host, in frames of their own, and the next query has as many retry rounds
    as the layout needed, so that all run again inside its one frame. The answers are exact
    geometry's at every step, and the layout is the rule's (decided in tile order, not by
    atomics), as computed on the host."""
    from pycinder.focused.frame.atlas_buffers import (ENTRY_BYTES, LIST_CAPACITY, PIXEL_BYTES,
                                                      RETRY_LISTS)
    from pycinder.testing import ground_truth

    t = 0.001
    meshes, poses = _combs_apart_and_deep(18)
    truth = ground_truth(meshes, poses, tolerance=t).overlap.tolist()
    assert truth == [[2 * k, 2 * k + 1] for k in range(18) if k % 3 == 2]
    width = 2048
    budget = 4 * 256 * width  # a retry round: 256 rows of the atlas
    per_pixel = PIXEL_BYTES + ENTRY_BYTES * LIST_CAPACITY
    det = pycinder.Detector(tolerance=t, records="found", planner=planner,
                            memory_budget=budget * per_pixel)
    planned = 1 if planner == "numpy" else 2  # submissions of a query's plan and frame
    first = det.find_collisions(meshes, poses)
    assert first.pairs.tolist() == truth and first.stats.retries > 0
    assert first.tiles.atlas_width == width and len(first.tiles.round_rows) >= 2
    undecided_rounds = np.unique(first.tiles.round[np.isin(first.tiles.pair, [0, 1, 3, 4, 6, 7])])
    assert len(undecided_rounds) >= 2  # the apart pairs' tiles lie in several rounds
    assert det.strategy.recently_retried
    needed = det.strategy.retry_rows_needed
    assert needed > budget // RETRY_LISTS // width  # more than one retry round
    det.strategy.retry_rows_needed = 1  # as after a query that needed one retry round
    count = CommandCount(monkeypatch)
    one = det.find_collisions(meshes, poses)
    assert one.pairs.tolist() == truth and one.stats.possibly_lost == 0
    assert one.stats.retries > 1 and count.submits > planned  # the rest on the host
    assert det.strategy.retry_rows_needed >= needed // 2
    monkeypatch.undo()
    det.find_collisions(meshes, poses)  # buffers grow to the retry rounds here
    count = CommandCount(monkeypatch)
    result = det.find_collisions(meshes, poses)
    assert (count.submits, count.maps) == (planned, planned)  # all inside the frame
    monkeypatch.undo()
    assert result.pairs.tolist() == truth and result.stats.possibly_lost == 0
    assert result.stats.retries == 1 and result.stats.reruns == 0 and result.stats.undecided > 0
    _check_retry_layout(det, result, budget // RETRY_LISTS // width)


def _check_retry_layout(det, result, rows):
    """The last frame's tiles as pass F7 left them (every tile it chose laid out, as the
    query's submissions say): each tile it laid out lies in its retry round's ``rows`` rows and
    the atlas's width, no two of a retry round overlap, chosen tiles of several of F7's
    workgroups were laid out, and each lies where the layout's rule puts it, computed here:
    height classes from the tallest, slots as wide as a class's widest tile, tiles in order."""
    from pycinder.focused.plan.plan_numpy import HEIGHT_CLASSES
    from pycinder.gpu.layout import TILE, WORKGROUP

    b, plan = det.strategy.frames.buffers, result.tiles
    n, pairs, width = len(plan), result.stats.candidates, plan.atlas_width
    device = det.gpu.device
    tiles = np.frombuffer(device.queue.read_buffer(b.tiles.buffer, 0, TILE.size * n),
                          TILE.dtype)
    counts = np.frombuffer(device.queue.read_buffer(b.tile_counts.buffer), np.uint32)
    flags = counts[2 * n + pairs: 3 * n + pairs]
    assert flags.any() and flags.max() >= 2  # tiles laid out in more than one retry round
    assert len(np.unique(np.flatnonzero(flags) // WORKGROUP)) >= 2
    for j in range(1, int(flags.max()) + 1):
        used = np.zeros((rows, width), np.int32)
        for x, y, w, h in tiles["window"][flags == j]:
            assert x + w <= width and y + h <= rows
            used[y:y + h, x:x + w] += 1
        assert used.max() == 1
    kept = flags == 0
    assert np.array_equal(tiles["window"][kept], plan.window[kept])  # the others stay put
    classes = np.searchsorted(HEIGHT_CLASSES, plan.window[:, 3])
    row = 0
    for c in reversed(range(len(HEIGHT_CLASSES))):
        chosen = np.flatnonzero(~kept & (classes == c))
        widest = max(int(plan.window[chosen, 2].max()) if len(chosen) else 1, 1)
        per_shelf = width // widest
        for rank, i in enumerate(chosen):
            at = row + rank // per_shelf * HEIGHT_CLASSES[c]
            assert flags[i] == at // rows + 1
            assert tiles["window"][i, :2].tolist() == [rank % per_shelf * widest, at % rows]
        row += -(-len(chosen) // per_shelf) * HEIGHT_CLASSES[c]
    assert det.strategy.retry_rows_needed == row


def test_retry_rounds_are_sized_within_the_budget_and_by_the_last_need():
    """again.retry_on_gpu: rows of a retry round (lists four times longer) within the retry's
    budget, at most the plan's largest round, a multiple of the tallest class (else a power of
    two), at least its tallest tile's class; none without a recent retry or with every tile's
    records. again.retry_rounds: enough for the last need, from 1 to MAX_RETRY_ROUNDS."""
    from pycinder.focused.frame.rerun_policy import MAX_RETRY_ROUNDS, retry_on_gpu, retry_rounds
    from pycinder.focused.plan.plan_numpy import TilePlan
    from pycinder.request import record_mode

    def plan(rows, tallest, width=1024):
        window = np.array([[0, 0, 64, tallest]])
        return TilePlan(pair=np.zeros(1, int), bodies=np.zeros((1, 2), int),
                        axes=np.zeros((1, 3, 3)), origin=np.zeros((1, 3)), pixel=np.ones(1),
                        window=window, slab=np.zeros((1, 2)), flags=np.zeros(1, int),
                        round=np.zeros(1, int), round_rows=rows, atlas_width=width)

    none = record_mode("none")
    assert retry_on_gpu(True, none, plan([1024, 512], 128), 300 * 1024) == 256
    assert retry_on_gpu(True, record_mode("found"), plan([200], 64), 10**9) == 128
    # a small plan: a power of two of its rows, at least its tallest tile's class
    assert retry_on_gpu(True, none, plan([100], 40), 10**9) == 64
    assert retry_on_gpu(True, none, plan([50], 40), 10**9) == 0
    assert retry_on_gpu(True, none, plan([1024], 128), 100 * 1024) == 0  # a band does not fit
    assert retry_on_gpu(False, none, plan([1024], 128), 300 * 1024) == 0
    assert retry_on_gpu(True, record_mode("all"), plan([1024], 128), 300 * 1024) == 0
    assert retry_rounds(0, 256) == 1
    assert retry_rounds(257, 256) == 2
    assert retry_rounds(10**6, 256) == MAX_RETRY_ROUNDS


def test_cull_items_past_what_the_rounds_hold_grow_them_and_the_frame_runs_again(monkeypatch):
    """again.grown_caps: a round (a retry round, whose tiles come from every round) that culled
    more items than the frame's rounds hold makes the frame run again with room for them, or is
    too large past the device's buffers; through a frame whose items were sized too small, the
    answer is still exact geometry's."""
    from pycinder.focused.frame import frames
    from pycinder.focused.frame.rerun_policy import RoundTooLarge, grown_caps
    from pycinder.focused.frame.atlas_buffers import Caps
    from pycinder.gpu.layout import C_MAX_EDGE_ITEMS, C_MAX_FACE_ITEMS, COUNTERS
    from pycinder.testing import ground_truth

    counters = np.zeros(COUNTERS, np.int64)
    counters[C_MAX_FACE_ITEMS], counters[C_MAX_EDGE_ITEMS] = 500, 200
    limits = Caps(items=1000)
    assert grown_caps(counters, Caps(), limits, False, items=300).items == 500
    assert grown_caps(counters, Caps(), limits, False, items=500) is None
    with pytest.raises(RoundTooLarge, match="cull items"):
        grown_caps(counters, Caps(), Caps(items=400), False, items=300)

    state = frames.FocusedFrames._state

    def too_few_items(self, sub):
        s, entries = state(self, sub)
        if sub.reruns == 0:
            s.items = 1
        return s, entries

    monkeypatch.setattr(frames.FocusedFrames, "_state", too_few_items)
    t = 0.005
    meshes = [comb_of(6, 0.0), comb_of(6, 0.03, width=0.3)]
    result = pycinder.Detector(tolerance=t, records="none").find_collisions(meshes)
    assert result.pairs.tolist() == ground_truth(meshes, None, tolerance=t).overlap.tolist()
    assert result.pairs.tolist() == [[0, 1]] and result.stats.reruns > 0

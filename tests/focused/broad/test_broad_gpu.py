"""The GPU broad phase against the NumPy reference (world boxes, sweep and prune, groups filter).

Every pair the reference finds must be found; a pair it does not find is allowed only where the
reference's boxes are within the documented padding of each other (twice the padding of both
boxes, along every axis), and only with equal within keys and different groups.
"""

import numpy as np
import pytest

from pycinder.focused.broad.broad_numpy import sweep_and_prune
from pycinder.scene.bodies import world_boxes
from pycinder.focused.broad import GpuBroadPhase
from pycinder.testing import random_rotation


@pytest.fixture(scope="module")
def bp() -> GpuBroadPhase:
    return GpuBroadPhase()


def reference(lo, hi, r, t, within=None, groups=None):
    wlo, whi = world_boxes(lo, hi, r, t)
    return sweep_and_prune(wlo, whi, within, groups), wlo, whi


def documented_padding(lo, hi, r, t):
    """The padding as the module's doc states it, per body and world axis."""
    trans = t[:, :3, 3]
    origin = 0.5 * (trans.min(axis=0) + trans.max(axis=0))
    reach = np.maximum(np.abs(lo), np.abs(hi)) + r[:, None]
    s = np.abs(trans - origin) + (np.abs(t[:, :3, :3]) * reach[:, None, :]).sum(axis=2)
    return 2.0 ** -19 * s + 2.0 ** -40 * np.abs(origin).max()


def check(bp, lo, hi, r, t, within=None, groups=None):
    """Run both; assert the contract; return (gpu pairs, reference pairs)."""
    got = bp.pairs(lo, hi, r, t, within=within, groups=groups)
    ref, wlo, whi = reference(lo, hi, r, t, within, groups)
    assert got.dtype == np.int64 and got.shape[1:] == (2,)
    assert (got[:, 0] < got[:, 1]).all()
    key = got[:, 0] * len(r) + got[:, 1]
    assert (np.diff(key) > 0).all(), "pairs must be sorted and unique"
    ref_set, got_set = set(map(tuple, ref.tolist())), set(map(tuple, got.tolist()))
    missed = ref_set - got_set
    assert not missed, f"{len(missed)} reference pairs missed, e.g. {sorted(missed)[:5]}"
    extra = np.array(sorted(got_set - ref_set), dtype=np.int64).reshape(-1, 2)
    if len(extra):
        a, b = extra[:, 0], extra[:, 1]
        pad = documented_padding(lo, hi, r, t)
        gap = np.maximum(wlo[b] - whi[a], wlo[a] - whi[b])
        assert (gap <= 2 * (pad[a] + pad[b])).all(), "an extra pair beyond the padding"
        if within is not None:
            assert (within[a] == within[b]).all()
        if groups is not None:
            assert (groups[a] != groups[b]).all()
    return got, ref


def random_bodies(rng, n, scale=1.0, offset=0.0, spread=None, linear="rotate"):
    """Boxes about arbitrary centres (not the origin), their bounding spheres, and transforms."""
    half = rng.uniform(0.05, 1.0, (n, 3)) * scale
    centre = rng.normal(scale=0.3 * scale, size=(n, 3))
    lo, hi = centre - half, centre + half
    r = np.linalg.norm(half, axis=1)
    t = np.tile(np.eye(4), (n, 1, 1))
    for i in range(n):
        m = random_rotation(rng)[:3, :3]
        if linear == "scale":
            m = m @ np.diag(rng.uniform(0.3, 3.0, 3)) @ random_rotation(rng)[:3, :3]
        t[i, :3, :3] = m
    spread = (scale * 3 * n ** (1 / 3)) if spread is None else spread
    t[:, :3, 3] = offset + rng.uniform(0, spread, (n, 3))
    return lo, hi, r, t


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
@pytest.mark.parametrize("offset", [0.0, -1e3, 1e6])
def test_random_boxes_at_scales_and_offsets(bp, scale, offset):
    rng = np.random.default_rng(round(np.log10(scale)) + 3 + 7 * round(np.log10(abs(offset) + 1)))
    lo, hi, r, t = random_bodies(rng, 400, scale, offset)
    got, ref = check(bp, lo, hi, r, t)
    assert len(ref) > 100  # the scene has overlaps to find


def test_rotated_and_scaled_transforms(bp):
    rng = np.random.default_rng(3)
    lo, hi, r, t = random_bodies(rng, 500, linear="scale")
    got, ref = check(bp, lo, hi, r, t)
    assert len(ref) > 100


@pytest.mark.parametrize("offset", [0.0, 1e6])
def test_touching_boxes_are_pairs(bp, offset):
    # A 4 x 4 x 4 grid of unit cubes sharing faces, edges and corners: every two cubes at most one
    # step apart along each axis touch (hand count: pairs at Chebyshev distance 1).
    cells = np.stack(np.meshgrid(*[np.arange(4.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    n = len(cells)
    lo, hi = np.full((n, 3), -0.5), np.full((n, 3), 0.5)
    r = np.full(n, np.sqrt(3) / 2)
    t = np.tile(np.eye(4), (n, 1, 1))
    t[:, :3, 3] = cells + offset
    got, ref = check(bp, lo, hi, r, t)
    i, j = np.triu_indices(n, 1)
    near = np.abs(cells[i] - cells[j]).max(axis=1) == 1
    expected = np.stack([i[near], j[near]], 1)
    assert np.array_equal(got, expected)  # no extra pair: the other gaps are 1


@pytest.mark.parametrize("offset", [0.0, 3e4, 1e6])
def test_rotated_boxes_touching_within_rounding(bp, offset):
    # Each rotated, scaled body gets a unit cube placed against one face of its world box (as
    # the float64 reference computes it), so that about half the pairs touch to the last bit and
    # the rest are apart by a rounding error: float32 boxes without padding lose many of them.
    rng = np.random.default_rng(int(offset) % 97)
    m = 300
    lo, hi, r, t = random_bodies(rng, m, linear="scale", spread=0.0)
    t[:, :3, 3] = offset + 10.0 * np.arange(m)[:, None] * (1, 0.5, 0.25)
    wlo, whi = world_boxes(lo, hi, r, t)
    axis = rng.integers(0, 3, m)
    side = rng.choice([-1.0, 1.0], m)
    cube = np.tile(np.eye(4), (m, 1, 1))
    cube[:, :3, 3] = 0.5 * (wlo + whi)
    face = np.where(side > 0, whi[np.arange(m), axis], wlo[np.arange(m), axis])
    cube[np.arange(m), axis, 3] = face + 0.5 * side
    lo2 = np.concatenate([lo, np.full((m, 3), -0.5)])
    hi2 = np.concatenate([hi, np.full((m, 3), 0.5)])
    r2 = np.concatenate([r, np.full(m, np.sqrt(3) / 2)])
    got, ref = check(bp, lo2, hi2, r2, np.concatenate([t, cube]))
    assert len(ref) > m // 4


def test_nested_and_identical_boxes(bp):
    # Boxes inside one another at one place, and copies of one box at another; apart from those,
    # a box far away. Every nested or identical pair overlaps.
    sizes = np.geomspace(0.01, 10, 20)
    lo = np.concatenate([-sizes[:, None] * np.ones(3), np.full((10, 3), -1.0), [[-1, -1, -1]]])
    hi = -lo
    r = np.linalg.norm(hi, axis=1)
    t = np.tile(np.eye(4), (31, 1, 1))
    t[20:30, :3, 3] = (100, 0, 0)
    t[30, :3, 3] = (0, 100, 0)
    got, ref = check(bp, lo, hi, r, t)
    i, j = np.triu_indices(30, 1)
    same_place = (i < 20) == (j < 20)
    assert np.array_equal(got, np.stack([i[same_place], j[same_place]], 1))


def test_within_and_groups(bp):
    rng = np.random.default_rng(5)
    lo, hi, r, t = random_bodies(rng, 600, spread=8.0)
    within = rng.integers(0, 4, 600)
    groups = rng.integers(0, 3, 600)
    for w, g in ((within, None), (None, groups), (within, groups)):
        got, ref = check(bp, lo, hi, r, t, within=w, groups=g)
        assert len(ref) > 100
    # Keys far apart (not a small range) or large (their bits a float's NaN) keep their meaning.
    plain = bp.pairs(lo, hi, r, t, within=within, groups=groups)
    for w, g in ((within * 2**40 - 7, groups - 2**50), (within * 0x3FE00000, groups * 0x7FC00000)):
        assert np.array_equal(check(bp, lo, hi, r, t, within=w, groups=g)[0], plain)


def test_zero_one_two_bodies(bp):
    unit = (np.array([[-1.0, -1, -1]]), np.array([[1.0, 1, 1]]), np.array([np.sqrt(3)]))
    for n in (0, 1):
        lo, hi, r = (np.repeat(a, n, axis=0) for a in unit)
        assert bp.pairs(lo, hi, r, np.tile(np.eye(4), (n, 1, 1))).shape == (0, 2)
    lo, hi, r = (np.repeat(a, 2, axis=0) for a in unit)
    t = np.tile(np.eye(4), (2, 1, 1))
    t[1, 0, 3] = 2.0  # touching
    assert bp.pairs(lo, hi, r, t).tolist() == [[0, 1]]
    t[1, 0, 3] = 2.1
    assert bp.pairs(lo, hi, r, t).tolist() == []
    t[1, 0, 3] = 0.0
    assert bp.pairs(lo, hi, r, t, groups=np.array([3, 3])).tolist() == []
    assert bp.pairs(lo, hi, r, t, within=np.array([1, 2])).tolist() == []


def test_dense_cluster_grows_the_pair_buffer():
    fresh = GpuBroadPhase()
    n = 400  # every box overlaps every other: 79,800 pairs, more than the first buffer holds
    rng = np.random.default_rng(8)
    _, _, _, t = random_bodies(rng, n, spread=0.1)
    lo, hi, r = np.full((n, 3), -1.0), np.full((n, 3), 1.0), np.full(n, np.sqrt(3))
    got, ref = check(fresh, lo, hi, r, t)
    i, j = np.triu_indices(n, 1)
    assert np.array_equal(got, np.stack([i, j], 1))
    assert fresh.stats.reruns == 1 and fresh.stats.pairs == len(i)
    # The grown buffer is kept: the next call needs one submission and one map.
    check(fresh, lo, hi, r, t)
    assert (fresh.stats.reruns, fresh.stats.submissions, fresh.stats.maps) == (0, 1, 1)


def test_buffers_are_reused(bp):
    rng = np.random.default_rng(11)
    bodies = random_bodies(rng, 1000)
    bp.pairs(*bodies)
    buffers = (bp.buffers.bodies, bp.buffers.elements, bp.buffers.sorted_lo, bp.buffers.pairs)
    generations = [b.generation for b in buffers]
    check(bp, *random_bodies(rng, 700))
    assert [b.generation for b in buffers] == generations


def test_100k_small_bodies_and_a_floor(bp):
    # More boxes than one invocation may loop over on llvmpipe (65535 steps): the floor, kept out
    # of the grid for its width, is tested against all of them by as many threads.
    rng = np.random.default_rng(12)
    n = 100_000
    half = rng.uniform(0.1, 0.5, (n, 3))
    lo, hi, r = -half, half, np.linalg.norm(half, axis=1)
    t = np.tile(np.eye(4), (n + 1, 1, 1))
    t[:n, :3, 3] = rng.uniform(0, 150, (n, 3)) + (1e4, 0, -1e4)
    t[n, :3, 3] = (1e4 + 75, 75, -1e4)  # a floor 160 across, 0.4 deep, at the bottom
    lo = np.concatenate([lo, [[-80, -80, -0.4]]])
    hi = np.concatenate([hi, [[80, 80, 0.0]]])
    r = np.concatenate([r, [np.linalg.norm([80, 80, 0.2])]])
    got, ref = check(bp, lo, hi, r, t)
    assert len(ref) > 1000 and (ref[:, 1] == n).sum() > 100
    assert bp.stats.wide_bodies >= 1 and bp.stats.unfinished == 0


def test_wide_bodies_meet_each_other_within_keys_and_groups(bp):
    # Twenty slabs of different sizes (all kept out of the grid), stacked so that every two meet,
    # among 3000 small boxes; two within keys and two groups.
    rng = np.random.default_rng(15)
    m, k = 20, 3000
    lo, hi, r, t = random_bodies(rng, m + k, scale=0.05, spread=30.0)
    size = np.geomspace(10, 100, m)
    lo[:m] = np.stack([-size, -size, np.full(m, -0.5)], 1)
    hi[:m] = np.stack([size, size, np.full(m, 0.5)], 1)
    r[:m] = np.linalg.norm(hi[:m], axis=1)
    t[:m] = np.eye(4)
    t[:m, :3, 3] = (15, 15, 15)
    within = rng.integers(0, 2, m + k)
    groups = rng.integers(0, 2, m + k)
    for w, g in ((None, None), (within, None), (None, groups), (within, groups)):
        got, ref = check(bp, lo, hi, r, t, within=w, groups=g)
        assert bp.stats.wide_bodies >= m  # and the widest of the small ones, up to 32
    got, _ = check(bp, lo, hi, r, t)
    wide_pairs = got[got[:, 1] < m]
    assert len(wide_pairs) == m * (m - 1) // 2


def test_a_sweep_past_its_budget_is_finished_on_the_host():
    # A rod along the sweep axis through 6000 small boxes in one column of the grid: its sweep
    # meets more boxes than one invocation may loop over, so the host finishes it.
    fresh = GpuBroadPhase()
    rng = np.random.default_rng(16)
    k = 6000
    lo, hi = np.full((k + 1, 3), -0.01), np.full((k + 1, 3), 0.01)
    lo[k, 0], hi[k, 0] = -50, 50
    r = np.linalg.norm(hi - lo, axis=1) / 2
    t = np.tile(np.eye(4), (k + 1, 1, 1))
    t[:k, :3, 3] = rng.uniform(0, 0.02, (k, 3)) * (5000, 1, 1)
    t[k, :3, 3] = (50, 0.01, 0.01)
    got, ref = check(fresh, lo, hi, r, t)
    assert (ref[:, 1] == k).sum() == k  # the rod meets every box
    assert fresh.stats.unfinished >= 1
    assert (fresh.stats.submissions, fresh.stats.maps) == (3, 3)  # + the grown pairs buffer


def test_dense_drifting_spheres(bp):
    # The benchmark's scene: many columns across the sweep axis, pairs across their borders.
    from pycinder.testing.scenes import drifting_spheres

    lo, hi, r, poses = drifting_spheres(10_000, 2)
    for t in poses:
        got, ref = check(bp, lo, hi, r, t)
        assert len(ref) > 10_000


def test_one_large_body_among_small_ones(bp):
    # A floor 100 across under 2000 small boxes, some of them resting on it: the floor is kept
    # out of the grid (and tested against every box), whose cells stay as small as the boxes.
    rng = np.random.default_rng(13)
    lo, hi, r, t = random_bodies(rng, 2001, scale=0.1, spread=50.0)
    lo[0], hi[0] = (-50, -50, -1), (50, 50, 0)
    r[0] = np.linalg.norm(hi[0] - lo[0]) / 2
    t[0] = np.eye(4)
    t[1:, 2, 3] = rng.uniform(-0.05, 2, 2000)
    got, ref = check(bp, lo, hi, r, t)
    assert (ref[:, 0] == 0).sum() > 50
    assert bp.stats.wide_bodies >= 1 and max(bp.stats.cell_size) < 1.0


@pytest.mark.parametrize("bad, words", [
    (lambda a: a["t"].__setitem__((3, 0, 3), np.nan), "transforms of body 3 is not finite"),
    (lambda a: a["r"].__setitem__(2, -1.0), "radius of body 2 is negative"),
    (lambda a: a["lo"].__setitem__((4, 1), 9.0), "local box of body 4 is empty"),
    (lambda a: a["t"].__setitem__((1, 0, 1), 1e20), "transform of body 1 has coordinates beyond"),
    (lambda a: a.__setitem__("lo", a["lo"][:, :2]), "local_lo must have shape (5, 3)"),
    (lambda a: a.__setitem__("w", np.zeros(4, int)), "within must be (5,) integers"),
    (lambda a: a.__setitem__("w", np.zeros(5)), "within must be (5,) integers"),
])
def test_bad_input_is_named(bp, bad, words):
    a = dict(zip(("lo", "hi", "r", "t"), random_bodies(np.random.default_rng(0), 5)), w=None)
    bad(a)
    with pytest.raises(ValueError, match=words.replace("(", r"\(").replace(")", r"\)")):
        bp.pairs(a["lo"], a["hi"], a["r"], a["t"], within=a["w"])


def test_dispatches_over_several_rows_of_workgroups(monkeypatch):
    # Large scenes lay workgroups out in rows of ROW; with a row of 3 workgroups, every pass of a
    # small scene spans several rows, and the last row's extra workgroups must do nothing.
    from pycinder.gpu import layout
    from pycinder.gpu.device import get_gpu, shader_source
    from pycinder.gpu import bindings

    cache = bindings.Stage._cache.setdefault(get_gpu().device, {})

    def forget() -> None:
        shader_source.cache_clear()
        for key in [k for k in cache if k[1].startswith("broad_")]:
            del cache[key]

    monkeypatch.setattr(layout, "ROW", 3)  # the shaders' ROW (the WGSL prelude)
    monkeypatch.setattr(bindings, "ROW", 3)  # the dispatches' (workgroup_grid)
    forget()
    try:
        small_rows = GpuBroadPhase()
        rng = np.random.default_rng(14)
        check(small_rows, *random_bodies(rng, 5000 - 37))  # 16 sort blocks in 18 workgroups
    finally:
        monkeypatch.undo()
        forget()


def test_benchmark_scene_compares_answers_and_reports():
    from benchmarks.broadbench import markdown, run_broadphase

    r = run_broadphase(counts=(500,), frames=2)
    (row,) = r["rows"]
    assert row["missed_pairs"] == 0 and row["pairs"] > 500
    assert row["submissions_maps_reruns"] == [[1, 1, 0]]
    assert "| 500 | 2 |" in "\n".join(markdown(r))


def test_queries_find_their_candidates_on_the_gpu_when_asked(monkeypatch):
    """``broad_phase`` only moves where the candidate pairs are found: a scene's pairs are those
    of exact geometry whichever finds them, and "auto" goes to the GPU from the documented body
    count (lowered here), at the price of one more submission."""
    import pycinder
    import pycinder.request
    from pycinder.testing import ground_truth, random_scene

    from conftest import CommandCount, assert_matches_truth

    meshes, transforms = random_scene(40, 12)
    truth = ground_truth(meshes, transforms)
    groups = np.arange(40) % 3
    answers = {}
    for mode in ("numpy", "gpu"):
        det = pycinder.Detector(broad_phase=mode)
        result = det.find_collisions(meshes, transforms)
        assert_matches_truth(result.pairs, truth, context=mode)
        grouped = det.find_collisions(meshes, transforms, groups=groups)
        assert (groups[grouped.pairs[:, 0]] != groups[grouped.pairs[:, 1]]).all()
        answers[mode] = (result.pairs.tolist(), grouped.pairs.tolist())
        assert (det.strategy._broad is not None) == (mode == "gpu")
        assert result.stats.broad_phase == mode
    assert answers["numpy"] == answers["gpu"]
    monkeypatch.setattr(pycinder.request, "GPU_BROAD_PHASE_BODIES", 40)
    det = pycinder.Detector(records="none")
    det.find_collisions(meshes, transforms)
    count = CommandCount(monkeypatch)
    assert det.find_collisions(meshes, transforms).pairs.tolist() == answers["numpy"][0]
    assert det.strategy._broad is not None and (count.submits, count.maps) == (2, 2)
    with pytest.raises(ValueError, match="broad_phase must be one of"):
        pycinder.Detector(broad_phase="cuda")
    with pytest.raises(ValueError, match="broad_phase applies to strategy='focused'"):
        pycinder.Detector(strategy="scene", broad_phase="gpu")


def test_a_query_on_the_gpu_answers_as_with_numpy_at_the_edges():
    """The GPU broad phase changes nothing a query answers or refuses: its padded near misses
    never reach the tolerance check (a 1e-6 box 0.01 beyond a 1e6 box at tolerance 1e-8), and
    bodies too large for its float32 boxes (1e19 units) go to NumPy under "auto"."""
    import trimesh

    import pycinder
    import pycinder.request

    big, small = trimesh.creation.box((1e6,) * 3), trimesh.creation.box((1e-6,) * 3)
    poses = np.stack([np.eye(4)] * 2)
    poses[1, 0, 3] = 5e5 + 0.01
    for mode in ("numpy", "gpu"):
        result = pycinder.Detector(broad_phase=mode, tolerance=1e-8).find_collisions(
            [big, small], poses)
        assert result.pairs.tolist() == [] and result.stats.candidates == 0
    huge = trimesh.creation.box((1e19,) * 3)
    far = np.stack([np.eye(4)] * 2)
    far[1, 0, 3] = 0.9e19
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pycinder.request, "GPU_BROAD_PHASE_BODIES", 2)
        result = pycinder.Detector().find_collisions([huge, huge], far)
    assert result.pairs.tolist() == [[0, 1]] and result.stats.broad_phase == "numpy"
    with pytest.raises(ValueError, match="too large for the float32 broad phase"):
        pycinder.Detector(broad_phase="gpu").find_collisions([huge, huge], far)


def test_passes_are_numbered_in_order_and_label_their_pipelines(bp):
    from pycinder.focused.broad import PASSES, broad_pass_table

    assert [p.INFO.number for p in PASSES] == [f"B{k}" for k in range(1, 9)]
    assert [type(p) for p in bp.passes] == list(PASSES)
    assert [p.stage.label for p in bp.passes] == [p.INFO.title for p in PASSES]
    table = broad_pass_table()
    assert all(p.INFO.name in table for p in PASSES)


def test_shaders_declare_no_struct_or_shared_constant_the_host_declares():
    """The structs the host writes and the constants it shares are generated from
    ``focused/broad/broad_common.py``: no broad-phase shader spells one out."""
    import re
    from importlib import resources

    from pycinder.focused.broad import b4_sort, broad_common

    names = {"Body", "Params", "SortStep", "Grid", "Counts"} | set(broad_common.CONSTS)
    for f in resources.files("pycinder.shaders").iterdir():
        if f.name.startswith("broad_"):
            text = f.read_text()
            assert not re.search(r"^\s*struct\s", text, re.M), f.name
            declared = set(re.findall(r"^\s*const\s+(\w+)", text, re.M))
            assert not declared & names, (f.name, declared & names)
    assert b4_sort.SORT_STEP.name == "SortStep" and broad_common.BODY.size == 96


def test_the_host_writes_the_body_struct_by_field_name():
    from pycinder.focused.broad.broad_common import BODY, COORDINATE_LIMIT
    from pycinder.focused.broad.broad_gpu_host import packed

    rng = np.random.default_rng(2)
    lo, hi, r, t = random_bodies(rng, 7)
    keys = np.arange(7, dtype=np.uint32)
    bodies, axis, origin = packed(lo, hi, r, t, keys, keys[::-1].copy())
    assert bodies.dtype == BODY.dtype and bodies.shape == (7,)
    assert np.array_equal(bodies["rows"][:, :, :3], t[:, :3, :3].astype(np.float32))
    assert np.array_equal(bodies["rows"][:, :, 3], (t[:, :3, 3] - origin).astype(np.float32))
    assert np.array_equal(bodies["radius"], r.astype(np.float32))
    assert (bodies["within"] == keys).all() and (bodies["group"] == keys[::-1]).all()
    assert COORDINATE_LIMIT > np.abs(bodies["hi"]).max()


def test_const_declarations():
    from pycinder.gpu.bindings import const_declarations

    assert const_declarations({"A": 3, "B": 0.5}) == "const A: u32 = 3u;\nconst B: f32 = 0.5;\n"
    for bad in (-1, 2 ** 32, 0.1, float("inf")):
        with pytest.raises(ValueError):
            const_declarations({"X": bad})

"""Broad phase and tile planning: exact against brute force, and the atlas's invariants."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.focused.broad import broad_numpy
from pycinder.focused.broad.broad_numpy import sweep_and_prune
from pycinder.scene import prepare_scene
from pycinder.testing import random_rotation, random_scene
from pycinder.focused.plan.plan_numpy import (FLAG_SKIP_IF_HIT, MAX_TILE, PROBE, PROBE_FACES,
                                         PROBE_PLAN, likely_pairs, plan_tiles)


def brute(lo, hi):
    n = len(lo)
    return sorted((i, j) for i in range(n) for j in range(i + 1, n)
                  if (lo[i] <= hi[j]).all() and (lo[j] <= hi[i]).all())


@pytest.mark.parametrize("seed", range(4))
def test_sweep_and_prune_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(0, 10, (300, 3))
    hi = lo + rng.uniform(0.01, 1.5, (300, 3))
    hi[:20] = lo[:20] + 1.0
    lo[20:40] = hi[:20]  # exactly touching boxes count
    hi[20:40] = lo[20:40] + 0.5
    assert [tuple(p) for p in sweep_and_prune(lo, hi).tolist()] == brute(lo, hi)
    groups = rng.integers(0, 3, 300)
    assert [tuple(p) for p in sweep_and_prune(lo, hi, groups=groups).tolist()] == \
        [p for p in brute(lo, hi) if groups[p[0]] != groups[p[1]]]


def test_a_pair_list_keeps_its_pairs_whose_boxes_meet_in_its_order():
    """A PairList given for ``within``: its pairs whose boxes overlap (touching ones too), in the
    list's order, and no other pair, at any size (no sweep runs); groups are refused."""
    rng = np.random.default_rng(8)
    lo = rng.uniform(0, 10, (400, 3))
    hi = lo + rng.uniform(0.01, 1.5, (400, 3))
    lo[20:40] = hi[:20]  # exactly touching boxes count
    hi[20:40] = lo[20:40] + 0.5
    every = brute(lo, hi)
    i, j = np.triu_indices(400, 1)
    listed = np.stack([i, j], axis=1)[rng.random(len(i)) < 0.3]
    listed = np.concatenate([listed, np.stack([np.arange(20), np.arange(20, 40)], axis=1)])
    listed = np.unique(listed, axis=0)  # sorted, each once
    got = sweep_and_prune(lo, hi, broad_numpy.PairList(listed))
    meet = set(every)
    assert [tuple(p) for p in got.tolist()] == \
        [tuple(p) for p in listed.tolist() if tuple(p) in meet]
    assert {(a, b) for a, b in zip(range(20), range(20, 40))} <= {tuple(p) for p in got.tolist()}
    assert len(sweep_and_prune(lo[:2], hi[:2], broad_numpy.PairList(np.zeros((0, 2))))) == 0
    with pytest.raises(ValueError, match="groups"):
        sweep_and_prune(lo, hi, broad_numpy.PairList(listed), groups=np.zeros(400))
    with pytest.raises(ValueError, match="shape"):
        broad_numpy.PairList(np.zeros(4))
    for bad in ([[3, 3]], [[4, 2]], [[-1, 2]]):
        with pytest.raises(ValueError, match="0 <= i < j"):
            broad_numpy.PairList(np.array(bad))
    with pytest.raises(ValueError, match="names box 400"):
        sweep_and_prune(lo, hi, broad_numpy.PairList(np.array([[0, 400]])))
    with pytest.raises(ValueError, match="sorted, each once"):
        sweep_and_prune(lo, hi, broad_numpy.PairList(listed[::-1]))
    with pytest.raises(ValueError, match="sorted, each once"):
        sweep_and_prune(lo, hi, broad_numpy.PairList(np.array([[0, 1], [0, 1]])))


@pytest.mark.parametrize("n", [2, 3, 17, broad_numpy.ALL_PAIRS_BELOW - 1,
                               broad_numpy.ALL_PAIRS_BELOW])
def test_few_boxes_are_tested_pair_by_pair_exactly(n):
    """Below ALL_PAIRS_BELOW boxes every pair is tested; the answer is the brute force's, with
    touching boxes, keys (``within``) and groups, as the sweep's."""
    rng = np.random.default_rng(n)
    lo = rng.uniform(0, 3, (n, 3))
    hi = lo + rng.uniform(0.1, 1.5, (n, 3))
    lo[1] = hi[0]  # exactly touching
    within = rng.integers(0, 2, n)
    groups = rng.integers(0, 3, n)
    truth = brute(lo, hi)
    for kw, keep in (({}, lambda p: True),
                     ({"within": within}, lambda p: within[p[0]] == within[p[1]]),
                     ({"groups": groups}, lambda p: groups[p[0]] != groups[p[1]]),
                     ({"within": within, "groups": groups},
                      lambda p: within[p[0]] == within[p[1]] and groups[p[0]] != groups[p[1]])):
        pairs = sweep_and_prune(lo, hi, **kw)
        assert pairs.dtype == np.int64 and pairs.shape[1] == 2
        assert [tuple(p) for p in pairs.tolist()] == [p for p in truth if keep(p)], kw


@pytest.mark.parametrize("seed", range(3))
def test_banded_sweep_matches_brute_force_on_band_edges_and_wide_boxes(seed, monkeypatch):
    """Many boxes are swept band by band across a second axis: every pair is found once,
    with boxes that start, end or touch exactly on the bands' edges, flat and wide boxes (a
    box in every band), keys and groups; the answer is the brute force's whether the bands are
    used or refused (too many copies)."""
    rng = np.random.default_rng(seed)
    n = 400
    lo = rng.uniform(0, 1, (n, 3)) * [12, 6, 3]  # swept along x, in bands across y
    hi = lo + rng.uniform(0.1, 0.8, (n, 3))
    y = 1
    box, band, _, width = broad_numpy._bands(lo[:, y], hi[:, y])
    assert width > 0 and band.max() > 3 and len(box) < broad_numpy.MAX_COPIES * n
    edges = lo[:, y].min() + width * rng.integers(1, int(band.max()), 60)
    lo[:30, y] = edges[:30]                      # starting on an edge
    hi[:30, y] = edges[:30] + 0.3
    lo[30:60, y] = edges[30:] - 0.3
    hi[30:60, y] = edges[30:]                    # ending on one
    lo[60:90] = hi[30:60]                        # touching those exactly
    hi[60:90] = lo[60:90] + 0.2
    hi[90:100, y] = lo[90:100, y]                # flat across
    lo[100:104, y], hi[100:104, y] = -1.0, 8.0   # wide: in every band
    bands = []
    real = broad_numpy._bands
    monkeypatch.setattr(broad_numpy, "_bands",
                        lambda a, b: bands.append(real(a, b)) or bands[-1])
    truth = brute(lo, hi)
    within = rng.integers(0, 3, n)
    groups = rng.integers(0, 2, n)
    for max_copies in (broad_numpy.MAX_COPIES, 1):
        monkeypatch.setattr(broad_numpy, "MAX_COPIES", max_copies)
        bands.clear()
        assert [tuple(p) for p in sweep_and_prune(lo, hi).tolist()] == truth
        assert (bands[0][3] > 0) == (max_copies > 1)
        assert [tuple(p) for p in sweep_and_prune(lo, hi, within, groups).tolist()] == \
            [p for p in truth if within[p[0]] == within[p[1]] and groups[p[0]] != groups[p[1]]]


def test_sweep_in_chunks(monkeypatch):
    rng = np.random.default_rng(9)
    lo = rng.uniform(0, 3, (400, 3))
    hi = lo + 1.0
    whole = sweep_and_prune(lo, hi)
    monkeypatch.setattr(broad_numpy, "CHUNK_PAIRS", 97)
    assert np.array_equal(sweep_and_prune(lo, hi), whole)


def test_sweep_scales_to_100k_bodies():
    rng = np.random.default_rng(1)
    lo = rng.uniform(0, 100, (100_000, 3))
    hi = lo + 0.5
    pairs = sweep_and_prune(lo, hi)
    assert (pairs[:, 0] < pairs[:, 1]).all()
    sample = pairs[rng.choice(len(pairs), 200)]
    assert ((lo[sample[:, 0]] <= hi[sample[:, 1]]) & (lo[sample[:, 1]] <= hi[sample[:, 0]])).all()


def test_world_boxes_hold_every_vertex():
    meshes, transforms = random_scene(30, 4)
    transforms = [t @ np.diag([1.0, 2.0, 0.5, 1.0]) for t in transforms]  # scaled too
    scene = prepare_scene(meshes, transforms)
    lo, hi = scene.world_boxes()
    for i, t in enumerate(transforms):
        # the vertices as the GPU sees them (single precision, relative to the shape's offset,
        # which the scene's transform carries)
        g = scene.transforms[i]
        w = scene.shape_of(i).vertices.astype(np.float64) @ g[:3, :3].T + g[:3, 3]
        assert (w >= lo[i] - 1e-9).all() and (w <= hi[i] + 1e-9).all()
        # the same body as given
        v = np.asarray(meshes[i].vertices) @ t[:3, :3].T + t[:3, 3]
        assert np.allclose(w, v, atol=1e-6)
    # Tight for round bodies: within 1% of the exact box of a sphere, whatever its rotation.
    ball = trimesh.creation.icosphere(subdivisions=4)
    scene = prepare_scene([ball], [random_rotation(np.random.default_rng(3))])
    lo, hi = scene.world_boxes()
    assert np.all(hi - lo <= 2.0 * 1.01)


def assert_tiles_never_overlap(plan):
    """No atlas pixel holds two tiles of one round."""
    for r, rows in enumerate(plan.round_rows):
        sel = np.flatnonzero(plan.round == r)
        grid = np.zeros((rows, plan.atlas_width), dtype=np.int32)
        for x, y, ww, hh in plan.window[sel].tolist():
            grid[y:y + hh, x:x + ww] += 1
        assert grid.max() == 1, f"round {r}: tiles overlap"


@pytest.mark.parametrize("budget", [2**20, 2**24])
def test_atlas_tiles_never_overlap_and_cover_their_windows(budget):
    meshes, transforms = random_scene(80, 8)
    scene = prepare_scene(meshes, transforms)
    lo, hi = scene.world_boxes()
    pairs = sweep_and_prune(lo, hi)
    tol = np.full(len(pairs), 0.004)
    plan = plan_tiles(pairs, tol, scene.local_lo, scene.local_hi, lo, hi, scene.transforms,
                      budget_pixels=budget // 76)
    assert len(plan) and plan.separated >= 0
    w, h = plan.window[:, 2], plan.window[:, 3]
    assert (w <= MAX_TILE[0]).all() and (h <= MAX_TILE[1]).all() and (w > 0).all()
    assert_tiles_never_overlap(plan)
    # Axes are orthonormal and right-handed; pixels are the tolerance.
    gram = plan.axes @ np.transpose(plan.axes, (0, 2, 1))
    assert np.allclose(gram, np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(plan.axes), 1.0)
    assert np.allclose(plan.pixel, 0.004)
    # The probes come first: the pieces after them are skipped once their pair is found.
    probes = plan.flags & FLAG_SKIP_IF_HIT == 0
    assert probes.any() and (~probes).any()
    assert (w[probes] <= PROBE[0]).all() and (h[probes] <= PROBE[1]).all()
    assert not (probes[1:] & ~probes[:-1]).any(), "a probe comes after a skippable piece"
    assert plan.round[probes].max() <= plan.round[~probes].min()


def test_lead_pairs_come_first_with_the_same_windows():
    """Pairs planned first (a query that stops at its first pair) get rounds of their own before
    every other tile; each pair keeps the pixels it had, and tiles of one round never overlap."""
    meshes, transforms = random_scene(80, 8)
    scene = prepare_scene(meshes, transforms)
    lo, hi = scene.world_boxes()
    pairs = sweep_and_prune(lo, hi)
    tol = np.full(len(pairs), 0.004)
    args = (pairs, tol, scene.local_lo, scene.local_hi, lo, hi, scene.transforms)
    lead = likely_pairs(lo, hi, pairs, 10)
    faces = scene.face_counts  # whether a pair is probed must not depend on the split
    plain = plan_tiles(*args, budget_pixels=2**20, faces=faces)
    led = plan_tiles(*args, budget_pixels=2**20, faces=faces, lead=lead)
    first = np.isin(led.pair, lead)
    assert first.any() and (~first).any()
    assert led.round[first].max() < led.round[~first].min()
    for plan in (plain, led):
        assert_tiles_never_overlap(plan)
    pixels = {}
    for plan in (plain, led):
        per_pair = np.bincount(plan.pair, weights=plan.window[:, 2] * plan.window[:, 3],
                               minlength=len(pairs))
        pixels[id(plan)] = per_pair
    assert np.array_equal(pixels[id(plain)], pixels[id(led)]) and led.separated == plain.separated


def test_likely_pairs_are_the_deepest_box_overlaps():
    lo = np.array([[0, 0, 0], [0.9, 0, 0], [0.2, 0, 0], [0.5, 0.5, 0.5], [5, 5, 5]], float)
    hi = lo + 1.0
    pairs = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [3, 4]])
    # shares of the smaller box: 0.1, 0.8, 0.125, 0.3, 0
    assert sorted(likely_pairs(lo, hi, pairs, 2).tolist()) == [1, 3]
    assert sorted(likely_pairs(lo, hi, pairs, 9).tolist()) == [0, 1, 2, 3, 4]
    flat = hi.copy()
    flat[:, 2] = lo[:, 2]  # boxes of no volume score nothing, without dividing by zero
    assert len(likely_pairs(lo, flat, pairs, 2)) == 2


def test_apart_oriented_boxes_need_no_tile():
    """A rod along x and a longer one at 45 degrees beside its end: their world boxes overlap,
    their own boxes do not, so the separating-axis test of the planner drops the pair."""
    short, long_ = trimesh.creation.box((2.0, 0.1, 0.1)), trimesh.creation.box((4.0, 0.1, 0.1))
    turn = trimesh.transformations.rotation_matrix(np.radians(45), (0, 0, 1))
    turn[:3, 3] = (-0.707, 0.707, 0.0)
    result = pycinder.Detector().find_collisions([short, long_], [np.eye(4), turn])
    assert result.stats.candidates == 1 and result.stats.separated == 1
    assert result.stats.tiles == 0 and result.pairs.tolist() == []


def test_only_large_windows_of_large_plans_are_probed():
    """A probe costs a second round of passes: a box resting on a ball is tested in one round;
    the same pair overlapping deeply at a fine tolerance gets its probe first, and so does a
    small window of dense meshes (the probe spares the rest of the window's faces)."""
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.4)

    def plan_for(gap: float, tolerance: float, faces=(12, 320)):
        poses = np.stack([np.eye(4)] * 2)
        poses[1, 2, 3] = 0.9 + gap
        scene = prepare_scene([box, ball], poses)
        assert scene.face_counts.tolist() == [12, 320]
        lo, hi = scene.world_boxes()
        pairs = sweep_and_prune(lo, hi)
        return plan_tiles(pairs, np.full(len(pairs), tolerance), scene.local_lo,
                          scene.local_hi, lo, hi, scene.transforms, budget_pixels=2**22,
                          faces=np.array(faces))

    touching = plan_for(0.0, 0.01)
    assert touching.pixels < PROBE_PLAN and len(touching.round_rows) == 1
    assert not (touching.flags & FLAG_SKIP_IF_HIT).any()
    assert (touching.window[:, 2] > PROBE[0]).any()          # a window a probe could have cut
    dense = plan_for(0.0, 0.01, faces=(PROBE_FACES, PROBE_FACES))
    assert len(dense.round_rows) == 2 and (dense.flags & FLAG_SKIP_IF_HIT).any()
    deep = plan_for(-0.4, 0.002)
    assert deep.pixels > PROBE_PLAN and len(deep.round_rows) == 2
    first = deep.round == 0
    assert (deep.window[first, 2] <= PROBE[0]).all() and (deep.window[first, 3] <= PROBE[1]).all()
    assert (deep.flags[~first] & FLAG_SKIP_IF_HIT).all()


def test_sum3_and_det3_are_numpys_bits():
    """World boxes and frames lean on sums along axes of 3 written out (``sum3``): the same
    bits as NumPy's reductions (which the stored answers were made with), strided views
    included; ``det3``'s signs are LU's away from singular matrices."""
    from pycinder.util.arrays import det3, sum3

    rng = np.random.default_rng(2)
    x = rng.normal(size=(20000, 3, 3)) * 10.0 ** rng.integers(-5, 6, (20000, 1, 1))
    assert np.array_equal(sum3(x), x.sum(axis=-1))
    assert np.array_equal(np.sqrt(sum3(x * x)), np.linalg.norm(x, axis=-1))
    view = x[:, :, ::-1][::2]
    assert np.array_equal(sum3(view), view.sum(axis=-1))
    assert np.array_equal(det3(x) < 0, np.linalg.det(x) < 0)

"""Dense meshes: hard clashes and clearance measured over the face clusters that meet only.

Pass H1 measures a dense pair over the pairs of face clusters whose projections meet along
each line (:mod:`pycinder.focused.measure.h1_items`), pass C1 over the cluster pairs that can be
nearer than the least distance found
(:meth:`~pycinder.focused.measure.c1_distance.Distance.nearest`). Both must give exactly the figures
of every cluster pair: checked here bit for bit on random dense pairs (spheres, tori, bumpy
non-convex spheres and dense boxes; overlapping, grazing and apart; turned, at scales from 1e-3 to
1e3 and far from the origin), and the answers against exact geometry: the separating axes of two
boxes (analytic, as dense meshes), coal's EPA for two convex spheres, python-fcl's distances for
clearance.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.focused.modes import clearance as clearance_mode
from pycinder.focused.measure import c1_distance
from pycinder.focused.modes import hardclash
from pycinder.focused.measure.h1_depth import ITEM_SKIP_SHIFT, LINES, decode
from pycinder.result import Stats
from pycinder.testing import coal_depth, random_rotation, surface_distance

SCALES = [1e-3, 1.0, 1e3]


def sphere(radius: float = 1.0, subdivisions: int = 3) -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def torus() -> trimesh.Trimesh:
    return trimesh.creation.torus(major_radius=0.8, minor_radius=0.3, major_sections=48,
                                  minor_sections=24)


def bumpy(seed: int) -> trimesh.Trimesh:
    """A sphere with bumps and dents: closed, not convex."""
    m = sphere(0.9, 3)
    rng = np.random.default_rng(seed)
    v = np.asarray(m.vertices, np.float64)
    centres = rng.normal(size=(6, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    gain = 1 + 0.25 * np.sum(np.sign(rng.normal(size=6))
                             * np.exp(-((v[:, None] / 0.9 - centres) ** 2).sum(2) * 8), axis=1)
    return trimesh.Trimesh(v * gain[:, None], m.faces, process=False)


def dense_box(extent) -> trimesh.Trimesh:
    """A box as a dense mesh (768 faces): exactly a box."""
    m = trimesh.creation.box(extent)
    for _ in range(3):
        m = m.subdivide()
    return m


def place(rng: np.random.Generator, scale: float, far: bool) -> list[np.ndarray]:
    """Two transforms: turned at random, b about one unit from a along a random direction
    (overlapping, grazing or apart for unit bodies), both far from the origin when ``far``."""
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    shift = (rng.uniform(-1, 1, 3) * 5e3 if far else np.zeros(3)) * scale
    out = []
    for k in range(2):
        t = random_rotation(rng)
        t[:3, 3] = shift + k * rng.uniform(0.6, 1.9) * scale * direction
        out.append(t)
    return out


def internals(det: pycinder.Detector, meshes: list, transforms: list):
    """The detector's scene, its shapes packed and uploaded, and its strategy."""
    scene = det._scene(meshes, np.asarray(transforms, np.float64), None)
    pack = det.strategy.pack(scene, Stats())
    return scene, pack, det.strategy


def depth_figures(det, meshes, transforms, cull: bool, rounds: bool = True) -> np.ndarray:
    """Pass H1's figures (K, LINES, 2) of every pair of the scene, culled or not; without
    ``rounds``, every line in one dispatch (no pair stops early)."""
    scene, pack, strategy = internals(det, meshes, transforms)
    n = len(meshes)
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)])
    items, frames, _ = hardclash.plan(scene, pack, pairs, cull=cull)
    buffers = strategy.frames.buffers
    depth = strategy._hard_clashes().depth
    if not rounds:
        words = depth.words(buffers.positions, buffers.faces, items, frames)
        return decode(words[:, :2 * LINES]).reshape(-1, LINES, 2)
    return depth.run(buffers.positions, buffers.faces, items, frames)


def assert_same_figures(culled: np.ndarray, every: np.ndarray) -> None:
    """Culled figures are every cluster pair's, line by line, bit for bit, up to the first line
    that clears the pair (no ray meets both bodies along it, or one way along it leaves them
    apart: as a whole item, the pair may stop there, its later lines being those of no ray);
    the pair's depth and direction are the same."""
    for k in range(len(every)):
        cleared = False
        for i in range(LINES):
            if cleared:
                assert np.all(culled[k, i] == -np.inf) or np.array_equal(culled[k, i],
                                                                         every[k, i])
            else:
                assert np.array_equal(culled[k, i], every[k, i]), (k, i, culled[k, i],
                                                                   every[k, i])
            cleared = cleared or bool(np.all(every[k, i] == -np.inf) or np.any(every[k, i] <= 0))
    flat_c = np.maximum(culled.reshape(len(culled), -1), 0)
    flat_e = np.maximum(every.reshape(len(every), -1), 0)
    assert np.array_equal(flat_c.min(axis=1), flat_e.min(axis=1))
    assert np.array_equal(flat_c.argmin(axis=1), flat_e.argmin(axis=1))


SHAPES = {"sphere": lambda rng: sphere(), "torus": lambda rng: torus(),
          "bumpy": lambda rng: bumpy(int(rng.integers(1000))),
          "box": lambda rng: dense_box(rng.uniform(0.6, 1.4, 3))}


@pytest.mark.parametrize("scale", SCALES)
def test_culled_depth_figures_are_every_cluster_pairs(scale):
    """Random dense pairs of every kind of shape: the figures over the cluster pairs that meet
    are those over every cluster pair, bit for bit."""
    rng = np.random.default_rng(int(scale * 1000) % 97 + 3)
    det = pycinder.Detector(min_depth=0.01 * scale)
    kinds = list(SHAPES)
    for trial in range(4):
        meshes = []
        for kind in (kinds[trial], kinds[(trial + 1 + int(rng.integers(3))) % 4]):
            m = SHAPES[kind](rng)
            m.apply_scale(scale)
            meshes.append(m)
        transforms = place(rng, scale, far=trial % 2 == 1)
        culled = depth_figures(det, meshes, transforms, cull=True)
        every = depth_figures(det, meshes, transforms, cull=False)
        assert_same_figures(culled, every)


def test_culling_measures_a_small_share_of_the_cluster_pairs():
    """Two overlapping dense spheres (20,480 faces each): the lines measured over all cluster
    pairs are a small share (4% here) of every cluster pair along every line."""
    det = pycinder.Detector(min_depth=0.01)
    t = [np.eye(4), np.eye(4)]
    t[1][:3, 3] = (0.7, 0.3, 0.2)
    meshes = [sphere(1.0, 5), sphere(1.0, 5)]
    scene, pack, _ = internals(det, meshes, t)
    items, _, _ = hardclash.plan(scene, pack, np.array([[0, 1]]))
    skipped = (items["whole"].astype(np.int64) >> ITEM_SKIP_SHIFT) & ((1 << LINES) - 1)
    measured = LINES * len(items) - sum(int(s).bit_count() for s in skipped)
    clusters = np.diff(pack.cluster_start)
    a, b = scene.body_shape
    assert measured < 0.06 * LINES * clusters[a] * clusters[b], measured


def test_a_dense_pair_cleared_along_a_line_stops_there():
    """Two dense spheres side by side, apart along y: a's y axis (its second line) has no ray
    meeting both, so no later line is measured; their depth is 0 either way."""
    det = pycinder.Detector(min_depth=0.01)
    t = [np.eye(4), np.eye(4)]
    t[1][:3, 3] = (0.3, 2.05, 0.0)
    meshes = [sphere(), sphere()]
    culled = depth_figures(det, meshes, t, cull=True)
    every = depth_figures(det, meshes, t, cull=False)
    assert_same_figures(culled, every)
    assert np.all(culled[0, 1] == -np.inf) and np.all(culled[0, 2:] == -np.inf)
    assert det.find_collisions(meshes, t).pairs.tolist() == []


def test_a_dense_pair_cleared_one_way_stops_after_the_bodies_axes():
    """Two dense spheres 0.01 apart, b mostly along a's x axis: a's x axis leaves them apart
    one way, so the world's lines are not measured (the bodies' axes are, in one round); those
    measured are every line's, in one dispatch."""
    det = pycinder.Detector(min_depth=0.01)
    t = [np.eye(4), np.eye(4)]
    t[1][:3, 3] = 2.01 * np.array([1.0, 0.3, 0.2]) / np.linalg.norm([1.0, 0.3, 0.2])
    meshes = [sphere(), sphere()]
    culled = depth_figures(det, meshes, t, cull=True)
    every = depth_figures(det, meshes, t, cull=False, rounds=False)
    assert np.isfinite(every[0, 6:]).any()
    assert culled[0, 0, 1] < 0 < culled[0, 0, 0]
    assert np.array_equal(culled[0, :6], every[0, :6])
    assert np.all(culled[0, 6:] == -np.inf)
    assert_same_figures(culled, every)


# -- Against exact geometry ---------------------------------------------------------------------

def box_depth(extent_a, ta, extent_b, tb) -> float:
    """Exact penetration depth of two boxes (separating axes: both boxes' face normals and the
    cross products of their edges), 0 when apart or touching."""
    axes_a, axes_b = ta[:3, :3].T, tb[:3, :3].T
    candidates = list(axes_a) + list(axes_b)
    for u in axes_a:
        for v in axes_b:
            w = np.cross(u, v)
            if np.linalg.norm(w) > 1e-9:
                candidates.append(w / np.linalg.norm(w))
    best = np.inf
    for n in candidates:
        ra = 0.5 * np.sum(np.abs(ta[:3, :3].T @ n) * extent_a)
        rb = 0.5 * np.sum(np.abs(tb[:3, :3].T @ n) * extent_b)
        best = min(best, ra + rb - abs(np.dot(tb[:3, 3] - ta[:3, 3], n)))
    return max(best, 0.0)


@pytest.mark.parametrize("scale", SCALES)
def test_dense_boxes_against_separating_axes(scale):
    """Dense turned boxes at random depths: reported exactly when deeper than d, never when at
    most d / 2 deep, each depth an upper bound within its error of the exact one."""
    rng = np.random.default_rng(17)
    d = 0.05 * scale
    det = pycinder.Detector(min_depth=d)
    for trial in range(6):
        extents = [rng.uniform(0.6, 1.4, 3) * scale for _ in range(2)]
        meshes = [dense_box(e) for e in extents]
        transforms = place(rng, scale, far=trial % 2 == 1)
        exact = box_depth(extents[0], transforms[0], extents[1], transforms[1])
        result = det.find_collisions(meshes, transforms)
        reported = result.pairs.tolist() == [[0, 1]]
        if exact > d:
            assert reported, (trial, exact)
        if exact <= d / 2:
            assert not reported, (trial, exact, result.depths)
        if reported:
            got, error = float(result.depths[0]), float(result.depth_errors[0])
            rounding = hardclash.ERROR_SCALE * 8 * scale
            assert exact <= got + rounding
            assert got - error - rounding <= exact


def test_dense_spheres_against_coal():
    """Two turned dense spheres (convex) pressed together at depths around d: coal's EPA depth
    lies within each reported depth's bound."""
    pytest.importorskip("coal", reason="coal's EPA is the truth for dense convex pairs")
    rng = np.random.default_rng(5)
    d = 0.02
    det = pycinder.Detector(min_depth=d)
    mesh = sphere(0.5, 4)

    for target in (0.0, 0.3 * d, 1.5 * d, 0.3):
        ta, tb = random_rotation(rng), random_rotation(rng)
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        tb[:3, 3] = direction * (1.0 - target)
        exact = coal_depth(mesh, ta, mesh, tb)
        result = det.find_collisions([mesh, mesh], [ta, tb])
        reported = result.pairs.tolist() == [[0, 1]]
        assert reported or exact <= d, (target, exact)
        assert not reported or exact > d / 2, (target, exact, result.depths)
        if reported:
            got, error = float(result.depths[0]), float(result.depth_errors[0])
            assert got - error - 1e-6 <= exact <= got + 1e-6, (got, error, exact)


@pytest.mark.parametrize("first", [(1,), None])
@pytest.mark.parametrize("scale", SCALES)
def test_dense_clearance_is_every_cluster_pairs_and_exact(scale, first, monkeypatch):
    """Clearance over dense pairs (crossing, near and apart): the least distance over the
    cluster pairs that can be nearer is that over every cluster pair within c, bit for bit, and
    within its bound of python-fcl's exact distance (``first``: the cluster pairs measured
    measured in the rounds before the last, the others only where they can be nearer)."""
    pytest.importorskip("fcl", reason="exact distances come from python-fcl")
    if first is not None:
        monkeypatch.setattr(c1_distance, "ROUNDS", first)
    rng = np.random.default_rng(int(scale * 1000) % 89 + 1)
    c = 0.1 * scale
    kinds = list(SHAPES)
    for trial in range(4):
        meshes = []
        for kind in (kinds[trial], kinds[(trial + 2) % 4]):
            m = SHAPES[kind](rng)
            m.apply_scale(scale)
            meshes.append(m)
        transforms = place(rng, scale, far=trial % 2 == 0)
        got = pycinder.Detector(clearance=c).find_collisions(meshes, transforms)
        with monkeypatch.context() as patched:
            # Every cluster pair within c, measured in one pass.
            patched.setattr(clearance_mode.Distance, "nearest",
                            lambda self, positions, faces, items, frames, *_:
                            self.run(positions, faces, items, frames))
            every = pycinder.Detector(clearance=c).find_collisions(meshes, transforms)
        assert got.pairs.tolist() == every.pairs.tolist()
        assert np.array_equal(got.distances, every.distances)
        exact = max(surface_distance(meshes[0], meshes[1], transforms), 0.0)
        if exact < c:
            assert got.pairs.tolist() == [[0, 1]]
        if got.pairs.tolist():
            assert abs(got.distances[0] - exact) <= got.distance_errors[0] + 1e-12 * scale


def test_regions_skip_the_lines_their_chunks_do_not_meet_along(monkeypatch):
    """A dense non-convex pair measured locally, in regions (their faces cut to the overlap's
    box, packed in chunks): the same depths with the regions' chunk pairs culled and not."""
    meshes = [torus(), sphere(0.5, 4)]
    transforms = [np.eye(4), np.eye(4)]
    transforms[1][:3, 3] = (0.8, 0.1, 0.05)
    det = pycinder.Detector(min_depth=0.01)
    culled = det.find_collisions(meshes, transforms)
    mirrored = [np.diag([1.0, -1.0, 1.0, 1.0]), transforms[1]]  # the chunks' maps mirror
    culled_mirrored = det.find_collisions(meshes, mirrored)
    monkeypatch.setattr(hardclash, "skip_lines",
                        lambda positions, faces, items, frames, closed=None: items)
    every = pycinder.Detector(min_depth=0.01).find_collisions(meshes, transforms)
    assert culled.pairs.tolist() == every.pairs.tolist() == [[0, 1]]
    assert np.array_equal(culled.depths, every.depths)
    assert np.array_equal(culled.depth_errors, every.depth_errors)
    every = pycinder.Detector(min_depth=0.01).find_collisions(meshes, mirrored)
    assert culled_mirrored.pairs.tolist() == every.pairs.tolist() == [[0, 1]]
    assert np.array_equal(culled_mirrored.depths, every.depths)


def test_culled_figures_of_mirrored_and_inside_out_bodies():
    """Cluster pairs are also left out along a line where both clusters face the same way (a
    ray enters a and leaves b elsewhere): with a transform that mirrors a body, and with a body
    wound inside out, faces are still taken as facing out, and the culled figures are every
    cluster pair's, bit for bit."""
    rng = np.random.default_rng(11)
    det = pycinder.Detector(min_depth=0.01)
    mirror = np.diag([1.0, -1.0, 1.0, 1.0])
    inside_out = sphere().copy()
    inside_out.invert()
    deep = [np.eye(4), np.eye(4)]
    deep[1][:3, 3] = (0.5, 0.3, 0.2)  # two unit spheres overlapping deeply
    for trial in range(6):
        meshes = [sphere(), torus()] if trial < 3 else [sphere(), sphere()]
        transforms = place(rng, 1.0, far=trial == 2) if trial < 3 else [t.copy() for t in deep]
        if trial in (0, 2, 3):
            transforms[0] = transforms[0] @ mirror
        if trial in (1, 2, 4):
            transforms[1] = transforms[1] @ mirror
        if trial in (4, 5):
            meshes[1] = inside_out
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the inside-out torus is warned about
            culled = depth_figures(det, meshes, transforms, cull=True)
            every = depth_figures(det, meshes, transforms, cull=False)
        assert_same_figures(culled, every)


def test_the_dense_benchmark_runs_and_is_right():
    """The benchmark's cases at a small size: every answer keeps its contract."""
    pytest.importorskip("coal", reason="the benchmark's depths come from coal")
    pytest.importorskip("fcl", reason="the benchmark's distances come from python-fcl")
    from benchmarks import dense

    results = dense.run(faces=320, repeat=1)
    assert {row["right"] for row in results["rows"]} <= {"yes", "yes (reported)"}
    assert len(dense.markdown(results)) == 4 + len(results["rows"])


@pytest.mark.parametrize("turned", [False, True])
def test_rounds_give_every_lines_figures_where_no_line_clears(turned):
    """Two overlapping dense spheres, as placed (the bodies' axes are the world's, whose
    figures they give) and turned: measured in rounds and culled, every line's figures are
    those of every cluster pair along every line in one dispatch."""
    det = pycinder.Detector(min_depth=0.01)
    rng = np.random.default_rng(8)
    t = [random_rotation(rng) if turned else np.eye(4) for _ in range(2)]
    t[1][:3, 3] = (0.7, 0.3, 0.2)
    meshes = [sphere(), sphere(1.0, 2)]
    culled = depth_figures(det, meshes, t, cull=True)
    every = depth_figures(det, meshes, t, cull=False, rounds=False)
    assert np.all(every > 0)
    assert np.array_equal(culled, every)


def test_dense_boxes_as_placed_against_separating_axes():
    """Dense boxes that are not turned (the bodies' axes are the world's) at depths around d:
    the contract against the exact depth."""
    d = 0.05
    det = pycinder.Detector(min_depth=d)
    for overlap in (-0.01, 0.02, 0.04, 0.06, 0.3):
        extents = [np.array([1.0, 0.8, 0.6]), np.array([0.5, 0.7, 0.9])]
        t = [np.eye(4), np.eye(4)]
        t[1][:3, 3] = (0.75 - overlap, 0.1, -0.05)
        exact = box_depth(extents[0], t[0], extents[1], t[1])
        assert exact == pytest.approx(max(overlap, 0.0))
        result = det.find_collisions([dense_box(e) for e in extents], t)
        assert (result.pairs.tolist() == [[0, 1]]) == (exact > d), overlap
        if exact > d:
            got, error = float(result.depths[0]), float(result.depth_errors[0])
            assert got - error - 1e-6 <= exact <= got + 1e-6

"""``Detector.in_collision``: whether anything collides, with the GPU stopping at the first pair it
finds, scored against exact geometry (``pycinder.testing.ground_truth``): True whenever a pair
penetrates by two tolerances, False whenever every pair is a tolerance apart."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing import ground_truth, random_rotation

TOL = 0.01


def scene_with_a_pair(offset: float, scale: float, rng: np.random.Generator):
    """Ten bodies far apart at random orientations, and a unit box at the origin with a ball of
    radius 0.3 on its +x face, ``offset`` from touching it (negative: that deep), all scaled."""
    meshes, transforms = [], []
    for k in range(10):
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.3) if k % 2 \
            else trimesh.creation.box((0.5, 0.5, 0.5))
        t = random_rotation(rng)
        t[:3, 3] = (3.0 * np.cos(0.6 * k), 3.0 * np.sin(0.6 * k), 2.0 + 0.1 * k)
        meshes.append(mesh)
        transforms.append(t)
    ball = np.eye(4)
    ball[0, 3] = 0.5 + 0.3 + offset
    meshes += [trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(subdivisions=4,
                                                                           radius=0.3)]
    transforms += [np.eye(4), ball]
    meshes = [m.copy().apply_scale(scale) for m in meshes]
    transforms = np.array(transforms)
    transforms[:, :3, 3] *= scale
    return meshes, transforms


def nested_and_nonconvex():
    """A ball wholly inside a box (no surface crosses), and a torus whose hole holds a rod that
    does not touch it."""
    box = trimesh.creation.box((2, 2, 2))
    inner = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.25)
    rod = trimesh.creation.cylinder(radius=0.3, height=3.0)
    t_torus = np.eye(4)
    t_torus[:3, 3] = (10, 0, 0)
    t_rod = t_torus.copy()
    return [box, inner, torus, rod], np.array([np.eye(4), np.eye(4), t_torus, t_rod])


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_answers_follow_the_exact_geometry(scale):
    rng = np.random.default_rng(7)
    det = pycinder.Detector(tolerance=TOL * scale)
    for offset, expected in ((1.5 * TOL, False), (-2.5 * TOL, True)):
        meshes, transforms = scene_with_a_pair(offset, scale, rng)
        truth = ground_truth(meshes, list(transforms), tolerance=TOL * scale)
        assert len(truth.ambiguous) == 0
        assert truth.overlap.tolist() == ([[10, 11]] if expected else [])
        assert det.in_collision(meshes, transforms) is expected, (offset, scale)
        # The pair within one group is no pair.
        groups = np.arange(12)
        groups[11] = groups[10]
        assert det.in_collision(meshes, transforms, groups=groups) is False


def test_nested_solids_and_a_rod_through_a_hole():
    meshes, transforms = nested_and_nonconvex()
    truth = ground_truth(meshes, list(transforms), tolerance=TOL)
    assert truth.overlap.tolist() == [[0, 1]]  # the ball inside the box; the rod clears
    det = pycinder.Detector(tolerance=TOL)
    assert det.in_collision(meshes, transforms) is True
    assert det.in_collision(meshes[2:], transforms[2:]) is False


def test_the_gpu_stops_at_the_first_pair():
    """A dense scene where many pairs collide: the stopping query tests fewer samples than the
    whole query, and still answers True; a manager's yes/no calls use it."""
    rng = np.random.default_rng(3)
    meshes = [trimesh.creation.icosphere(subdivisions=2, radius=0.5) for _ in range(40)]
    transforms = np.tile(np.eye(4), (40, 1, 1))
    transforms[:, :3, 3] = rng.uniform(0, 3, (40, 3))
    det = pycinder.Detector(tolerance=TOL, records="none")
    whole = det.find_collisions(meshes, transforms)
    truth = ground_truth(meshes, list(transforms), tolerance=TOL)
    assert len(truth.overlap) > 20 and truth.score(whole.pairs)["recall"] == 1.0
    stopped = det._pending(meshes, transforms, None, None, None, "none",
                           stop_at_first=True).result()
    # Pass F4 found some pairs; pass F5, which runs after it, then tested no edge at all.
    assert len(stopped.pairs) >= 1
    assert {tuple(p) for p in stopped.pairs.tolist()} <= {tuple(p) for p in whole.pairs.tolist()}
    assert whole.stats.samples > 0 and stopped.stats.samples < whole.stats.samples
    assert det.in_collision(meshes, transforms) is True
    manager = pycinder.CollisionManager(tolerance=TOL)
    for k, (mesh, t) in enumerate(zip(meshes, transforms)):
        manager.add_object(f"b{k}", mesh, t)
    assert manager.in_collision_internal() is True
    assert manager.in_collision_single(meshes[0], transforms[0]) is True
    far = np.eye(4)
    far[:3, 3] = (20, 0, 0)
    assert manager.in_collision_single(meshes[0], far) is False


def test_prepared_bodies_and_the_scene_strategy():
    meshes, transforms = nested_and_nonconvex()
    det = pycinder.Detector(tolerance=TOL)
    prepared = det.prepare(meshes)
    assert det.in_collision(prepared, transforms) is True
    apart = transforms.copy()
    apart[1, :3, 3] = (5, 5, 5)
    assert det.in_collision(prepared, apart) is False
    scene = pycinder.Detector(strategy="scene", resolution=256)
    assert scene.in_collision(meshes, transforms) == bool(len(
        scene.find_collisions(meshes, transforms).pairs))


def test_the_likeliest_pairs_first_then_the_rest(monkeypatch):
    """The pairs whose boxes overlap most run first; when they do not collide, the rest still
    runs. Two rods through rings (boxes overlapping broadly, surfaces apart) and two cubes
    overlapping by 2.5 tolerances at a corner of their boxes."""
    from pycinder.focused import focused_strategy

    monkeypatch.setattr(focused_strategy, "LEAD_PAIRS", 1)
    monkeypatch.setattr(focused_strategy, "LEAD_FROM", 3)
    meshes, transforms = [], []
    for x in (10.0, 20.0):
        ring = np.eye(4)
        ring[:3, 3] = (x, 0, 0)
        meshes += [trimesh.creation.torus(major_radius=1.0, minor_radius=0.25),
                   trimesh.creation.cylinder(radius=0.3, height=3.0)]
        transforms += [ring, ring]
    cube = np.eye(4)
    cube[:3, 3] = (1.0 - 2.5 * TOL, 0, 0)
    meshes += [trimesh.creation.box((1, 1, 1)), trimesh.creation.box((1, 1, 1))]
    transforms += [np.eye(4), cube]
    transforms = np.array(transforms)
    truth = ground_truth(meshes, list(transforms), tolerance=TOL)
    assert truth.overlap.tolist() == [[4, 5]] and len(truth.ambiguous) == 0
    det = pycinder.Detector(tolerance=TOL, records="none")
    stopped = det._pending(meshes, transforms, None, None, None, "none",
                           stop_at_first=True).result()
    assert stopped.stats.candidates == 3 and stopped.pairs.tolist() == [[4, 5]]
    assert det.in_collision(meshes, transforms) is True
    assert det.in_collision(meshes[:4], transforms[:4]) is False


def test_a_dense_scene_stops_after_its_likeliest_pairs():
    """A scene of many candidates where most pairs collide stops after the rounds of the
    likeliest ones: the rest's faces are never clipped or drawn."""
    rng = np.random.default_rng(5)
    n = 120
    meshes = [trimesh.creation.icosphere(subdivisions=1, radius=0.5) for _ in range(n)]
    transforms = np.tile(np.eye(4), (n, 1, 1))
    transforms[:, :3, 3] = rng.uniform(0, 4.5, (n, 3))
    # The exact geometry of the closest two: a pair that must be found.
    d = np.linalg.norm(transforms[:, None, :3, 3] - transforms[None, :, :3, 3], axis=2)
    d[np.diag_indices(n)] = np.inf
    i, j = np.unravel_index(np.argmin(d), d.shape)
    assert len(ground_truth([meshes[i], meshes[j]], [transforms[i], transforms[j]],
                            tolerance=0.02).overlap) == 1
    det = pycinder.Detector(tolerance=0.02, records="none")
    whole = det.find_collisions(meshes, transforms)
    lead = pycinder.focused.plan.plan_numpy.LEAD_PAIRS
    assert whole.stats.candidates > 4 * lead and len(whole.pairs) > 100
    stopped = det._pending(meshes, transforms, None, None, None, "none",
                           stop_at_first=True).result()
    assert len(stopped.pairs) >= 1
    assert stopped.stats.triangles < whole.stats.triangles / 2
    assert det.in_collision(meshes, transforms) is True

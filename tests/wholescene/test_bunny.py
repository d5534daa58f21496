"""A closed high-polygon mesh is never reported against itself; with others, exactly the truth."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing import ground_truth, random_rotation

from conftest import assert_matches_truth


def test_bunny_is_closed_and_large(bunny):
    assert bunny.is_watertight and bunny.is_volume
    assert 50_000 <= len(bunny.faces) <= 60_000


@pytest.mark.parametrize("mode", ["filter", "prevent", "offset"])
def test_bunny_never_collides_with_itself(bunny, mode):
    det = pycinder.Detector(strategy="scene", resolution=1024, self_interference=mode)
    rng = np.random.default_rng(7)
    for _ in range(50):
        t = random_rotation(rng)
        t[:3, 3] = rng.uniform(-1, 1, 3)
        result = det.find_collisions([bunny], [t])
        assert result.pairs.shape == (0, 2)
        assert len(result.records) == 0
        if mode == "prevent":
            # Prevention works at the source: nothing had to be filtered.
            assert result.stats.self_interference_pixels == 0


@pytest.fixture(scope="module")
def bunny_ball_poses(bunny):
    """Eight poses of a ball near the bunny's surface (inside, crossing, or just outside), with
    their exact truth, shared by the modes below."""
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.08)
    rng = np.random.default_rng(3)
    centre = bunny.bounds.mean(axis=0)
    poses = []
    for k in range(8):
        t = random_rotation(rng)
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        hit = bunny.ray.intersects_location([centre], [direction])[0]
        surface = hit[np.argmax(np.linalg.norm(hit - centre, axis=1))] if len(hit) else centre
        offset = direction * [-0.12, -0.04, 0.0, 0.12, 0.04, -0.12, 0.12, 0.16][k]
        transforms = [t, t @ trimesh.transformations.translation_matrix(surface + offset)]
        poses.append((transforms, ground_truth([bunny, ball], transforms, tolerance=0.002)))
    return ball, poses


@pytest.mark.parametrize("mode", ["filter", "prevent"])
def test_bunny_and_a_second_body(bunny, bunny_ball_poses, mode):
    det = pycinder.Detector(strategy="scene", resolution=1024, self_interference=mode)
    ball, poses = bunny_ball_poses
    scored = {"overlap": 0, "separate": 0}
    for k, (transforms, truth) in enumerate(poses):
        result = det.find_collisions([bunny, ball], transforms)
        assert_matches_truth(result.pairs, truth, context=f"pose {k}")
        assert (result.records["penetrating"] != result.records["penetrated"]).all()
        scored["overlap"] += len(truth.overlap)
        scored["separate"] += len(truth.separate)
    assert scored["overlap"] >= 3 and scored["separate"] >= 2


def test_bunny_focused_never_against_itself_and_exact_with_a_ball(bunny, detector):
    """The focused strategy never tests a body against itself, and finds a ball on the surface."""
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.01)
    rng = np.random.default_rng(11)
    points, faces = trimesh.sample.sample_surface_even(bunny, 12, seed=3)
    for p, f in zip(points, faces):
        t = random_rotation(rng)
        lift = rng.choice([-0.004, 0.0, 0.004, 0.02])
        ball_t = trimesh.transformations.translation_matrix(p + bunny.face_normals[f] * lift)
        transforms = [t, t @ ball_t]
        truth = ground_truth([bunny, ball], transforms)
        assert_matches_truth(detector.find_collisions([bunny, ball], transforms).pairs, truth)
        assert detector.find_collisions([bunny], [t]).pairs.shape == (0, 2)

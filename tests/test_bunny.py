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
    det = pycinder.Detector(1024, self_interference=mode)
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


@pytest.mark.parametrize("mode", ["filter", "prevent"])
def test_bunny_and_a_second_body(bunny, mode):
    det = pycinder.Detector(1024, self_interference=mode)
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.08)
    rng = np.random.default_rng(3)
    centre = bunny.bounds.mean(axis=0)
    scored = {"overlap": 0, "separate": 0}
    for k in range(12):
        t = random_rotation(rng)
        # Put the ball near the bunny's surface: inside, crossing, or just outside.
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        hit = bunny.ray.intersects_location([centre], [direction])[0]
        surface = hit[np.argmax(np.linalg.norm(hit - centre, axis=1))] if len(hit) else centre
        offset = direction * rng.choice([-0.12, -0.04, 0.0, 0.04, 0.12])
        ball_t = trimesh.transformations.translation_matrix(surface + offset)
        transforms = [t, t @ ball_t]
        truth = ground_truth([bunny, ball], transforms)
        result = det.find_collisions([bunny, ball], transforms)
        assert_matches_truth(result.pairs, truth, context=f"pose {k}")
        assert (result.records["penetrating"] != result.records["penetrated"]).all()
        scored["overlap"] += len(truth.overlap)
        scored["separate"] += len(truth.separate)
    assert scored["overlap"] >= 3 and scored["separate"] >= 3

"""Collision results against exact geometry (manifold3d intersection volume, 5% band)."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.debug import three_boxes
from pycinder.testing import ground_truth, nested_scene, random_scene

from conftest import assert_matches_truth

MODES = ["filter", "prevent", "offset"]


@pytest.fixture(scope="module", params=MODES)
def detector(request) -> pycinder.Detector:
    return pycinder.Detector(1024, self_interference=request.param)


def test_three_boxes(detector):
    boxes, _, _ = three_boxes()
    truth = ground_truth(boxes)
    assert truth.overlap.tolist() == [[0, 1], [1, 2]]  # the scene is what the paper shows
    result = detector.find_collisions(boxes)
    assert_matches_truth(result.pairs, truth, context="three boxes")
    assert result.pairs.tolist() == [[0, 1], [1, 2]]


def test_three_boxes_through_paper_view(detector):
    boxes, _, view = three_boxes()
    assert detector.find_collisions(boxes, view=view).pairs.tolist() == [[0, 1], [1, 2]]


def test_nested_solid_without_surface_crossing(detector):
    meshes, transforms = nested_scene()
    truth = ground_truth(meshes, transforms)
    assert truth.overlap.tolist() == [[0, 1]]
    result = detector.find_collisions(meshes, transforms)
    assert_matches_truth(result.pairs, truth, context="nested")
    # Every record is the small sphere's edge inside the box, never the other way round.
    assert set(result.records["penetrating"].tolist()) == {1}
    assert set(result.records["penetrated"].tolist()) == {0}


@pytest.mark.parametrize("n,seed", [(5, 11), (5, 12), (20, 21), (20, 22)])
def test_random_scenes(detector, n, seed):
    meshes, transforms = random_scene(n, seed)
    truth = ground_truth(meshes, transforms)
    assert len(truth.overlap) and len(truth.separate)  # the scene tests both ways
    result = detector.find_collisions(meshes, transforms)
    assert_matches_truth(result.pairs, truth, context=f"{n} bodies, seed {seed}")


def test_near_misses_are_not_reported(detector_1024):
    """Pairs of tori and spheres 8% of their size apart: clearly separate, never reported."""
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.25)
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    meshes, transforms = [], []
    for k in range(4):
        gap = 0.08 * (k + 1) * 0.5
        meshes += [torus, ball]
        # The ball sits in the torus hole: its surface is gap away from the tube.
        r = 1.0 - 0.25 - 0.5 - gap
        transforms += [trimesh.transformations.translation_matrix((5 * k, 0, 0)),
                       trimesh.transformations.translation_matrix((5 * k + r, 0, 0))]
    truth = ground_truth(meshes, transforms)
    result = detector_1024.find_collisions(meshes, transforms)
    score = truth.score(result.pairs)
    assert not score["false"]
    # and the same scene pushed into contact is found
    pushed = [t.copy() for t in transforms]
    for k in range(4):
        pushed[2 * k + 1][0, 3] = 5 * k + 0.55
    truth2 = ground_truth(meshes, pushed)
    assert len(truth2.overlap) == 4
    assert_matches_truth(detector_1024.find_collisions(meshes, pushed).pairs, truth2)


def test_torus_hole_is_not_inside():
    """A rod through a torus's hole, touching nothing, is not a collision (non-convex shapes)."""
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    rod = trimesh.creation.cylinder(radius=0.3, height=4.0)
    truth = ground_truth([torus, rod])
    assert len(truth.separate) == 1
    assert pycinder.find_collisions([torus, rod], resolution=1024).pairs.tolist() == []
    shifted = [np.eye(4), trimesh.transformations.translation_matrix((0.75, 0, 0))]
    assert pycinder.find_collisions([torus, rod], shifted, resolution=1024).pairs.tolist() == [[0, 1]]


DENSE = [(60, 31), (60, 32)]


@pytest.mark.parametrize("n,seed", DENSE)
def test_dense_scene_reports_no_false_pair(detector_1024, n, seed):
    """Dense scenes: never a false pair, and recall at least the floor measured for one view."""
    meshes, transforms = random_scene(n, seed)
    truth = ground_truth(meshes, transforms)
    score = truth.score(detector_1024.find_collisions(meshes, transforms).pairs)
    assert not score["false"]
    assert score["recall"] >= 0.9, score


@pytest.mark.xfail(reason="one edge per pixel (paper 4.3): in dense scenes the last edge drawn "
                          "hides others, so some pairs are lost; expected to improve", strict=False)
@pytest.mark.parametrize("n,seed", DENSE)
def test_dense_scene_full_recall(detector_1024, n, seed):
    meshes, transforms = random_scene(n, seed)
    truth = ground_truth(meshes, transforms)
    assert_matches_truth(detector_1024.find_collisions(meshes, transforms).pairs, truth)

"""The paper's whole-scene strategy (``strategy="scene"``) against exact geometry.

Its pixel is the scene's extent divided by the resolution, so the truth is taken at a tolerance
of three of its pixels.
"""

import numpy as np
import pytest
import trimesh

import pycinder
import pycinder.testing
from pycinder.view import View
from pycinder.debug import three_boxes
from pycinder.testing import ground_truth, nested_scene, random_scene

from conftest import assert_matches_truth

MODES = ["filter", "prevent", "offset"]


@pytest.fixture(scope="module", params=MODES)
def scene_detector(request) -> pycinder.Detector:
    return pycinder.Detector(strategy="scene", resolution=1024, self_interference=request.param)


def truth_for(result, meshes, transforms=None):
    """Exact truth at a tolerance of three pixels of the result's (first) view."""
    return ground_truth(meshes, transforms, tolerance=3 * result.views[0].pixel_size)


def test_three_boxes(scene_detector):
    boxes, _, _ = three_boxes()
    result = scene_detector.find_collisions(boxes)
    truth = truth_for(result, boxes)
    assert truth.overlap.tolist() == [[0, 1], [1, 2]]  # the scene is what the paper shows
    assert_matches_truth(result.pairs, truth, context="three boxes")
    assert result.pairs.tolist() == [[0, 1], [1, 2]]


def test_three_boxes_through_paper_view(scene_detector):
    boxes, _, view = three_boxes()
    assert scene_detector.find_collisions(boxes, view=view).pairs.tolist() == [[0, 1], [1, 2]]


def test_nested_solid_without_surface_crossing(scene_detector):
    meshes, transforms = nested_scene()
    result = scene_detector.find_collisions(meshes, transforms)
    truth = truth_for(result, meshes, transforms)
    assert truth.overlap.tolist() == [[0, 1]]
    assert_matches_truth(result.pairs, truth, context="nested")
    # Every record is the small sphere's edge inside the box, never the other way round.
    assert set(result.records["penetrating"].tolist()) == {1}
    assert set(result.records["penetrated"].tolist()) == {0}


@pytest.mark.parametrize("n,seed", [(5, 11), (5, 12), (20, 21), (20, 22)])
def test_random_scenes(scene_detector, n, seed):
    meshes, transforms = random_scene(n, seed)
    result = scene_detector.find_collisions(meshes, transforms)
    truth = truth_for(result, meshes, transforms)
    assert len(truth.overlap) and len(truth.separate)  # the scene tests both ways
    assert_matches_truth(result.pairs, truth, context=f"{n} bodies, seed {seed}")


def test_torus_hole_is_not_inside():
    """A rod through a torus's hole, touching nothing, is not a collision (non-convex shapes)."""
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    rod = trimesh.creation.cylinder(radius=0.3, height=4.0)
    det = pycinder.Detector(strategy="scene", resolution=1024)
    assert det.find_collisions([torus, rod]).pairs.tolist() == []
    shifted = [np.eye(4), trimesh.transformations.translation_matrix((0.75, 0, 0))]
    assert det.find_collisions([torus, rod], shifted).pairs.tolist() == [[0, 1]]


@pytest.mark.parametrize("n,seed", [(60, 31), (60, 32)])
def test_dense_scene_reports_no_false_pair_and_loses_some(n, seed):
    """The paper's limit, kept as a reference: one edge per pixel loses pairs in dense scenes
    (the focused strategy's lists do not; see test_focused.py), but never invents one."""
    meshes, transforms = random_scene(n, seed)
    result = pycinder.Detector(strategy="scene", resolution=1024).find_collisions(meshes, transforms)
    score = truth_for(result, meshes, transforms).score(result.pairs)
    assert not score["false"]
    assert score["recall"] >= 0.9, score


def test_offset_works_through_a_user_view_without_pixel_size():
    """self_interference="offset" through a perspective View (which has no pixel_size): edges
    still move outwards by half a pixel at the scene's depth, so far fewer self-interference
    pixels reach the filter than without the offset."""
    bunny = pycinder.testing.bunny()
    centre, size = bunny.bounds.mean(axis=0), float(np.linalg.norm(bunny.extents))
    view = View.look_at(eye=centre + (0.3 * size, 0.4 * size, 1.5 * size), target=centre,
                        near=0.5 * size, far=4 * size, fov_y=50)
    assert view.pixel_size is None
    offset = pycinder.Detector(strategy="scene", resolution=512, self_interference="offset")
    plain = pycinder.Detector(strategy="scene", resolution=512, self_interference="filter")
    a = offset.find_collisions([bunny], view=view)
    b = plain.find_collisions([bunny], view=view)
    assert a.pairs.tolist() == b.pairs.tolist() == []
    assert b.stats.self_interference_pixels > 0
    assert a.stats.self_interference_pixels < b.stats.self_interference_pixels / 5

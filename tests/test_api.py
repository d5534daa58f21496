"""The public API: request checking, result shapes, views, warnings, reuse."""

import dataclasses

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing import ground_truth, random_scene
from pycinder.view import View

from conftest import assert_matches_truth

T = trimesh.transformations.translation_matrix


def test_readme_example():
    a = trimesh.creation.box((1, 1, 1))
    b = trimesh.creation.icosphere(radius=0.4)
    b.apply_translation((0.6, 0, 0))
    result = pycinder.find_collisions([a, b])
    assert result.pairs.tolist() == [[0, 1]]
    assert result.pairs.dtype == np.int64 and result.pairs.shape == (1, 2)
    assert result.is_collision and bool(result) and len(result) == 1
    assert pycinder.find_collisions([a, b], tolerance=1e-3).pairs.tolist() == [[0, 1]]


@pytest.mark.parametrize("strategy", ["focused", "scene"])
def test_pairs_are_unique_sorted_and_ordered(strategy):
    meshes, transforms = random_scene(20, 5)
    result = pycinder.Detector(strategy=strategy).find_collisions(meshes, transforms)
    p = result.pairs
    assert p.dtype == np.int64 and p.ndim == 2 and p.shape[1] == 2 and len(p)
    assert (p[:, 0] < p[:, 1]).all()
    assert len(np.unique(p, axis=0)) == len(p)
    assert (np.lexsort(p.T[::-1]) == np.arange(len(p))).all()
    assert result.records.dtype == pycinder.RECORD_DTYPE
    assert result.points().shape == (len(result.records), 3)


def test_vertex_face_pairs_and_trimesh_give_the_same_answer(detector):
    meshes, transforms = random_scene(8, 9)
    as_pairs = [(np.asarray(m.vertices), np.asarray(m.faces)) for m in meshes]
    a = detector.find_collisions(meshes, transforms)
    b = detector.find_collisions(as_pairs, transforms)
    assert a.pairs.tolist() == b.pairs.tolist()


def test_options_are_checked_once_when_the_request_is_made():
    with pytest.raises(ValueError, match="only apply to strategy='scene'"):
        pycinder.Detector(resolution=512)
    with pytest.raises(ValueError, match="tolerance applies to strategy='focused'"):
        pycinder.Detector(strategy="scene", tolerance=0.1)
    for bad in (0, -1.0, float("nan"), float("inf"), "0.1", True):
        with pytest.raises(ValueError, match="tolerance must be a positive number"):
            pycinder.CollisionRequest(tolerance=bad)
    with pytest.raises(ValueError, match="strategy must be one of"):
        pycinder.CollisionRequest(strategy="fast")
    with pytest.raises(ValueError, match="records must be one of"):
        pycinder.CollisionRequest(records=True)
    with pytest.raises(TypeError, match="first argument is a CollisionRequest"):
        pycinder.Detector(1024)
    request = pycinder.CollisionRequest(tolerance=0.01)
    with pytest.raises(dataclasses.FrozenInstanceError):
        request.tolerance = 0.02
    det = pycinder.Detector(request, records="none")
    assert det.request.tolerance == 0.01 and det.request.records == "none"
    with pytest.raises(ValueError, match="view applies to strategy='scene'"):
        det.find_collisions([trimesh.creation.box()], view=View.fit(np.eye(3)))
    with pytest.raises(ValueError, match="records must be one of"):
        det.find_collisions([trimesh.creation.box()], records="some")
    # NumPy scalars are numbers too.
    assert pycinder.CollisionRequest(tolerance=np.float32(0.5)).tolerance == 0.5
    assert pycinder.CollisionRequest(tolerance=np.int64(2)).tolerance == 2.0
    with pytest.raises(TypeError, match="leave 'records' out"):
        pycinder.CollisionManager(records="all")
    with pytest.raises(ValueError, match="tolerance must be a positive number"):
        pycinder.CollisionManager(tolerance=-1)


@pytest.mark.parametrize("strategy", ["focused", "scene"])
def test_empty_and_single_scenes(strategy):
    det = pycinder.Detector(strategy=strategy)
    for bodies in ([], [trimesh.creation.box()]):
        result = det.find_collisions(bodies)
        assert result.pairs.shape == (0, 2) and len(result.records) == 0 and not result


def test_scene_strategy_user_views_are_merged():
    meshes, transforms = random_scene(12, 4)
    views = [View.fit_bodies(meshes, transforms, direction=d, resolution=1024)
             for d in [(0, 0, -1), (1, 0, 0), (0.3, -1, 0.2)]]
    det = pycinder.Detector(strategy="scene", resolution=1024)
    merged = det.find_collisions(meshes, transforms, view=views)
    truth = ground_truth(meshes, transforms, tolerance=3 * views[0].pixel_size)
    assert_matches_truth(merged.pairs, truth)
    assert set(merged.records["view"].tolist()) <= {0, 1, 2}
    assert merged.stats.views == 3
    singles = [det.find_collisions(meshes, transforms, view=v) for v in views]
    union = np.unique(np.concatenate([s.pairs for s in singles]), axis=0)
    assert merged.pairs.tolist() == union.tolist()
    assert len(merged.records) == sum(len(s.records) for s in singles)


def test_scene_strategy_perspective_view():
    boxes = [trimesh.creation.box((1, 1, 1)), trimesh.creation.box((1, 1, 1))]
    view = View.look_at(eye=(3, 2, 6), target=(0.3, 0, 0), near=2.0, far=12.0)
    det = pycinder.Detector(strategy="scene", resolution=512)
    assert det.find_collisions(boxes, [np.eye(4), T((0.7, 0.3, 0.2))], view=view).pairs.tolist() \
        == [[0, 1]]
    assert det.find_collisions(boxes, [np.eye(4), T((1.3, 0.3, 0.2))], view=view).pairs.tolist() \
        == []


def test_a_view_that_cuts_a_body_is_reported_at_the_callers_line():
    a, b = trimesh.creation.box((1, 1, 1)), trimesh.creation.box((1, 1, 1))
    t = [T((0.5, 0, 0)), np.eye(4)]
    view = View.look_at(eye=(0, 0, 3), target=(0, 0, 0), near=2.7, far=10.0)
    det = pycinder.Detector(strategy="scene", resolution=64)
    with pytest.warns(pycinder.ClippedBodyWarning, match="is cut by the near plane") as w:
        det.find_collisions([a, b], t, view=view)
    assert sorted(str(x.message)[:6] for x in w) == ["body 0", "body 1"]
    assert all(x.filename == __file__ for x in w)
    with pytest.raises(ValueError, match="near plane"):
        pycinder.Detector(strategy="scene", resolution=64, strict=True).find_collisions(
            [a, b], t, view=view)


def test_scene_strategy_reuses_buffers_and_uploads_only_changed_vertices():
    det = pycinder.Detector(strategy="scene", resolution=256)
    meshes, transforms = random_scene(6, 3)
    arrays = [(np.array(m.vertices), np.array(m.faces)) for m in meshes]
    first = det.find_collisions(arrays, transforms)
    total = sum(v.shape[0] for v, _ in arrays) * 12
    assert first.stats.uploaded_vertex_bytes == total
    pipelines = dict(det.strategy.raycast.pipelines)
    same = det.find_collisions(arrays, transforms)
    assert same.stats.uploaded_vertex_bytes == 0
    assert same.pairs.tolist() == first.pairs.tolist()
    arrays[2][0][:] *= 1.01  # deform body 2 only, in place
    moved = det.find_collisions(arrays, transforms)
    assert moved.stats.uploaded_vertex_bytes == arrays[2][0].shape[0] * 12
    assert det.strategy.raycast.pipelines == pipelines


def test_stats_report_bytes_and_time():
    a, b = trimesh.creation.box((1, 1, 1)), trimesh.creation.box((1, 1, 1))
    apart = [np.eye(4), T((3, 0, 0))]
    touching = [np.eye(4), T((0.5, 0.2, 0.1))]
    det = pycinder.Detector(strategy="scene", resolution=256, readback="full")
    r = det.find_collisions([a, b], apart)
    assert r.stats.bytes_read == 16  # early out: only the counters came back
    assert r.stats.wall_ms["total"] > 0
    r = det.find_collisions([a, b], touching)
    assert r.stats.bytes_read == 16 + 256 * 256 * 16
    assert r.stats.records == len(r.records) > 0
    focused = pycinder.Detector()
    r = focused.find_collisions([a, b], apart)
    assert r.stats.candidates == 0 and r.stats.bytes_read == 0  # the broad phase decided
    r = focused.find_collisions([a, b], touching)
    assert r.stats.candidates == 1 and r.stats.records == len(r.records) > 0


def test_repeated_queries_leave_the_inputs_as_they_were():
    """The same (N, 4, 4) float64 array of transforms and the same vertex arrays, queried again
    and again: same answer, and the arrays are never written to (shapes are re-centred inside
    the scene, on copies)."""
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    off_centre = (np.array(ball.vertices) + [3.0, 0.0, 0.0], np.array(ball.faces))
    transforms = np.stack([np.eye(4)] * 3)
    transforms[1, 0, 3], transforms[2, 0, 3] = 0.8, -3.8     # centres at 0, 0.8 and -0.8
    given = transforms.copy(), off_centre[0].copy()
    det = pycinder.Detector()
    answers = [det.find_collisions([ball, ball, off_centre], transforms).pairs.tolist()
               for _ in range(4)]
    assert answers == [[[0, 1], [0, 2]]] * 4
    assert np.array_equal(transforms, given[0]) and np.array_equal(off_centre[0], given[1])

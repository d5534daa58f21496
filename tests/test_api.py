"""The public API contract, checked against exact geometry and hand-computed expectations."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing import ground_truth, random_scene
from pycinder.view import View

from conftest import assert_matches_truth


def test_readme_example():
    a = trimesh.creation.box((1, 1, 1))
    b = trimesh.creation.icosphere(radius=0.4)
    b.apply_translation((0.6, 0, 0))
    result = pycinder.find_collisions([a, b])
    assert result.pairs.tolist() == [[0, 1]]
    assert result.pairs.dtype == np.int64 and result.pairs.shape == (1, 2)


def test_pairs_are_unique_sorted_and_ordered(detector_1024):
    meshes, transforms = random_scene(20, 5)
    result = detector_1024.find_collisions(meshes, transforms)
    p = result.pairs
    assert p.dtype == np.int64 and p.ndim == 2 and p.shape[1] == 2
    assert (p[:, 0] < p[:, 1]).all()
    assert len(np.unique(p, axis=0)) == len(p)
    assert (np.lexsort(p.T[::-1]) == np.arange(len(p))).all()


def test_vertex_face_pairs_and_trimesh_give_the_same_answer(detector_1024):
    meshes, transforms = random_scene(8, 9)
    as_pairs = [(np.asarray(m.vertices), np.asarray(m.faces)) for m in meshes]
    a = detector_1024.find_collisions(meshes, transforms)
    b = detector_1024.find_collisions(as_pairs, transforms)
    assert a.pairs.tolist() == b.pairs.tolist()


def test_records_fields_and_points_lie_inside_the_penetrated_body():
    box = trimesh.creation.box((2, 2, 2))
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    t = [np.eye(4), trimesh.transformations.translation_matrix((1.2, 0.3, 0.1))]
    result = pycinder.find_collisions([box, ball], t, resolution=1024)
    rec = result.records
    for name in ("x", "y", "depth", "penetrating", "penetrated", "edge"):
        assert name in rec.dtype.names
    assert len(rec) > 50
    assert ((rec["x"] >= 0) & (rec["x"] < 1024) & (rec["y"] >= 0) & (rec["y"] < 1024)).all()
    assert ((rec["depth"] > 0) & (rec["depth"] < 1)).all()
    points = result.points()
    edge_vertices = result.edge_vertices()
    assert points.shape == (len(rec), 3)
    pixel = result.views[0].pixel_size
    meshes = [box, trimesh.Trimesh(ball.vertices + t[1][:3, 3], ball.faces)]
    for k in (0, 1):
        sel = rec["penetrated"] == k
        if not sel.any():
            continue
        # Signed distance is positive inside; allow two pixels for rasterisation.
        d = trimesh.proximity.signed_distance(meshes[k], points[sel])
        assert (d > -2 * pixel).all(), d.min()
        # and each point lies on an edge of the penetrating body
        other = meshes[1 - k]
        edges = edge_vertices[sel]
        a, b = other.vertices[edges[:, 0]], other.vertices[edges[:, 1]]
        ab = b - a
        s = np.clip(np.einsum("ij,ij->i", points[sel] - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
        dist = np.linalg.norm(a + s[:, None] * ab - points[sel], axis=1)
        assert dist.max() < 2 * pixel


def test_detector_reuses_buffers_and_uploads_only_changed_vertices():
    det = pycinder.Detector(256)
    meshes, transforms = random_scene(6, 3)
    arrays = [(np.array(m.vertices), np.array(m.faces)) for m in meshes]
    first = det.find_collisions(arrays, transforms)
    total = sum(v.shape[0] for v, _ in arrays) * 12
    assert first.stats.uploaded_vertex_bytes == total
    pipelines = dict(det.raycast.pipelines)
    same = det.find_collisions(arrays, transforms)
    assert same.stats.uploaded_vertex_bytes == 0
    assert same.pairs.tolist() == first.pairs.tolist()
    # Deform body 2 only, in place.
    arrays[2][0][:] *= 1.01
    moved = det.find_collisions(arrays, transforms)
    assert moved.stats.uploaded_vertex_bytes == arrays[2][0].shape[0] * 12
    assert det.raycast.pipelines == pipelines


def test_deforming_mesh_is_seen_by_the_gpu():
    det = pycinder.Detector(512)
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    verts = np.array(ball.vertices) + [0.6, 0, 0]
    bodies = [(np.array(box.vertices), np.array(box.faces)), (verts, np.array(ball.faces))]
    assert det.find_collisions(bodies).pairs.tolist() == [[0, 1]]
    verts += [1.0, 0, 0]  # move the vertices in place: now 0.8 apart
    assert det.find_collisions(bodies).pairs.tolist() == []


def test_user_view_and_several_views(detector_1024):
    meshes, transforms = random_scene(12, 4)
    truth = ground_truth(meshes, transforms)
    views = [View.fit_bodies(meshes, transforms, direction=d, resolution=1024)
             for d in [(0, 0, -1), (1, 0, 0), (0.3, -1, 0.2)]]
    merged = detector_1024.find_collisions(meshes, transforms, view=views)
    assert_matches_truth(merged.pairs, truth)
    assert set(merged.records["view"].tolist()) <= {0, 1, 2}
    assert merged.stats.views == 3
    singles = [detector_1024.find_collisions(meshes, transforms, view=v) for v in views]
    union = np.unique(np.concatenate([s.pairs for s in singles]), axis=0)
    assert merged.pairs.tolist() == union.tolist()
    assert len(merged.records) == sum(len(s.records) for s in singles)


def test_perspective_view():
    boxes_close = [trimesh.creation.box((1, 1, 1)), trimesh.creation.box((1, 1, 1))]
    t = [np.eye(4), trimesh.transformations.translation_matrix((0.7, 0.3, 0.2))]
    view = View.look_at(eye=(3, 2, 6), target=(0.3, 0, 0), near=2.0, far=12.0)
    assert pycinder.find_collisions(boxes_close, t, view=view).pairs.tolist() == [[0, 1]]
    t[1] = trimesh.transformations.translation_matrix((1.3, 0.3, 0.2))
    assert pycinder.find_collisions(boxes_close, t, view=view).pairs.tolist() == []


def test_view_that_cuts_a_body_is_reported():
    a, b = trimesh.creation.box((1, 1, 1)), trimesh.creation.box((1, 1, 1))
    t = [np.eye(4), trimesh.transformations.translation_matrix((0.5, 0, 0))]
    view = View.look_at(eye=(0, 0, 3), target=(0, 0, 0), near=2.7, far=10.0)
    with pytest.warns(pycinder.ClippedBodyWarning, match="body 0 is cut by the near plane of view 0"):
        pycinder.find_collisions([a, b], t, view=view)
    with pytest.raises(ValueError, match="near plane"):
        pycinder.Detector(64, strict=True).find_collisions([a, b], t, view=view)


def test_empty_scene():
    result = pycinder.find_collisions([])
    assert result.pairs.shape == (0, 2) and len(result.records) == 0 and not result


def test_stats_report_bytes_and_time():
    a = trimesh.creation.box((1, 1, 1))
    b = trimesh.creation.box((1, 1, 1))
    apart = [np.eye(4), trimesh.transformations.translation_matrix((3, 0, 0))]
    det = pycinder.Detector(256, readback="full")
    r = det.find_collisions([a, b], apart)
    assert r.stats.bytes_read == 16  # early out: only the counters came back
    assert r.stats.wall_ms["total"] > 0
    touching = [np.eye(4), trimesh.transformations.translation_matrix((0.5, 0.2, 0.1))]
    r = det.find_collisions([a, b], touching)
    assert r.stats.bytes_read == 16 + 256 * 256 * 16
    assert r.stats.records == len(r.records) > 0

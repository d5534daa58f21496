"""Bodies checked once (Detector.prepare): queries that change only transforms, and vertices told
with update(); answers scored against exact geometry."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing import ground_truth, random_rotation, random_scene


def _check(result, truth):
    found = {tuple(p) for p in result.pairs.tolist()}
    assert {tuple(p) for p in truth.overlap.tolist()} <= found
    assert not found & {tuple(p) for p in truth.separate.tolist()}


def test_prepared_bodies_answer_every_frame_of_a_moving_scene(detector):
    meshes, transforms = random_scene(30, 11, density=0.3)
    names = [f"part{i}" for i in range(30)]
    bodies = detector.prepare(meshes, names=names)
    assert len(bodies) == 30 and bodies[3] is meshes[3]
    rng = np.random.default_rng(5)
    poses = np.array(transforms)
    for frame in range(3):
        result = detector.find_collisions(bodies, poses)
        truth = ground_truth(meshes, poses)
        assert len(truth.overlap) > 3
        _check(result, truth)
        assert result.names == names
        # the same scene given as a list answers the same
        assert result.pairs.tolist() == detector.find_collisions(meshes, poses).pairs.tolist()
        poses[:, :3, 3] += rng.normal(scale=0.15, size=(30, 3))
        poses[:, :3, :3] = poses[:, :3, :3] @ random_rotation(rng)[:3, :3]


def test_updated_vertices_are_seen_and_other_bodies_keep_theirs(detector):
    """Three copies of one ball share a mesh; growing one of them makes it reach its neighbour,
    the others stay as they were."""
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    poses = np.stack([np.eye(4)] * 3)
    poses[:, 0, 3] = [0.0, 1.2, 2.4]
    bodies = detector.prepare([ball, ball, ball])
    assert detector.find_collisions(bodies, poses).pairs.tolist() == []
    grown = np.asarray(ball.vertices) * 1.5            # radius 0.75: 0.05 into body 1
    bodies.update(0, grown)
    meshes = [(grown, ball.faces), ball, ball]
    truth = ground_truth(meshes, poses, tolerance=0.005)
    assert truth.overlap.tolist() == [[0, 1]]
    result = pycinder.Detector(tolerance=0.005).find_collisions(bodies, poses)
    assert result.pairs.tolist() == [[0, 1]]
    np.testing.assert_array_equal(bodies[0][0], grown)
    # several bodies at once; vertices of any real dtype; one shape for equal vertices
    bodies.update([1, 2], [np.asarray(ball.vertices, np.float32) * 0.5] * 2)
    assert detector.find_collisions(bodies, poses).pairs.tolist() == []
    b = bodies.body_shape
    assert len(bodies.shapes) == 2 and b[1] == b[2] != b[0]


def test_the_scenes_of_prepared_bodies_share_their_per_body_arrays_until_an_update(detector):
    """Every query's scene of prepared bodies shares one set of per-body arrays (boxes, face
    counts, ...), read-only; an update makes new ones that see the new vertices."""
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    box = trimesh.creation.box((1.0, 2.0, 3.0))
    bodies = detector.prepare([ball, box, ball])
    first, second = bodies.scene(None), bodies.scene(np.stack([np.eye(4)] * 3))
    for name in ("local_lo", "local_hi", "face_counts", "open", "radius"):
        assert getattr(first, name) is getattr(second, name), name
        assert not getattr(first, name).flags.writeable, name
    np.testing.assert_allclose(first.local_hi[1] - first.local_lo[1], [1.0, 2.0, 3.0])
    assert first.face_counts.tolist() == [320, 12, 320]
    bodies.update(0, np.asarray(ball.vertices) * 2.0)
    after = bodies.scene(None)
    assert after.local_lo is not first.local_lo
    np.testing.assert_allclose(after.local_hi[0] - after.local_lo[0], 2.0 * (
        first.local_hi[0] - first.local_lo[0]))
    np.testing.assert_array_equal(after.local_hi[1:], first.local_hi[1:])


def test_copies_of_prepared_bodies_answer_as_a_batch_of_their_scenes(detector):
    """Copies of prepared bodies in many small scenes (one query, pairs only within a scene)
    give each scene the pairs the batch of the same scenes gives; copies' transforms are
    checked and named; indices out of range are refused."""
    rng = np.random.default_rng(4)
    meshes = [trimesh.creation.icosphere(subdivisions=1, radius=0.3),
              trimesh.creation.box((0.5, 0.2, 0.4)), trimesh.creation.cylinder(0.1, 0.8)]
    bodies = detector.prepare(meshes, names=["ball", "box", "rod"])
    scenes, index, transforms, within = [], [], [], []
    for s in range(12):
        which = rng.choice(3, size=rng.integers(2, 4), replace=False)
        poses = np.stack([random_rotation(rng) for _ in which])
        poses[:, :3, 3] = rng.uniform(-0.4, 0.4, (len(which), 3))
        scenes.append(([meshes[k] for k in which], poses))
        index += which.tolist()
        transforms.append(poses)
        within += [s] * len(which)
    scene = bodies.copies(np.array(index), np.concatenate(transforms))
    mine = detector._find_within(scene, np.array(within), None)
    first = np.cumsum([0] + [len(t) for t in transforms])
    batch = detector.find_collisions_batch(scenes)
    assert sum(len(r.pairs) for r in batch) == len(mine.pairs) > 0
    for s, result in enumerate(batch):
        inside = (mine.pairs[:, 0] >= first[s]) & (mine.pairs[:, 0] < first[s + 1])
        assert (mine.pairs[inside] - first[s]).tolist() == result.pairs.tolist(), s
    bad = np.concatenate(transforms)
    bad[4, 0, 0] = np.nan
    names = [f"copy {k}" for k in range(len(bad))]
    with pytest.raises(ValueError, match=r"body 4 \('copy 4'\): transform contains NaN"):
        bodies.copies(np.array(index), bad, names)
    with pytest.raises(ValueError, match="index must be"):
        bodies.copies(np.array([0, 3]), np.stack([np.eye(4)] * 2))
    # World boxes given with the copies are the scene's (not measured again): the same pairs
    # with boxes grown a little; radii for the GPU's broad phase are still measured.
    poses = np.concatenate(transforms)
    lo, hi = scene.world_boxes()
    boxed = bodies.copies(np.array(index), poses, boxes=(lo - 0.01, hi + 0.01))
    assert np.array_equal(boxed.world_boxes()[0], lo - 0.01)
    assert np.array_equal(boxed.bounding_radii(), scene.bounding_radii())
    again = detector._find_within(boxed, np.array(within), None)
    assert again.pairs.tolist() == mine.pairs.tolist()
    with pytest.raises(ValueError, match="boxes must be two"):
        bodies.copies(np.array(index), poses, boxes=(lo[:2], hi))


def test_an_update_uploads_only_the_vertices_it_changed_and_ages_no_cached_shape(monkeypatch):
    """A body with a shape of its own keeps its slot (the GPU's index buffers stay, only its
    vertices are written), and updates between list queries do not push the list's shapes out
    of the cache (they are not measured again)."""
    from pycinder.scene import bodies as scene_bodies

    detector = pycinder.Detector()
    meshes = [trimesh.creation.icosphere(subdivisions=2, radius=0.4),
              trimesh.creation.box((1, 1, 1)), trimesh.creation.cylinder(0.3, 1.0)]
    poses = np.stack([np.eye(4)] * 3)
    poses[:, 0, 3] = [0.0, 0.8, 1.7]                   # neighbours near: candidate pairs
    listed = [(np.array(m.vertices), np.array(m.faces)) for m in meshes]
    detector.find_collisions(listed, poses)
    bodies = detector.prepare(meshes)
    detector.find_collisions(bodies, poses)
    measured = []
    real = scene_bodies._measure
    monkeypatch.setattr(scene_bodies, "_measure",
                        lambda *a: measured.append(len(a[0])) or real(*a))
    for k in range(3):
        moved = np.asarray(meshes[0].vertices) * (1.0 + 0.01 * (k + 1))
        bodies.update(0, moved)
        result = detector.find_collisions(bodies, poses)
        assert result.stats.uploaded_vertex_bytes == moved.size * 4   # float32, this body only
    assert measured == [len(meshes[0].vertices)] * 3
    detector.find_collisions(listed, poses)
    assert measured == [len(meshes[0].vertices)] * 3                   # nothing measured again


def test_a_loop_of_updates_leaves_nothing_behind():
    """A body deforming through update() for many frames, with no list query in between: the
    detector's cache holds no shape per frame, and the answers follow the vertices."""
    detector = pycinder.Detector()
    ball = trimesh.creation.icosphere(subdivisions=1, radius=0.5)
    poses = np.stack([np.eye(4), trimesh.transformations.translation_matrix((1.1, 0, 0))])
    bodies = detector.prepare([ball, ball])
    cached = len(detector.shapes)
    for k in range(300):
        # radius 0.5 (0.1 apart) or 0.75 (overlap), and new vertices every frame
        scale = (1.0 + 0.5 * (k % 2)) * (1.0 + 1e-6 * k)
        bodies.update(0, np.asarray(ball.vertices) * scale)
        if k % 50 < 2:
            want = [[0, 1]] if k % 2 else []
            assert detector.find_collisions(bodies, poses).pairs.tolist() == want
    assert len(detector.shapes) == cached and len(bodies.shapes) == 2


def test_a_vertex_array_edited_in_place_is_seen_only_once_updated(detector):
    """Like trimesh's manager (its BVHs are built when objects are added), prepared bodies are
    the meshes as they were: an edit counts from update()."""
    box = trimesh.creation.box((1, 1, 1))
    vertices = np.array(box.vertices)
    bodies = detector.prepare([(vertices, box.faces), box])
    poses = np.stack([np.eye(4), trimesh.transformations.translation_matrix((1.2, 0, 0))])
    assert detector.find_collisions(bodies, poses).pairs.tolist() == []
    vertices[:, 0] *= 1.6                               # now 0.1 into the other box
    assert detector.find_collisions(bodies, poses).pairs.tolist() == []
    bodies.update(0, vertices)
    assert detector.find_collisions(bodies, poses).pairs.tolist() == [[0, 1]]
    # the list form sees the edit at once
    assert detector.find_collisions([(vertices, box.faces), box], poses).pairs.tolist() \
        == [[0, 1]]


def test_contacts_and_submit_work_on_prepared_bodies(detector):
    a = trimesh.creation.box((1, 1, 1))
    b = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    bodies = detector.prepare([a, b], names=["box", "ball"])
    poses = np.stack([np.eye(4), trimesh.transformations.translation_matrix((0.7, 0, 0))])
    pending = detector.submit(bodies, poses, contacts=True)
    result = pending.result()
    assert result.pairs.tolist() == [[0, 1]]
    contacts = result.contacts()
    assert len(contacts) == 1
    # the ball's centre is 0.7 from the box's, 0.2 inside its face at x = 0.5: depth 0.2
    assert contacts.depth[0] == pytest.approx(0.2, abs=0.02)


def test_bad_input_to_prepared_bodies_names_the_body(detector, monkeypatch):
    box = trimesh.creation.box((1, 1, 1))
    bad = np.array(box.vertices)
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"body 1 \('lid'\).*NaN"):
        detector.prepare([box, (bad, box.faces)], names=["base", "lid"])
    bodies = detector.prepare([box, box], names=["base", "lid"])
    with pytest.raises(ValueError, match=r"body 1 \('lid'\).*NaN"):
        bodies.update(1, bad)
    assert bodies[1] is box                             # left as it was
    with pytest.raises(IndexError, match="body 2"):
        bodies.update(2, box.vertices)
    with pytest.raises(ValueError, match="2 vertex arrays for 1 bodies"):
        bodies.update([0], [box.vertices, box.vertices])
    with pytest.raises(ValueError, match=r"shape \(2, 4, 4\)"):
        detector.find_collisions(bodies, np.eye(4)[None])
    with pytest.raises(ValueError, match=r"body 0 \('base'\).*NaN"):
        detector.find_collisions(bodies, np.full((2, 4, 4), np.nan))
    with pytest.raises(ValueError, match="prepared bodies have their names"):
        detector.find_collisions(bodies, names=["x", "y"])
    monkeypatch.setitem(pycinder.request.MAX_BODIES, "focused", 1)
    with pytest.raises(ValueError, match="more than the 1 one query can hold"):
        detector.find_collisions(bodies)
    with pytest.raises(ValueError, match="more than the 1 one query can hold"):
        detector.prepare([box, box])


def test_an_update_keeps_the_prepared_faces_without_looking_them_up(monkeypatch):
    """update() gives a body new vertices on the topology it was prepared with: its faces are
    not looked up or compared again (an array of faces edited in place since is not seen), while
    vertices of another count, and faces replaced by another array, are looked up; answers
    against exact geometry."""
    from pycinder.scene.topology import TopologyCache

    detector = pycinder.Detector()
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    faces = np.array(ball.faces)
    poses = np.stack([np.eye(4), trimesh.transformations.translation_matrix((1.1, 0, 0))])
    bodies = detector.prepare([(np.array(ball.vertices), faces), ball])
    looked = []
    real = TopologyCache.get
    monkeypatch.setattr(TopologyCache, "get", lambda self, *a: looked.append(a) or real(self, *a))
    faces[:, [1, 2]] = faces[:, [2, 1]]                  # edited in place: inside out, unseen
    for scale, want in ((1.0, []), (1.3, [[0, 1]]), (0.9, [])):
        bodies.update(0, np.asarray(ball.vertices) * scale)
        result = detector.find_collisions(bodies, poses)
        truth = ground_truth([(np.asarray(ball.vertices) * scale, ball.faces), ball], poses)
        assert result.pairs.tolist() == truth.overlap.tolist() == want
    assert looked == []
    with pytest.raises(ValueError, match=r"body 0: .*vertices"):
        bodies.update(0, np.asarray(ball.vertices)[:10])   # the faces index more vertices
    assert len(looked) == 1
    # A trimesh whose faces are set anew: they are looked up (half of them: an open surface).
    box = trimesh.creation.box((1, 1, 1))
    kept = detector.prepare([box, ball], names=["box", "ball"])
    before = len(looked)
    kept.update(1, np.asarray(ball.vertices) * 1.01)        # a trimesh's own faces: kept
    assert len(looked) == before
    box.faces = box.faces[:6]
    with pytest.warns(pycinder.OpenMeshWarning, match=r"body 0 \('box'\)"):
        kept.update(0, box.vertices * 1.01)
    assert len(looked) == before + 1
    assert len(kept.shapes[kept.body_shape[0]].topology.faces) == 6

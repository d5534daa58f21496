"""CollisionManager as a drop-in for trimesh's: behaviour from trimesh's documentation, answers
from exact geometry and python-fcl, and contacts against analytic pairs."""

import numpy as np
import pytest
import trimesh

pytest.importorskip("fcl", reason="trimesh's manager, the answers compared with, and distances "
                                  "run on python-fcl (the test and distance extras)")

import pycinder
from pycinder.manager import EXTERNAL
from pycinder.testing import ground_truth, random_scene

TrimeshManager = trimesh.collision.CollisionManager
T = trimesh.transformations.translation_matrix
R = trimesh.transformations.rotation_matrix


def both(**objects):
    """The same objects in pycinder's manager and trimesh's."""
    ours, theirs = pycinder.CollisionManager(), TrimeshManager()
    for name, (mesh, transform) in objects.items():
        ours.add_object(name, mesh, transform)
        theirs.add_object(name, mesh, transform)
    return ours, theirs


def clear_scene(seed: int):
    """A random scene with no pair in the tolerance band, so FCL and the truth agree."""
    for s in range(seed, seed + 50):
        meshes, transforms = random_scene(10, s, density=0.2)
        truth = ground_truth(meshes, transforms)
        if len(truth.ambiguous) == 0 and len(truth.overlap):
            return meshes, transforms, truth
    raise AssertionError("no clear scene")


@pytest.mark.parametrize("seed", [100, 200])
def test_internal_names_match_trimesh(seed):
    meshes, transforms, truth = clear_scene(seed)
    ours, theirs = both(**{f"obj{i}": (m, t) for i, (m, t) in enumerate(zip(meshes, transforms))})
    hit, names = ours.in_collision_internal(return_names=True)
    assert (hit, names) == theirs.in_collision_internal(return_names=True)
    assert ours.in_collision_internal() is hit is True
    assert names == {(f"obj{i}", f"obj{j}") for i, j in truth.overlap.tolist()}


def test_separate_touching_and_overlapping_boxes():
    box = trimesh.creation.box((1, 1, 1))
    ours, theirs = both(a=(box, np.eye(4)), b=(box, T((1.2, 0, 0))))
    assert ours.in_collision_internal() is False is theirs.in_collision_internal()
    # Touching faces (distance 0) lie in the tolerance band, where either answer keeps the
    # contract (python-fcl's depends on rounding), so only the type is checked. Just beyond the
    # tolerance they are apart for both.
    for m in (ours, theirs):
        m.set_transform("b", T((1.0, 0, 0)))
    assert isinstance(ours.in_collision_internal(), bool)
    tol = 0.01 * np.sqrt(3)  # the default: 1% of the smaller body's diagonal
    for m in (ours, theirs):
        m.set_transform("b", T((1.0 + 1.01 * tol, 0, 0)))
    assert ours.in_collision_internal() is False is theirs.in_collision_internal()
    for m in (ours, theirs):
        m.set_transform("b", T((0.9, 0.3, 0.2)))
    hit, names, data = ours.in_collision_internal(return_names=True, return_data=True)
    assert (hit, names) == (True, {("a", "b")}) == theirs.in_collision_internal(return_names=True)
    assert len(data) == 1 and data[0].names == {"a", "b"}
    c = data[0]
    assert c.pair == ("a", "b") and np.allclose(c.normal, [1, 0, 0], atol=np.sin(np.radians(10)))
    assert c.depth == pytest.approx(0.1, abs=0.01 + 0.1 * 0.1 + 0.02)
    assert 0 <= c.index("a") < 12 and 0 <= c.index("b") < 12


def test_a_body_inside_another_collides():
    """FCL tests surfaces, so a body wholly inside another is no collision to trimesh's manager;
    it is one here."""
    big, small = trimesh.creation.torus(2.0, 0.8), trimesh.creation.torus(2.0, 0.1)
    ours, theirs = both(big=(big, np.eye(4)), small=(small, np.eye(4)))
    assert ground_truth([big, small]).overlap.tolist() == [[0, 1]]
    assert theirs.in_collision_internal() is False
    assert ours.in_collision_internal(return_names=True) == (True, {("big", "small")})
    assert ours.min_distance_internal() < 0


def test_non_convex_container():
    """A ball in an open-topped box made of five slabs (one closed, non-convex solid)."""
    import manifold3d as m3d

    outer = m3d.Manifold.cube((2.0, 2.0, 2.0), center=True)
    inner = m3d.Manifold.cube((1.6, 1.6, 1.8), center=True).translate((0, 0, 0.3))
    mesh = (outer - inner).to_mesh()
    cup = trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts))
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    ours = pycinder.CollisionManager()
    ours.add_object("cup", cup)
    for z, expected in ((0.0, False), (-0.35, True), (1.6, False)):
        truth = ground_truth([cup, ball], [np.eye(4), T((0, 0, z))])
        assert (len(truth.overlap) == 1) == expected
        assert ours.in_collision_single(ball, T((0, 0, z))) is expected, z


def test_set_transform_round_trips_and_errors():
    box, ball = trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.3)
    ours = pycinder.CollisionManager()
    ours.add_object("box", box)
    obj = ours.add_object("ball", ball, T((3, 0, 0)).astype(np.float32))  # float32 is fine
    assert obj.name == "ball" and obj.transform.dtype == np.float64
    assert ours.in_collision_internal() is False
    ours.set_transform("ball", T((0.5, 0.4, 0)))
    assert ours.in_collision_internal(return_names=True) == (True, {("ball", "box")})
    ours.set_transform("ball", T((3, 0, 0)))
    assert ours.in_collision_internal() is False
    ours.add_object("ball", ball, T((0.6, 0, 0)))  # same name: replaced
    assert ours.in_collision_internal(return_names=True) == (True, {("ball", "box")})
    ours.remove_object("ball")
    assert ours.in_collision_internal() is False
    for call in (lambda: ours.remove_object("ball"), lambda: ours.set_transform("x", np.eye(4)),
                 lambda: ours.min_distance_internal("x")):
        with pytest.raises(ValueError, match="not in collision manager!"):
            call()
    with pytest.raises(ValueError, match=r"transform must be \(4,4\)!"):
        ours.add_object("bad", box, np.eye(3))


def test_every_method_tests_the_mesh_as_it_was_added(monkeypatch):
    """As trimesh builds its BVHs when objects are added: moving objects checks no mesh again,
    a mesh edited in place is seen by no method until it is added again (in both managers), and
    adding or removing objects checks the meshes anew."""
    meshes, transforms, _ = clear_scene(300)
    ours, theirs = both(**{f"o{i}": (m, t) for i, (m, t) in enumerate(zip(meshes, transforms))})
    prepared = []
    real = pycinder.Detector.prepare
    monkeypatch.setattr(pycinder.Detector, "prepare",
                        lambda self, *a, **k: prepared.append(1) or real(self, *a, **k))
    rng = np.random.default_rng(3)
    for _ in range(3):
        for i in range(len(meshes)):
            t = transforms[i].copy()
            t[:3, 3] += rng.normal(scale=0.3, size=3)
            ours.set_transform(f"o{i}", t)
        truth = ground_truth(meshes, [ours._objs[f"o{i}"].transform for i in range(len(meshes))])
        names = ours.in_collision_internal(return_names=True)[1]
        assert {(f"o{i}", f"o{j}") for i, j in truth.overlap.tolist()} <= names
        assert not names & {(f"o{i}", f"o{j}") for i, j in truth.separate.tolist()}
    assert len(prepared) == 1
    box, ball = trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.3)
    far = [T((50, 0, 0)), T((51.3, 0, 0))]
    probe = T((49.1, 0, 0))                                   # the ball 0.1 from the box
    other = pycinder.CollisionManager()
    other.add_object("ball", ball, probe)
    other_t = TrimeshManager()
    other_t.add_object("ball", ball, probe)
    for m in (ours, theirs):
        m.add_object("box", box, far[0])
        m.add_object("lid", box, far[1])
    box.vertices = box.vertices * [1.8, 1, 1]                 # now 0.1 into "lid" and the ball
    for m, o in ((ours, other), (theirs, other_t)):
        assert ("box", "lid") not in m.in_collision_internal(return_names=True)[1]
        assert "box" not in m.in_collision_single(ball, probe, return_names=True)[1]
        assert ("box", "ball") not in m.in_collision_other(o, return_names=True)[1]
    assert ours.min_distance_single(ball, probe) > 0.05
    assert len(prepared) == 2                     # the two adds: once, at the next query
    past_lid = T((52.2, 0, 0))                  # 0.1 beyond "lid" as added; in it, widened
    for m, o in ((ours, other), (theirs, other_t)):
        m.add_object("box", box, far[0])
        assert ("box", "lid") in m.in_collision_internal(return_names=True)[1]
        assert "box" in m.in_collision_single(ball, probe, return_names=True)[1]
        assert ("box", "ball") in m.in_collision_other(o, return_names=True)[1]
        # "lid", added with the same mesh, keeps the mesh as it was when it was added
        assert "lid" not in m.in_collision_single(ball, past_lid, return_names=True)[1]
    distance, name = ours.min_distance_single(ball, past_lid, return_name=True)
    assert name == "lid" and 0.1 - 1e-9 <= distance < 0.13    # python-fcl, on the old mesh
    with pytest.raises(ValueError, match="read-only"):
        ours._objs["box"].trimesh.vertices[0, 0] = 5.0   # what is tested cannot be edited
    assert list(ours._objs)[-2:] == ["box", "lid"]            # a replaced object keeps its place
    ours.remove_object("lid")
    assert not any("lid" in p for p in ours.in_collision_internal(return_names=True)[1])
    assert len(prepared) == 4


def test_a_call_with_another_manager_waits_for_that_manager():
    """in_collision_other reads the other manager's objects: it holds that manager's lock, so
    an add_object there (from another thread) cannot change them under it."""
    import threading

    box = trimesh.creation.box((1, 1, 1))
    ours, other = pycinder.CollisionManager(), pycinder.CollisionManager()
    ours.add_object("a", box)
    other.add_object("b", box, T((0.5, 0, 0)))
    answers = []
    with other._lock:                                   # as if other were busy in a call
        worker = threading.Thread(target=lambda: answers.append(
            ours.in_collision_other(other, return_names=True)))
        worker.start()
        worker.join(timeout=0.5)
        assert worker.is_alive() and not answers         # it waits for other's lock
    worker.join(timeout=60)
    assert answers == [(True, {("a", "b")})]
    # crossed calls from two threads take the two locks in one order: no deadlock
    results = []
    threads = [threading.Thread(target=lambda m, o: results.append(m.in_collision_other(o)),
                                args=pair) for pair in ((ours, other), (other, ours)) * 3]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert results == [True] * 6


def test_single_and_other_as_trimesh():
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(radius=0.3)
    ours, theirs = both(box=(box, np.eye(4)), ball=(ball, T((3, 0, 0))))
    probe = trimesh.creation.icosphere(radius=0.25)
    at = T((0.6, 0, 0))
    for m in (ours, theirs):
        assert m.in_collision_single(probe, at) is True
        assert m.in_collision_single(probe, at, return_names=True) == (True, {"box"})
        hit, data = m.in_collision_single(probe, at, return_data=True)
        assert hit and data and all(d.names == {"box", "__external"} for d in data)
    # Same names in both managers: the pairs are (this name, other name).
    other_ours, other_theirs = both(box=(probe, at))
    assert ours.in_collision_other(other_ours, return_names=True) == \
        theirs.in_collision_other(other_theirs, return_names=True) == (True, {("box", "box")})
    hit, names, data = ours.in_collision_other(other_ours, return_names=True, return_data=True)
    assert data and all(d.names == {"box"} for d in data)
    assert pycinder.CollisionManager().in_collision_internal() is False


def test_many_probes_in_one_query(monkeypatch):
    """700 copies of one probe against one large box: every probe found, in one query, and the
    same answer as trimesh's manager outside the tolerance band."""
    queries = []
    find = pycinder.Detector.find_collisions

    def counted(self, *args, **kwargs):
        queries.append(len(args[0]))
        return find(self, *args, **kwargs)

    monkeypatch.setattr(pycinder.Detector, "find_collisions", counted)
    probe = trimesh.creation.icosphere(subdivisions=1, radius=0.05)
    ours, theirs = pycinder.CollisionManager(), TrimeshManager()
    centres = np.random.default_rng(0).uniform(-1.2, 1.2, (700, 3))
    for k, c in enumerate(centres):
        ours.add_object(f"p{k}", probe, T(c))
        theirs.add_object(f"p{k}", probe, T(c))
    box = trimesh.creation.box((2, 2, 2))
    hit, names = ours.in_collision_single(box, return_names=True)
    _, fcl_names = theirs.in_collision_single(box, return_names=True)
    # Signed distance of each centre to the box; the probe's surface lies 0.04 to 0.05 from it.
    outside = np.maximum(np.abs(centres) - 1, 0)
    inside = np.minimum(np.max(np.abs(centres) - 1, axis=1), 0)
    box_distance = np.linalg.norm(outside, axis=1) + inside
    tol = 0.01 * np.linalg.norm(probe.extents)
    must = {f"p{k}" for k in np.flatnonzero(box_distance < 0.04 - 2 * tol)}
    apart = {f"p{k}" for k in np.flatnonzero(box_distance > 0.05 + tol)}
    assert hit and must <= names and not (names & apart)
    assert len(must) > 300
    assert names ^ fcl_names <= set(ours._objs) - must - apart
    assert queries == [701]  # the probe and the 700 objects, in one query


def _fcl_distance(a, ta, b, tb):
    """python-fcl's signed distance, built as trimesh builds it."""
    m = TrimeshManager()
    m.add_object("a", a, ta)
    return m.min_distance_single(b, tb)


@pytest.mark.parametrize("gap", [0.3, 0.05, -0.05, -0.2])
def test_distances_agree_with_fcl(gap):
    """Separated: python-fcl's exact distance; overlapping: negative, the penetration depth."""
    a, b = trimesh.creation.icosphere(3, 0.5), trimesh.creation.box((0.6, 0.6, 0.6))
    tb = T((0.5 + 0.3 + gap, 0.0, 0.0))
    ours = pycinder.CollisionManager(tolerance=0.005)
    ours.add_object("sphere", a)
    d, name, data = ours.min_distance_single(b, tb, return_name=True, return_data=True)
    expected = _fcl_distance(a, np.eye(4), b, tb)
    assert name == "sphere" and data.names == {"sphere", "__external"}
    # The truth is the gap between the sphere and the box's face (the faceted sphere lies within
    # 0.001 of the round one), negative when they overlap; python-fcl gives the same.
    assert d == pytest.approx(gap, abs=0.005 + 0.001)
    assert expected == pytest.approx(gap, abs=0.001)
    if gap > 0:
        assert np.linalg.norm(data.point("sphere") - data.point("__external")) == \
            pytest.approx(d, abs=1e-6)
    ours.add_object("box", b, tb)
    assert ours.min_distance_internal(return_names=True)[1] == ("box", "sphere")
    assert ours.min_distance_internal(name="box") == pytest.approx(d, abs=1e-9)


def test_overlapping_non_convex_distance_is_negative():
    """python-fcl reports 0 for overlapping non-convex meshes; here it is minus the depth."""
    torus = trimesh.creation.torus(1.0, 0.3, major_sections=64, minor_sections=32)
    ours, theirs = both(t1=(torus, np.eye(4)), t2=(torus, T((2.5, 0, 0))))
    assert theirs.min_distance_internal() == pytest.approx(0.0)
    d = ours.min_distance_internal()
    assert d == pytest.approx(-0.1, abs=0.03)
    for m in (ours, theirs):
        m.set_transform("t2", T((2.7, 0, 0)))
    assert ours.min_distance_internal() == pytest.approx(theirs.min_distance_internal(), abs=1e-9)
    other = pycinder.CollisionManager()
    other.add_object("t1", torus, T((0, 0, 2)))
    d, names, data = ours.min_distance_other(other, return_names=True, return_data=True)
    assert names == ("t1", "t1") and data.names == {"t1"}
    assert d == pytest.approx(2.0 - 0.6, abs=0.01)


ANALYTIC = {
    # name: meshes, transforms, true normal (from the first into the second), true depth
    "sphere-box": ([trimesh.creation.box((2, 2, 2)), trimesh.creation.icosphere(4, 0.5)],
                   [np.eye(4), T((0, 1.45, 0))], (0, 1, 0), 0.05),
    "sphere-sphere": ([trimesh.creation.icosphere(4, 0.5), trimesh.creation.icosphere(4, 0.5)],
                      [np.eye(4), T((0.9, 0, 0))], (1, 0, 0), 0.1),
    "box-edge-on-slab": ([trimesh.creation.box((4, 0.5, 4)), trimesh.creation.box((1, 1, 1))],
                         [np.eye(4), T((0, 0.25 + np.sqrt(0.5) - 0.05, 0)) @ R(np.pi / 4, (0, 0, 1))],
                         (0, 1, 0), 0.05),
    "capsule-on-slab": ([trimesh.creation.box((4, 0.5, 4)),
                         trimesh.creation.capsule(height=1.0, radius=0.2, count=[32, 32])],
                        [np.eye(4), T((0, 0.25 + 0.2 - 0.04, 0))], (0, 1, 0), 0.04),
    "boxes-face-to-face": ([trimesh.creation.box((1, 1, 1)), trimesh.creation.box((1, 1, 1))],
                           [np.eye(4), T((0.93, 0.2, 0.1))], (1, 0, 0), 0.07),
}


@pytest.mark.parametrize("name", list(ANALYTIC))
def test_contact_accuracy_against_analytic_pairs(name):
    """One contact per region; normal within 10 degrees, depth within 10% plus a tolerance."""
    meshes, transforms, normal, depth = ANALYTIC[name]
    tol = 0.005
    ours = pycinder.CollisionManager(tolerance=tol)
    ours.add_object("first", meshes[0], transforms[0])
    ours.add_object("second", meshes[1], transforms[1])
    hit, data = ours.in_collision_internal(return_data=True)
    assert hit and len(data) == 1
    c = data[0]
    n = np.asarray(normal, float) * (1 if c.pair == ("first", "second") else -1)
    angle = np.degrees(np.arccos(np.clip(np.dot(c.normal, n), -1, 1)))
    assert angle < 10, angle
    assert abs(c.depth - depth) < 0.1 * depth + tol, c.depth
    world = [m.copy().apply_transform(t) for m, t in zip(meshes, transforms)]
    inside = [trimesh.proximity.signed_distance(w, [c.point])[0] for w in world]
    assert min(inside) > -tol  # the point is on the intersection


def test_return_data_asks_for_contacts_and_stays_trimesh_s(monkeypatch):
    """The manager asks its detector for contacts explicitly (contacts=True with return_data,
    pairs only without), and its ContactData are those contacts, named, as before: a unit box and
    a ball of radius 0.4 at x = 0.6 overlap by exactly 0.3 along +x, at one region."""
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.4)
    tol = 0.005
    ours = pycinder.CollisionManager(tolerance=tol)
    ours.add_object("box", box)
    ours.add_object("ball", ball, T((0.6, 0, 0)))
    asked = []
    find = pycinder.Detector.find_collisions
    monkeypatch.setattr(pycinder.Detector, "find_collisions",
                        lambda self, *a, **k: asked.append(dict(k)) or find(self, *a, **k))
    hit, names, data = ours.in_collision_internal(return_names=True, return_data=True)
    assert asked[-1].get("contacts") is True and "records" not in asked[-1]
    assert (hit, names) == (True, {("ball", "box")})
    assert len(data) == 1 and isinstance(data[0], pycinder.ContactData)
    c = data[0]
    assert c.names == {"box", "ball"} and c.pair == ("box", "ball")
    assert np.degrees(np.arccos(np.clip(c.normal @ [1, 0, 0], -1, 1))) < 10
    assert abs(c.depth - 0.3) < 0.03 + tol
    world = [box, ball.copy().apply_translation((0.6, 0, 0))]
    assert min(trimesh.proximity.signed_distance(w, [c.point])[0] for w in world) > -tol
    assert -1 <= c.index("box") < 12 and -1 <= c.index("ball") < len(ball.faces)
    # the same contacts as the detector's own, asked for with the query
    det = pycinder.Detector(tolerance=tol)
    direct = find(det, [box, ball], np.stack([np.eye(4), T((0.6, 0, 0))]),
                  names=["box", "ball"], contacts=True).contacts()
    assert [repr(d) for d in direct] == [repr(d) for d in data]
    # pairs only, without return_data; the probe and the other manager ask for contacts too
    assert ours.in_collision_internal(return_names=True) == (True, {("ball", "box")})
    hit, data = ours.in_collision_single(ball, T((0.6, 0, 0)), return_data=True)
    assert asked[-1].get("contacts") is True and hit
    assert {frozenset(d.names) for d in data} == {frozenset({"box", EXTERNAL}),
                                                 frozenset({"ball", EXTERNAL})}
    with pytest.raises(TypeError, match="'contacts'"):
        pycinder.CollisionManager(contacts=True)


def test_scene_to_collision():
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box((1, 1, 1)), node_name="box")
    scene.add_geometry(trimesh.creation.icosphere(radius=0.3), node_name="ball",
                       transform=T((0.6, 0, 0)))
    manager, objects = pycinder.scene_to_collision(scene)
    assert set(objects) == {"box", "ball"}
    assert manager.in_collision_internal(return_names=True) == (True, {("ball", "box")})

"""The focused strategy against exact geometry: dense scenes, nested solids, non-convex shapes,
deforming meshes, and the machinery (rounds, retries, record modes) that must not change answers."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing.scenes import ManyBodies
from pycinder.contacts import reduce_contacts
from pycinder.focused.frame.frames import FocusedFrames
from pycinder.testing import bunny as load_bunny
from pycinder.testing import ground_truth, nested_scene, random_scene
from pycinder.focused.plan.plan_numpy import FLAG_SKIP_IF_HIT

from conftest import assert_matches_truth

T = trimesh.transformations.translation_matrix


@pytest.mark.parametrize("n,seed", [(60, 31), (60, 32), (120, 5)])
def test_dense_scenes_full_recall(detector, n, seed):
    """Random scenes, a third full: every pair that must be found, and no separate pair."""
    meshes, transforms = random_scene(n, seed)
    truth = ground_truth(meshes, transforms)
    assert len(truth.overlap) > n // 2
    assert_matches_truth(detector.find_collisions(meshes, transforms).pairs, truth,
                         context=f"{n} bodies, seed {seed}")


def test_thousand_small_bodies_full_recall(detector):
    scene = ManyBodies(1000, 1, seed=1)
    verts, transforms = scene.frame(0)
    meshes = [trimesh.Trimesh(v, f, process=False) for v, f in zip(verts, scene.faces)]
    truth = ground_truth(meshes, list(transforms))
    assert len(truth.overlap) > 1000
    result = detector.find_collisions(meshes, transforms)
    assert_matches_truth(result.pairs, truth, context="1000 bodies")


def test_nested_solid_without_surface_crossing(detector):
    meshes, transforms = nested_scene()
    truth = ground_truth(meshes, transforms)
    assert truth.overlap.tolist() == [[0, 1]]
    result = pycinder.Detector(records="all").find_collisions(meshes, transforms)
    assert result.pairs.tolist() == [[0, 1]]
    # Every sample is the small sphere inside the box, never the other way round.
    assert set(result.records["penetrating"].tolist()) == {1}
    assert set(result.records["penetrated"].tolist()) == {0}


def test_rod_through_torus_hole(detector):
    """Non-convex: a rod through a torus's hole touches nothing; moved onto the tube, it does."""
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    rod = trimesh.creation.cylinder(radius=0.3, height=4.0)
    assert ground_truth([torus, rod]).separate.tolist() == [[0, 1]]
    assert detector.find_collisions([torus, rod]).pairs.tolist() == []
    shifted = [np.eye(4), T((0.75, 0, 0))]
    assert ground_truth([torus, rod], shifted).overlap.tolist() == [[0, 1]]
    assert detector.find_collisions([torus, rod], shifted).pairs.tolist() == [[0, 1]]


def test_near_misses_at_the_default_tolerance(detector):
    """Balls in torus holes 3% of their size from the tube (three default tolerances): never
    reported; pushed onto the tube, always."""
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.25)
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    meshes, apart, touching = [], [], []
    for k in range(4):
        meshes += [torus, ball]
        axis = np.array([np.cos(k), np.sin(k), 0.0])
        r = 1.0 - 0.25 - 0.5 - 0.03 * (k + 1)
        apart += [T((5 * k, 0, 0)), T(np.array([5 * k, 0, 0]) + r * axis)]
        touching += [T((5 * k, 0, 0)), T(np.array([5 * k, 0, 0]) + 0.3 * axis)]
    truth = ground_truth(meshes, apart)
    assert len(truth.separate) == len(truth.overlap) + len(truth.separate) + len(truth.ambiguous)
    assert detector.find_collisions(meshes, apart).pairs.tolist() == []
    truth = ground_truth(meshes, touching)
    assert len(truth.overlap) == 4
    assert_matches_truth(detector.find_collisions(meshes, touching).pairs, truth)


def test_answer_independent_of_scene_extent_and_neighbours(detector):
    """A pair's answer and its tiles do not change with what else is in the scene or where."""
    a, b = trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)
    pair = [np.eye(4), T((0.87, 0.1, 0.05))]
    alone = detector.find_collisions([a, b], pair)
    far = [T((1e6, -3e5, 2e5)) @ t for t in pair]
    crowd_meshes, crowd = random_scene(40, 3, size=0.2)
    crowd = [T((40, 0, 0)) @ t for t in crowd]
    shifted = detector.find_collisions([a, b] + crowd_meshes, far + crowd)
    assert alone.pairs.tolist() == [[0, 1]]
    assert [0, 1] in shifted.pairs.tolist()

    def windows(result):
        """The tiles covering the pair's window (a plan as small as ``alone`` is not probed
        first, see ``tiles.PROBE_PLAN``; in a larger one, the probe comes on top of them)."""
        tiles = result.tiles
        mine = (tiles.bodies == [0, 1]).all(axis=1)
        pieces = mine & (tiles.flags & FLAG_SKIP_IF_HIT != 0)
        cover = pieces if pieces.any() else mine
        return sorted(map(tuple, tiles.window[cover, 2:].tolist())), set(tiles.pixel[cover])

    assert windows(alone) == windows(shifted)


def test_a_body_without_partner_is_never_drawn():
    bun = load_bunny()
    ball = trimesh.creation.icosphere(radius=0.02)
    det = pycinder.Detector()
    far = det.find_collisions([bun, ball], [np.eye(4), T((5, 0, 0))])
    assert far.stats.candidates == 0 and far.stats.triangles == 0
    # Touching the bunny at one spot draws that spot, not the bunny.
    top = bun.vertices[np.argmax(bun.vertices[:, 1])]
    near = det.find_collisions([bun, ball], [np.eye(4), T(top)])
    assert near.pairs.tolist() == [[0, 1]]
    assert 0 < near.stats.triangles < 0.05 * len(bun.faces)


def test_two_bunnies_touching_at_an_ear_draw_the_ear():
    bun = load_bunny()
    ear = bun.vertices[np.argmax(bun.vertices[:, 1])]
    flip = trimesh.transformations.rotation_matrix(np.pi, (0, 0, 1), point=ear)
    # The second bunny upside down, its ear tip on the first one's, pushed in a little.
    second = T((0, -0.004, 0)) @ flip
    det = pycinder.Detector(records="all")
    result = det.find_collisions([bun, bun], [np.eye(4), second])
    truth = ground_truth([bun, bun], [np.eye(4), second])
    assert_matches_truth(result.pairs, truth)
    assert result.stats.triangles < 0.02 * 2 * len(bun.faces)


def test_deforming_mesh_normals_follow_the_vertices():
    """encode="normal": the normals in the records are those of this frame's vertices, even when
    the same face array comes back with new vertices."""
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    box = trimesh.creation.box((1, 1, 1))
    faces = np.array(ball.faces)
    det = pycinder.Detector(encode="normal", records="all")
    for k, shear in enumerate((0.0, 0.8)):  # frame 2: same faces, new vertices
        m = np.eye(3)
        m[0, 1] = shear  # a shear changes the face normals
        verts = np.array(ball.vertices) @ m.T
        result = det.find_collisions([(verts, faces), box], [T((0.7, 0, 0)), np.eye(4)])
        rec = result.records[result.records["penetrating"] == 0]
        surface = rec[rec["face"] >= 0]
        assert len(surface) > 10
        current = trimesh.Trimesh(verts, faces, process=False).face_normals
        cos = np.einsum("ij,ij->i", surface["normal"], current[surface["face"]])
        assert cos.min() > 0.9999, (k, cos.min())
        edges = rec[rec["edge"] >= 0]
        assert len(edges) and np.all(np.abs(np.linalg.norm(edges["normal"], axis=1) - 1) < 1e-4)


def test_deforming_in_place_is_seen_and_only_changed_shapes_upload():
    det = pycinder.Detector()
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    verts = np.array(ball.vertices) + [0.6, 0, 0]
    bodies = [(np.array(box.vertices), np.array(box.faces)), (verts, np.array(ball.faces))]
    first = det.find_collisions(bodies)
    assert first.pairs.tolist() == [[0, 1]]
    assert det.find_collisions(bodies).stats.uploaded_vertex_bytes == 0
    verts += [1.0, 0, 0]  # in place: now 0.8 apart
    moved = det.find_collisions(bodies)
    assert moved.pairs.tolist() == []
    verts -= [1.0, 0, 0]
    again = det.find_collisions(bodies)
    assert again.pairs.tolist() == [[0, 1]]
    assert again.stats.uploaded_vertex_bytes == verts.shape[0] * 12


def test_memory_rounds_give_the_same_answer():
    meshes, transforms = random_scene(60, 31)
    roomy = pycinder.Detector().find_collisions(meshes, transforms)
    tight = pycinder.Detector(memory_budget=2**20).find_collisions(meshes, transforms)
    assert tight.stats.rounds > roomy.stats.rounds
    assert tight.pairs.tolist() == roomy.pairs.tolist()
    assert_matches_truth(tight.pairs, ground_truth(meshes, transforms), context="tight budget")


def test_full_pixel_lists_are_retried_in_thinner_boxes():
    """With room for only two crossings per pixel, pixels overflow; their tiles are cut along the
    view until decided, and the answer is the same."""
    meshes, transforms = random_scene(20, 21)
    normal = pycinder.Detector(records="all").find_collisions(meshes, transforms)
    det = pycinder.Detector(records="all")
    det.strategy.frames = FocusedFrames(det.gpu, list_capacity=2)
    det.strategy.budget_pixels //= 4
    squeezed = det.find_collisions(meshes, transforms)
    assert squeezed.stats.undecided > 0 and squeezed.stats.retries > 0
    assert squeezed.stats.possibly_lost == 0
    assert squeezed.pairs.tolist() == normal.pairs.tolist()
    assert_matches_truth(squeezed.pairs, ground_truth(meshes, transforms), context="retried")
    # Records of every attempt name their own tile in the plan the result carries: the tile's
    # pair is the record's pair, and the tile's frame puts the record's pixel at its point.
    rec, tiles = squeezed.records, squeezed.tiles
    assert len(tiles) == squeezed.stats.tiles
    tile_pairs = np.sort(tiles.bodies[rec["view"]], axis=1)
    rec_pairs = np.sort(np.c_[rec["penetrating"], rec["penetrated"]], axis=1)
    assert (tile_pairs == rec_pairs).all()
    # A retried tile's records come once: the same samples as without retries, per body pair
    # and edge or face, at the same points (within a pixel: an edge is sampled from where it
    # enters the thinner box).
    def samples(r):
        return np.unique(np.c_[r["penetrating"], r["penetrated"], r["edge"], r["face"]], axis=0,
                         return_counts=True)

    assert len(rec) == len(normal.records)
    for mine, theirs in zip(samples(rec), samples(normal.records)):
        assert np.array_equal(mine, theirs)
    cKDTree = pytest.importorskip("scipy.spatial", reason="scipy (the test extra) measures "
                                  "the gaps").cKDTree
    gap = cKDTree(normal.records["point"]).query(rec["point"])[0]
    assert gap.max() < squeezed.stats.tolerance[0]
    points = tiles.to_world(rec["view"], rec["pixel_x"] + 0.5, rec["pixel_y"] + 0.5, rec["pixel_z"])
    assert np.allclose(points, rec["point"], atol=1e-6 * np.abs(rec["point"]).max())
    contacts = reduce_contacts(squeezed.records, squeezed.scene, squeezed.tiles)
    assert sorted(map(tuple, np.unique(contacts.pair, axis=0).tolist())) == \
        sorted(map(tuple, squeezed.pairs.tolist()))
    assert np.allclose(np.linalg.norm(contacts.normal, axis=1), 1.0)


def test_record_modes_agree_on_pairs_and_records_lie_where_they_say():
    meshes, transforms = random_scene(20, 22)
    results = {m: pycinder.Detector(records=m).find_collisions(meshes, transforms)
               for m in ("found", "all", "none")}
    pairs = {m: r.pairs.tolist() for m, r in results.items()}
    assert pairs["found"] == pairs["all"] == pairs["none"]
    assert_matches_truth(results["found"].pairs, ground_truth(meshes, transforms))
    assert len(results["none"].records) == 0
    assert 0 < len(results["found"].records) <= len(results["all"].records)
    result = results["all"]
    rec = result.records
    ends = result.edge_vertices()
    world = [m.copy().apply_transform(t) for m, t in zip(meshes, transforms)]
    tol = results["all"].stats.tolerance[1]
    rng = np.random.default_rng(0)
    for i in rng.choice(len(rec), size=min(300, len(rec)), replace=False):
        r = rec[i]
        inside = trimesh.proximity.signed_distance(world[r["penetrated"]], [r["point"]])[0]
        pen = world[r["penetrating"]]
        if r["face"] >= 0:
            # A surface sample: on the penetrating surface, inside the other body. Its depth is
            # the one the rasterizer interpolated at the pixel centre over the face with its
            # vertices snapped to the sub-pixel grid: that moves the face by at most half a grid
            # step in x and in y, sqrt(2) * 2**-9 pixels with the 8 bits of Vulkan, D3D12 and
            # Metal hardware (lavapipe's too), and a point of a plane moved sideways by d lies
            # at most d from it, whatever its slope. The list keeps the depth with its 2 low
            # bits cleared: 4 ulps of a depth of at most 2**8 pixels, 2**-13 of a pixel more.
            # (An H100 put one 1.1e-3 tolerances from the surface.)
            snap = (2**0.5 * 2**-9 + 2**-13) * tol
            assert inside > -snap
            assert abs(trimesh.proximity.signed_distance(pen, [r["point"]])[0]) < snap
        else:
            # an edge sample: inside, at most half a pixel's diagonal from its edge
            assert inside > -1e-4 * tol
            a, b = pen.vertices[ends[i]]
            s = np.clip(np.dot(r["point"] - a, b - a) / np.dot(b - a, b - a), 0, 1)
            assert np.linalg.norm(a + s * (b - a) - r["point"]) < 0.72 * tol


def test_stats_say_what_was_done(detector):
    meshes, transforms = random_scene(20, 21)
    st = detector.find_collisions(meshes, transforms).stats
    assert st.strategy == "focused" and st.bodies == 20
    assert st.candidates >= st.tiles // 4 > 0 and st.pixels > 0 and st.triangles > 0
    assert 0 < st.tolerance[0] <= st.tolerance[1]
    assert st.possibly_lost == 0 and st.bytes_read > 0
    for stage in ("validate", "broad phase", "tiles", "gpu", "total"):
        assert stage in st.wall_ms


def test_a_large_window_left_unprobed_goes_in_pieces():
    """In a plan small enough that only dense pairs are probed, a pair of few faces whose window
    is taller than a tile (two boxes in the same place) goes whole into the first phase: cut
    into tiles, not placed as one tile taller than the atlas's bands (which raised IndexError)."""
    sphere = trimesh.creation.icosphere(subdivisions=4)   # 5,120 faces: a dense pair
    box = trimesh.creation.box((1, 1, 1))
    moves = [np.eye(4) for _ in range(4)]
    moves[1][0, 3], moves[2][0, 3], moves[3][0, 3] = 1.95, 10.0, 10.0
    result = pycinder.find_collisions([sphere, sphere, box, box], moves, tolerance=1 / 140)
    assert result.pairs.tolist() == [[0, 1], [2, 3]]
    assert (result.tiles.window[:, 3] <= 128).all()

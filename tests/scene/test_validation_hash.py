"""Content-addressed reuse of shapes (scene/bodies.py): vertex arrays are keyed by a 128-bit XXH3
hash of their bytes and a hit is confirmed against a copy of the bytes, so edits in place of any
dtype are seen, equal content in a new array reuses the uploaded shape, and a hash collision
makes a new shape, never a wrong one."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.scene import bodies as scene_bodies
from pycinder.scene.bodies import ShapeCache

BOX = trimesh.creation.box((1.0, 1.0, 1.0))
DTYPES = [np.float32, np.float64, np.int64, np.int32, np.float16]


def move(x=0.0):
    m = np.eye(4)
    m[0, 3] = x
    return m


def two_unit_box(dtype):
    return (np.asarray(BOX.vertices) * 2).astype(dtype), np.asarray(BOX.faces)


@pytest.fixture(scope="module")
def det():
    return pycinder.Detector()


@pytest.mark.parametrize("dtype", DTYPES)
def test_an_edit_in_place_of_any_dtype_makes_a_new_shape(dtype):
    v, f = two_unit_box(dtype)
    cache = ShapeCache()
    first = cache.get(v, f, "body 0", False)
    assert cache.get(v, f, "body 0", False) is first          # unchanged: reused
    v[3, 1] += 1                                               # one coordinate of one vertex
    second = cache.get(v, f, "body 0", False)
    assert second is not first
    assert second.hi[1] - second.lo[1] == pytest.approx(3.0)   # the new vertex, measured


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.int64])
def test_an_edit_in_place_changes_the_answer_and_is_uploaded(det, dtype):
    v, f = two_unit_box(dtype)                                 # x in [-1, 1]
    poses = [move(), move(2.0)]                                # the unit box: x in [1.5, 2.5]
    assert det.find_collisions([(v, f), BOX], poses).pairs.tolist() == []
    corner = int(np.argmax(v[:, 0] + v[:, 1] + v[:, 2]))     # one vertex only
    was = v[corner].copy()
    v[corner] = (3, 0, 0)                                      # a spike through the box
    hit = det.find_collisions([(v, f), BOX], poses)
    assert hit.pairs.tolist() == [[0, 1]]
    assert hit.stats.uploaded_vertex_bytes > 0
    v[corner] = was                                            # back as it was
    assert det.find_collisions([(v, f), BOX], poses).pairs.tolist() == []


@pytest.mark.parametrize("dtype", DTYPES)
def test_equal_content_in_a_new_array_reuses_the_uploaded_shape(det, dtype):
    v, f = two_unit_box(dtype)
    poses = [move(), move(1.5)]
    first = det.find_collisions([(v, f), BOX], poses)
    again = det.find_collisions([(v.copy(), f.copy()), BOX], poses)
    assert first.pairs.tolist() == again.pairs.tolist() == [[0, 1]]
    assert again.stats.uploaded_vertex_bytes == 0
    assert det.shapes.get(np.array(v, order="F"), f, "body 0", False) \
        is det.shapes.get(v.copy(), f, "body 0", False)       # layout is not content


def test_the_same_values_in_another_dtype_are_another_key():
    v, f = two_unit_box(np.float64)
    cache = ShapeCache()
    a = cache.get(v, f, "body 0", False)
    b = cache.get(v.astype(np.float32), f, "body 0", False)
    assert a is not b                                          # keyed by bytes and dtype
    np.testing.assert_array_equal(a.vertices, b.vertices)      # the same shape all the same


@pytest.fixture
def colliding(monkeypatch):
    """Every array hashes to the same 128 bits."""
    monkeypatch.setattr(scene_bodies, "_digest", lambda data: b"\0" * 16)


def test_a_forced_hash_collision_makes_a_new_shape(colliding):
    v, f = two_unit_box(np.float64)
    w = v * 1.5
    cache = ShapeCache()
    a = cache.get(v, f, "body 0", False)
    b = cache.get(w, f, "body 1", False)
    assert b is not a
    np.testing.assert_allclose(b.hi - b.lo, 3.0)               # w's, not v's
    assert cache.get(v.copy(), f, "body 0", False) is not b    # and back: measured again


def test_a_forced_hash_collision_within_one_query_keeps_both_shapes(colliding):
    v, f = two_unit_box(np.float64)                            # x in [-1, 1]
    w = v.copy()
    w[:, 0] += 2.5                                             # x in [1.5, 3.5]
    poses = [move(), move(0.0), move(1.1)]                     # the unit box: x in [0.6, 1.6]
    det = pycinder.Detector()
    found = det.find_collisions([(v, f), (w, f), BOX], poses).pairs.tolist()
    assert sorted(map(sorted, found)) == [[0, 2], [1, 2]]
    w[:, 0] += 0.5                                             # the box no longer touches it
    assert det.find_collisions([(v, f), (w, f), BOX], poses).pairs.tolist() == [[0, 2]]


def test_a_forced_collision_edited_in_place_is_still_seen(colliding, det):
    v, f = two_unit_box(np.int64)
    poses = [move(), move(2.0)]
    assert det.find_collisions([(v, f), BOX], poses).pairs.tolist() == []
    v[:, 0] += 1
    assert det.find_collisions([(v, f), BOX], poses).pairs.tolist() == [[0, 1]]


def test_the_kept_copy_is_counted_and_dropped():
    """A shape keeps a copy of the bytes it was made from, counted in the cache's bytes, until
    it is dropped; a body whose vertices change from query to query at the same place keeps none
    from its second change on (it is not hashed, see ShapeCache.get_many)."""
    v, f = two_unit_box(np.float64)
    w = v * 3
    cache = ShapeCache()
    for k in range(4):                                         # body 1 deforms, 4 frames
        cache.begin_query()
        cache.get_many([(w, f, "body 0"), (v + k, f, "body 1")], False)
        cache.end_query()
    assert len(cache) == 3                                     # body 0's, body 1's last two
    assert cache.nbytes == sum(s.nbytes for s in cache._entries.values()) + w.nbytes
    for k in range(2):                                         # body 1 stops deforming
        cache.begin_query()
        cache.get_many([(w, f, "body 0"), (v + 3, f, "body 1")], False)
        cache.end_query()
    assert len(cache) == 2                                     # one shape per body
    assert cache.nbytes == sum(s.nbytes for s in cache._entries.values()) + 2 * w.nbytes


def test_bad_vertices_are_still_named(det):
    v, f = two_unit_box(np.float64)
    v[5, 2] = np.nan
    with pytest.raises(ValueError, match=r"body 1 \('lid'\): 1 vertex is NaN or infinite "
                                         r"\(first: vertex 5"):
        det.find_collisions([BOX, (v, f)], [move(), move()], names=["base", "lid"])

"""Bodies whose vertices change from query to query: new arrays every frame, one array edited in
place (of any dtype, contiguous or not), through a list of bodies and through
PreparedBodies.update. The answers are scored against exact geometry every frame, and the checks
are those of new bodies: bad vertices named, changed faces validated again."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.scene import bodies as scene_bodies
from pycinder.scene.bodies import world_boxes
from pycinder.testing import ground_truth, random_rotation

BALL = trimesh.creation.icosphere(subdivisions=3, radius=0.5)     # 642 vertices
BIG_BALL = trimesh.creation.icosphere(subdivisions=5, radius=0.5)  # 10,242 vertices, 123 kB
BOX = trimesh.creation.box((1.0, 1.0, 1.0))
SCALES = (1.0, 1.25, 0.9, 1.3, 1.0, 1.2, 0.95)
"""The ball's scale frame by frame: its surface reaches x = 0.5 * scale, the box's face is at
x = 0.55 (0.05 apart at 1.0, 0.075 deep at 1.25)."""


def poses(n_pairs: int = 1) -> np.ndarray:
    """Ball 2k at (0, 3k, 0), box 2k + 1 beside it at x = 1.05."""
    out = np.tile(np.eye(4), (2 * n_pairs, 1, 1))
    out[0::2, 1, 3] = out[1::2, 1, 3] = 3.0 * np.arange(n_pairs)
    out[1::2, 0, 3] = 1.05
    return out


def check(result, meshes, transforms) -> None:
    """Every pair exact geometry says must collide is found, and none that is apart."""
    truth = ground_truth(meshes, list(transforms))
    found = {tuple(p) for p in result.pairs.tolist()}
    assert {tuple(p) for p in truth.overlap.tolist()} <= found
    assert not found & {tuple(p) for p in truth.separate.tolist()}


@pytest.fixture
def digests(monkeypatch):
    """The sizes of the arrays hashed for the shape cache."""
    sizes: list[int] = []
    real = scene_bodies._digest
    monkeypatch.setattr(scene_bodies, "_digest",
                        lambda data: sizes.append(memoryview(data).nbytes) or real(data))
    return sizes


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_new_arrays_every_frame_follow_the_geometry_unhashed(digests, dtype):
    """A body given new vertices every frame is hashed while it might be rigid (its first two
    frames), then measured without a hash; when it stops changing it keeps its shape (nothing
    uploaded again) and is hashed again."""
    det = pycinder.Detector()
    rest, faces = np.asarray(BALL.vertices), np.asarray(BALL.faces)
    ball_bytes = rest.astype(dtype).nbytes
    for k, s in enumerate(SCALES):
        meshes = [((rest * s).astype(dtype), faces), BOX]
        result = det.find_collisions(meshes, poses())
        check(result, meshes, poses())
        assert result.pairs.tolist() == ([[0, 1]] if s > 1.1 else [])
        hashed = digests.count(ball_bytes)
        assert hashed == min(k + 1, 2), k
    for k in range(3):                                       # new arrays, the same vertices
        result = det.find_collisions([((rest * SCALES[-1]).astype(dtype), faces), BOX], poses())
        assert result.pairs.tolist() == []
        assert result.stats.uploaded_vertex_bytes == 0
    assert digests.count(ball_bytes) == 2 + 3                # hashed again, every frame


def _layouts(rest: np.ndarray) -> dict:
    """The same vertices in arrays of several dtypes and layouts, each edited in place."""
    strided = np.zeros((len(rest), 4))
    strided[:, :3] = rest
    return {"float64": rest.copy(), "float32": rest.astype(np.float32),
            "float64 columns of a wider array": strided[:, :3],
            "float32 Fortran order": np.asfortranarray(rest, dtype=np.float32),
            "int64 (a scaled grid)": np.round(rest * 1000).astype(np.int64)}


@pytest.mark.parametrize("layout", ["float64", "float32", "float64 columns of a wider array",
                                    "float32 Fortran order", "int64 (a scaled grid)"])
@pytest.mark.parametrize("prepared", [False, True])
def test_an_array_edited_in_place_every_frame_is_seen(layout, prepared):
    det = pycinder.Detector()
    rest, faces = np.asarray(BIG_BALL.vertices), np.asarray(BIG_BALL.faces)
    v = _layouts(rest)[layout]
    unit = 1000.0 if v.dtype.kind == "i" else 1.0
    transforms = poses()
    transforms[0] = np.diag([1 / unit] * 3 + [1.0])          # the grid back to metres
    bodies = det.prepare([(v, faces), BOX]) if prepared else [(v, faces), BOX]
    for s in SCALES:
        v[...] = rest * s * unit if v.dtype.kind == "f" else np.round(rest * s * unit)
        if prepared:
            bodies.update(0, v)
        result = det.find_collisions(bodies, transforms)
        check(result, [(np.array(v, np.float64), faces), BOX], transforms)
        assert result.pairs.tolist() == ([[0, 1]] if s > 1.1 else [])


def test_faces_edited_in_place_are_validated_again():
    """The faces of a deforming box, edited in place into a tetrahedron (and rows that repeat a
    vertex): the new topology is built and reported on, and the answer is its own."""
    det = pycinder.Detector()
    faces = np.array(BOX.faces)
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    corner = np.eye(4)
    corner[:3, 3] = 0.45                                     # in the box, off the tetrahedron
    transforms = np.stack([np.eye(4), corner])
    for s in (1.0, 1.01, 1.02):                              # the box deforms: new arrays
        meshes = [(np.asarray(BOX.vertices) * s, faces), ball]
        assert det.find_collisions(meshes, transforms).pairs.tolist() == [[0, 1]]
    # The tetrahedron of corners 0, 3, 5 and 6 (x + y + z <= 0.5), wound outwards.
    tetra = trimesh.Trimesh(np.asarray(BOX.vertices)[[0, 3, 5, 6]], [[0, 1, 2], [0, 2, 3],
                                                                      [0, 3, 1], [1, 3, 2]])
    tetra.fix_normals()
    faces[:4] = np.array([0, 3, 5, 6])[tetra.faces]
    faces[4:] = [0, 0, 3]                                    # repeated vertex: dropped
    meshes = [(np.asarray(BOX.vertices) * 1.02, faces), ball]
    with pytest.warns(pycinder.DegenerateFaceWarning, match="8 faces repeat a vertex index"):
        result = det.find_collisions(meshes, transforms)
    assert result.pairs.tolist() == []
    check(result, [(np.asarray(BOX.vertices) * 1.02, faces[:4]), ball], transforms)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_bad_vertices_of_a_deforming_body_are_named(bad):
    det = pycinder.Detector()
    rest, faces = np.asarray(BALL.vertices), np.asarray(BALL.faces)
    for s in (1.0, 1.1, 1.2):                                # unhashed from here on
        det.find_collisions([BOX, (rest * s, faces)], poses()[::-1], names=["box", "ball"])
    broken = rest * 1.3
    broken[7, 1] = bad
    with pytest.raises(ValueError, match=r"body 1 \('ball'\): 1 vertex is NaN or infinite "
                                         r"\(first: vertex 7"):
        det.find_collisions([BOX, (broken, faces)], poses()[::-1], names=["box", "ball"])
    bodies = det.prepare([BOX, (rest, faces)], names=["box", "ball"])
    with pytest.raises(ValueError, match=r"body 1 \('ball'\): 1 vertex is NaN"):
        bodies.update(1, broken)
    assert det.find_collisions([BOX, (rest * 1.3, faces)], poses()[::-1]).pairs.tolist() \
        == [[0, 1]]                                          # and the next query answers


def test_results_keep_their_vertices_while_memory_is_reused():
    """New shapes' vertices reuse memory that no shape, result or view refers to any more, and
    never memory that one does."""
    det = pycinder.Detector()
    rest, faces = np.asarray(BIG_BALL.vertices), np.asarray(BIG_BALL.faces)
    bodies = det.prepare([(rest, faces), BOX])
    kept, views = [], []
    for k in range(12):
        s = SCALES[k % len(SCALES)]
        bodies.update(0, rest * s)
        result = det.find_collisions(bodies, poses())
        assert result.pairs.tolist() == ([[0, 1]] if s > 1.1 else [])
        if k < 3:                                            # kept: their memory stays theirs
            shape = bodies.shapes[bodies.body_shape[0]]
            kept.append((shape, (rest * s - shape.offset).astype(np.float32)))
            views.append((shape.vertices[5:9], shape.vertices[5:9].copy()))
    for shape, want in kept:
        assert np.array_equal(shape.vertices, want)
    for view, want in views:
        assert np.array_equal(view, want)
    arrays = det.shapes.memory._kept[len(rest)]
    assert len(arrays) < 10                                  # not a new array every frame


def test_world_boxes_need_no_bounding_sphere_where_it_cannot_tighten_them():
    """World boxes with the half diagonal in place of the bounding sphere where a sphere cannot
    be tighter (bodies moved, mirrored or turned by quarter turns) equal those with the
    sphere, bit for bit; a body that is only moved is never measured for its sphere."""
    rng = np.random.default_rng(3)
    meshes = [BIG_BALL, BOX, trimesh.creation.cylinder(0.2, 1.5), BALL]
    transforms = []
    for k in range(24):
        t = np.eye(4)
        if k % 4 == 1:
            t[:3, :3] = random_rotation(rng)[:3, :3] * rng.uniform(0.2, 3.0)
        elif k % 4 == 2:
            t[:3, :3] = np.diag(rng.choice([-1.0, 1.0], 3) * rng.uniform(0.2, 3.0, 3))
        elif k % 4 == 3:
            t[:3, :3] = np.eye(3)[rng.permutation(3)] * rng.choice([-1.0, 1.0], 3)
        t[:3, 3] = rng.uniform(-5, 5, 3)
        transforms.append(t)
    bodies = [meshes[k % 4] for k in range(24)]
    det = pycinder.Detector()
    moved = det.prepare([BIG_BALL, BOX]).scene(np.tile(np.eye(4), (2, 1, 1)))
    moved.world_boxes()
    assert moved.shapes[0]._radius is None                  # never measured
    scene = det.prepare(bodies).scene(np.array(transforms))
    lo, hi = scene.world_boxes()
    want = world_boxes(scene.local_lo, scene.local_hi, scene.radius, scene.transforms)
    assert np.array_equal(lo, want[0]) and np.array_equal(hi, want[1])

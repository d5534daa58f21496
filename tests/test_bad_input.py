"""Bad input gets a clear error naming the body and the problem; warnings point at the caller."""

import warnings

import numpy as np
import pytest
import trimesh
import wgpu
from hypothesis import given, settings
from hypothesis import strategies as st

import pycinder
from pycinder.gpu import device as gpu_device


@pytest.fixture(scope="module")
def det() -> pycinder.Detector:
    return pycinder.Detector()


def box_arrays():
    b = trimesh.creation.box((1, 1, 1))
    return np.array(b.vertices), np.array(b.faces)


@settings(max_examples=25, deadline=None)
@given(vertex=st.integers(0, 7), axis=st.integers(0, 2),
       value=st.sampled_from([np.nan, np.inf, -np.inf]), body=st.integers(0, 2))
def test_nan_or_inf_vertices_name_the_body(det, vertex, axis, value, body):
    bodies = [box_arrays() for _ in range(3)]
    v, f = bodies[body]
    v[vertex, axis] = value
    with pytest.raises(ValueError, match=rf"body {body}\b.*NaN or infinite.*vertex {vertex}"):
        det.find_collisions(bodies)


@settings(max_examples=25, deadline=None)
@given(i=st.integers(0, 3), j=st.integers(0, 3), value=st.sampled_from([np.nan, np.inf]),
       body=st.integers(0, 1))
def test_nan_transform_names_the_body(det, i, j, value, body):
    t = [np.eye(4), np.eye(4)]
    t[body][i, j] = value
    with pytest.raises(ValueError, match=rf"body {body}\b.*transform.*NaN"):
        det.find_collisions([box_arrays(), box_arrays()], t)


@settings(max_examples=25, deadline=None)
@given(bad=st.one_of(st.integers(8, 10_000), st.integers(-10_000, -1)), face=st.integers(0, 11),
       corner=st.integers(0, 2))
def test_face_index_out_of_range(det, bad, face, corner):
    v, f = box_arrays()
    f[face, corner] = bad
    with pytest.raises(ValueError, match=r"body 1\b.*out of range.*8 vertices"):
        det.find_collisions([box_arrays(), (v, f)])


def test_degenerate_face_repeating_a_vertex_is_dropped_with_a_warning():
    """A face repeating a vertex index (common in STL files after processing) bounds nothing: it
    is dropped, the body named, and the scene answered."""
    v, f = box_arrays()
    f = np.concatenate([f, [[f[4, 0], f[4, 0], f[4, 1]]]])     # one degenerate face, appended
    other = trimesh.transformations.translation_matrix((0.5, 0.1, 0.2))
    with pytest.warns(pycinder.DegenerateFaceWarning,
                      match=r"body 1 \('stl'\).*1 faces repeat a vertex index; faces that repeat a "
                            r"vertex index are dropped"):
        result = pycinder.Detector().find_collisions([box_arrays(), (v, f)], [np.eye(4), other],
                                                     names=["box", "stl"])
    assert result.pairs.tolist() == [[0, 1]]
    with pytest.raises(ValueError, match=r"body 0\b.*repeat a vertex index"):
        pycinder.Detector(strict=True).find_collisions([(v, f)])


def test_one_bad_body_among_sixty_leaves_the_rest_answered():
    """60 boxes in a row, each overlapping the next; body 17 has degenerate faces (repeated
    indices) and is still tested; every other pair is answered."""
    v, f = box_arrays()
    bad = np.concatenate([f, [[0, 0, 1], [2, 3, 3], [5, 4, 5]]])
    bodies = [(v, bad) if k == 17 else (v, f) for k in range(60)]
    transforms = [trimesh.transformations.translation_matrix((0.9 * k, 0, 0)) for k in range(60)]
    with pytest.warns(pycinder.DegenerateFaceWarning, match=r"body 17\b.*3 faces"):
        result = pycinder.Detector().find_collisions(bodies, transforms)
    assert result.pairs.tolist() == [[k, k + 1] for k in range(59)]


def test_all_faces_degenerate_names_the_body():
    v, f = box_arrays()
    with pytest.raises(ValueError, match=r"body 1\b.*every face repeats a vertex index"):
        pycinder.Detector().find_collisions([box_arrays(), (v, np.array([[0, 0, 1], [2, 2, 2]]))])


def test_zero_area_face_warns_and_strict_raises():
    # A closed tetrahedron-like surface with a vertex collapsed onto an edge midpoint.
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0, 0], [0, 0, 1.0]])
    f = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]])
    with pytest.warns(pycinder.DegenerateFaceWarning, match="body 0.*faces have zero area.*zero area ignored"):
        pycinder.Detector().find_collisions([(v, f)])
    with pytest.raises(ValueError, match="body 0.*zero area"):
        pycinder.Detector(strict=True).find_collisions([(v, f)])


@pytest.mark.parametrize("mesh", [(np.zeros((0, 3)), np.zeros((0, 3), int)),
                                  (np.zeros((3, 3)), np.zeros((0, 3), int))])
def test_empty_mesh(det, mesh):
    with pytest.raises(ValueError, match=r"body 1\b.*empty"):
        det.find_collisions([box_arrays(), mesh])


def test_open_mesh_warns_and_strict_raises():
    box = trimesh.creation.box((1, 1, 1))
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-2], process=False)
    with pytest.warns(pycinder.OpenMeshWarning, match=r"body 1 \('lid'\).*2 boundary edges|body 1 \('lid'\).*boundary edges"):
        pycinder.Detector().find_collisions([box, open_box], names=["box", "lid"])
    with pytest.raises(ValueError, match=r"body 1 \('lid'\).*not a closed"):
        pycinder.Detector(strict=True).find_collisions([box, open_box], names=["box", "lid"])


def test_the_same_faces_from_trimesh_and_from_arrays_warn_once():
    """One topology per face content, whether it comes as trimesh's tracked array or as a plain
    copy: an open mesh given both ways is reported once; faces that differ only away from the
    rows the cache samples get a topology of their own."""
    box = trimesh.creation.box((1, 1, 1))
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-2], process=False)
    det = pycinder.Detector()
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        det.find_collisions([box, open_box])
        det.find_collisions([box, (np.array(open_box.vertices), np.array(open_box.faces))])
        det.find_collisions([box, open_box])
    assert sum(issubclass(w.category, pycinder.OpenMeshWarning) for w in seen) == 1
    cache = det.shapes.topologies
    big = trimesh.creation.icosphere(subdivisions=4)          # 5120 faces: rows are sampled
    other = np.array(big.faces)
    other[1] = other[1][[1, 2, 0]]                            # same face, another first corner
    assert cache.get(big.faces, len(big.vertices), "a")[1]
    assert not cache.get(np.array(big.faces), len(big.vertices), "b")[1]
    topo, built = cache.get(other, len(big.vertices), "c")
    assert built and np.array_equal(topo.faces, other)
    assert cache.get(big.faces, len(big.vertices), "a")[0].faces[1].tolist() == big.faces[1].tolist()


def test_inconsistent_winding_is_wound_again_and_tested_as_a_solid():
    """A closed box with one face turned the other way: wound again (one RewoundMeshWarning),
    then a solid, so a ball wholly inside it is found (nothing would be inside a surface);
    strict checking refuses it instead."""
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    faces = np.array(box.faces)
    faces[0] = faces[0, ::-1]
    with pytest.warns(pycinder.RewoundMeshWarning, match=r"body 0 \('box'\).*wound "
                      r"inconsistently.*tested as a solid") as caught:
        result = pycinder.Detector().find_collisions([(box.vertices, faces), ball],
                                                     names=["box", "ball"])
    assert len(caught) == 1 and caught[0].message.bodies == ["body 0 ('box')"]
    assert result.pairs.tolist() == [[0, 1]]
    with pytest.raises(ValueError, match="wound inconsistently"):
        pycinder.Detector(strict=True).find_collisions([(box.vertices, faces)])


def test_inside_out_mesh_is_reported_and_still_a_solid():
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    inverted = (box.vertices, box.faces[:, ::-1])
    with pytest.warns(pycinder.OpenMeshWarning, match=r"body 0 \('inverted'\).*inside out") as w:
        result = pycinder.Detector().find_collisions([inverted, ball], names=["inverted", "ball"])
    assert w[0].filename == __file__
    # Its inside has winding -1: a ball wholly inside is found, one outside is not.
    assert result.pairs.tolist() == [[0, 1]]
    far = trimesh.transformations.translation_matrix((0.75, 0, 0))
    with pytest.warns(pycinder.OpenMeshWarning, match="inside out"):
        apart = pycinder.Detector().find_collisions([inverted, ball], [np.eye(4), far])
    assert apart.pairs.tolist() == []
    with pytest.raises(ValueError, match="inside out"):
        pycinder.Detector(strict=True).find_collisions([(box.vertices, box.faces[:, ::-1])])


def test_too_many_bodies(det):
    box = box_arrays()
    scene = pycinder.Detector(strategy="scene", resolution=64)
    with pytest.raises(ValueError, match=r"65536 bodies is more than the 65535"):
        scene.find_collisions([box] * 65536)
    with pytest.raises(ValueError, match=r"16777216 bodies is more than the 16777215"):
        det.find_collisions([box] * 2**24)


def test_resolution_over_device_limit():
    limit = gpu_device.get_gpu().max_resolution
    with pytest.raises(ValueError, match=rf"{limit + 1}.*over this device's texture limit of {limit}"):
        pycinder.Detector(strategy="scene", resolution=limit + 1)


@pytest.mark.parametrize("bad", [0, -5, 1.5, True, "512"])
def test_resolution_must_be_a_positive_integer(bad):
    with pytest.raises(ValueError, match="resolution"):
        pycinder.Detector(strategy="scene", resolution=bad)


def test_no_adapter(monkeypatch):
    monkeypatch.setattr(wgpu.gpu, "request_adapter_sync", lambda **kw: None)
    with pytest.raises(pycinder.NoAdapterError, match="mesa-vulkan-drivers"):
        gpu_device._request_adapter()
    assert issubclass(pycinder.NoAdapterError, RuntimeError)


def test_no_adapter_when_backend_raises(monkeypatch):
    def fail(**kw):
        raise RuntimeError("Request adapter failed")
    monkeypatch.setattr(wgpu.gpu, "request_adapter_sync", fail)
    with pytest.raises(pycinder.NoAdapterError, match="no WebGPU adapter"):
        gpu_device._request_adapter()


def test_wrong_shapes_and_types(det):
    with pytest.raises(ValueError, match=r"transforms must have shape \(2, 4, 4\)"):
        det.find_collisions([box_arrays(), box_arrays()], [np.eye(4)])
    with pytest.raises(TypeError, match=r"body 0\b.*expected a trimesh"):
        det.find_collisions([42])
    with pytest.raises(ValueError, match=r"body 0\b.*vertices must have shape"):
        det.find_collisions([(np.zeros((4, 2)), np.zeros((1, 3), int))])
    with pytest.raises(ValueError, match=r"body 1\b.*vertices must be real numbers"):
        det.find_collisions([box_arrays(), (np.full((8, 3), "x", dtype=object), box_arrays()[1])])
    with pytest.raises(ValueError, match="not affine"):
        t = np.eye(4)
        t[3, 0] = 1
        det.find_collisions([box_arrays()], [t])
    with pytest.raises(ValueError, match="self_interference must be one of"):
        pycinder.Detector(strategy="scene", self_interference="ignore")
    with pytest.raises(ValueError, match=r"body 1\b.*transform is singular"):
        det.find_collisions([box_arrays(), box_arrays()], [np.eye(4), np.diag([1.0, 0, 1, 1])])
    with pytest.raises(ValueError, match="one name per body"):
        det.find_collisions([box_arrays(), box_arrays()], names=["only one"])


def test_valid_input_still_works_after_errors(det):
    with pytest.raises(ValueError):
        det.find_collisions([(np.full((8, 3), np.nan), box_arrays()[1])])
    a, b = box_arrays(), box_arrays()
    t = [np.eye(4), trimesh.transformations.translation_matrix((0.5, 0.1, 0.2))]
    assert det.find_collisions([a, b], t).pairs.tolist() == [[0, 1]]


def test_faces_that_differ_only_in_a_dropped_face_get_their_own_topology():
    """A face repeating a vertex is dropped; a mesh whose only difference is that face, valid,
    is another mesh: a closed ball, where the first is open (the cache samples rows, so this
    difference is past its fingerprint)."""
    ball = trimesh.creation.icosphere(subdivisions=4)
    broken = np.array(ball.faces)
    broken[1] = [broken[1][0], broken[1][0], broken[1][1]]
    inner = trimesh.creation.icosphere(subdivisions=1, radius=0.3)
    det = pycinder.Detector()
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        det.find_collisions([(ball.vertices, broken), inner])
    assert any(issubclass(w.category, pycinder.OpenMeshWarning) for w in seen)
    whole = det.find_collisions([ball, inner])          # trimesh's tracked faces
    assert whole.pairs.tolist() == [[0, 1]]             # the small ball is inside the solid
    assert det.find_collisions([(ball.vertices, np.array(ball.faces)), inner]).pairs.tolist() \
        == [[0, 1]]

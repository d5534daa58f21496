"""Work that llvmpipe's loop limiter would end silently.

llvmpipe (the CPU driver behind lavapipe Vulkan and llvmpipe OpenGL) ends a shader invocation's
loops after 65,535 steps in all, as if their conditions were false, and says nothing. Pass F5
samples an edge's part inside a box at a pixel's steps, and the box is as deep as the overlap is
long over the tolerance: it tests a long part in segments of its own threads. Pass F6 tests an
open body's edges against the other body's faces cluster by cluster: it counts its steps and,
past a budget, counts its tile undecided, so that the host runs the tile again with thinner boxes,
and warns when that is not enough. On a GPU without the limiter these tests pass either way.
"""

import warnings

import numpy as np
import pytest
import trimesh

import pycinder
import pycinder.focused.frame.f6_crossing_test as crossing_test
from pycinder.testing import grid_plate, surface_distance
from pycinder.focused.plan.plan_numpy_windows import TILT

T = 2.5e-5
LENGTH = 2.0
LIMIT = 65535


def _needle_and_block(end_height: float) -> tuple[trimesh.Trimesh, trimesh.Trimesh, np.ndarray]:
    """A triangular needle LENGTH long and 0.2 T thick, and a block whose top face it runs along:
    20 T above it at its near end, ``end_height`` above it (negative: inside) where it leaves the
    block through its end face, 0.05 from its far end.

    The needle runs along the view the tile planner picks for the pair (its overlap box is the
    needle's bounding box, and the view looks along the box's longest axis tilted by TILT
    towards its middle one), so that its edges are LENGTH / T pixels deep in the box, and it
    falls between pixel centres: only its edges' samples can find it. Its vertices are ordered so
    that the edges are sampled from the near end. Returns the needle, the block, and points
    along the needle's long edges (LENGTH / T of them each)."""
    u1 = np.array([np.cos(TILT), np.sin(TILT), 0.0])              # the view's direction
    across = np.array([-np.sin(TILT), np.cos(TILT), 0.0])
    # The block's top face is tilted sideways, level along the needle: its bounding box holds
    # the needle's whole length above it.
    turn = trimesh.transformations.rotation_matrix(0.05, u1)[:3, :3]
    normal = turn @ (0, 0, 1.0)
    length = LENGTH + 0.7 * T                                     # puts it between pixel centres
    end = length - 0.05

    def centre(s: float) -> np.ndarray:
        height = 20 * T + (end_height - 20 * T) * s / end
        return s * u1 + (0, 0, height / normal[2])

    angles = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    section = 0.2 * T * (np.cos(angles)[:, None] * across + np.sin(angles)[:, None] * (0, 0, 1.0))
    vertices = np.concatenate([centre(0.0) + section, centre(length) + section])
    faces = [[0, 2, 1], [3, 4, 5]]
    for i in range(3):
        j = (i + 1) % 3
        faces += [[i, j, j + 3], [i, j + 3, i + 3]]
    needle = trimesh.Trimesh(vertices, faces, process=False)
    block = trimesh.creation.box((end + 1.0, 2.0, 1.0))
    pose = np.eye(4)
    pose[:3, :3] = np.stack([u1, turn @ across, normal], axis=1)
    pose[:3, 3] = (end - (end + 1.0) / 2) * u1 - 0.5 * normal
    block.apply_transform(pose)
    s = np.linspace(0.0, 1.0, int(LENGTH / T))[:, None]
    along = np.concatenate([vertices[i] + s * (vertices[i + 3] - vertices[i]) for i in range(3)])
    return needle, block, along


def test_a_needle_found_only_by_the_far_end_of_edges_longer_than_the_loop_limit():
    """The contract's edge clause: the needle's edges pass 3-5 T inside the block, near their far
    ends, after more samples than llvmpipe's limit (before segments, lavapipe missed the pair)."""
    needle, block, along = _needle_and_block(-3.5 * T)
    assert needle.is_volume and block.is_volume
    depth = trimesh.proximity.signed_distance(block, along)      # positive inside
    assert 3 * T < depth.max() < 5 * T
    # Each long edge is sampled from its near end, a sample a pixel: its first sample deep
    # enough comes after more than the limiter's steps.
    per_edge = depth.reshape(3, -1)
    first_deep = np.argmax(per_edge > 1.6 * T, axis=1)
    assert (per_edge.max(axis=1) > 1.6 * T).all() and (first_deep > LIMIT).all()
    result = pycinder.Detector(tolerance=T).find_collisions([block, needle])
    assert result.pairs.tolist() == [[0, 1]]
    assert result.stats.possibly_lost == 0


def test_the_needle_two_tolerances_above_the_block_is_not_reported():
    needle, block, _ = _needle_and_block(2.1 * T)   # its lowest point 0.1 T below its axis
    assert surface_distance(needle, block) == pytest.approx(2 * T, rel=0.05)
    result = pycinder.Detector(tolerance=T).find_collisions([block, needle])
    assert result.pairs.tolist() == []


def _wavy(mesh: trimesh.Trimesh, lift: float) -> trimesh.Trimesh:
    v = mesh.vertices.copy()
    v[:, 2] = 0.05 * np.sin(6 * v[:, 0]) + lift
    return trimesh.Trimesh(v, mesh.faces, process=False)


def _crossing_test(meshes, transforms, budget, monkeypatch):
    """Find collisions among open bodies with pass F6's step budget lowered to ``budget``."""
    monkeypatch.setattr(crossing_test, "CROSSING_BUDGET", budget)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", pycinder.LossWarning)
        result = pycinder.Detector(tolerance=0.01).find_collisions(meshes, transforms)
    return result, [w for w in caught if issubclass(w.category, pycinder.LossWarning)]


@pytest.mark.filterwarnings("ignore::pycinder.OpenMeshWarning")
def test_crossing_test_past_its_budget_runs_the_tile_again_with_thinner_boxes(monkeypatch):
    """Two wavy open sheets 2 t apart: with a budget too small for the first box, the tile is
    counted undecided and decided in thinner boxes, without a warning."""
    plate = grid_plate(1.0, 40)
    meshes = [_wavy(plate, 0.0), _wavy(plate, 0.021)]
    assert surface_distance(*meshes) > 0.02
    result, lost = _crossing_test(meshes, None, 4000, monkeypatch)
    assert result.pairs.tolist() == []
    assert result.stats.undecided > 0 and result.stats.retries > 0
    assert result.stats.possibly_lost == 0 and not lost


@pytest.mark.filterwarnings("ignore::pycinder.OpenMeshWarning")
def test_a_tile_past_the_crossing_budget_goes_straight_to_thinner_boxes(monkeypatch):
    """Longer lists cannot help a tile that pass F6 left unfinished: every retry cuts its box,
    and the next frames get no retry rounds of longer lists on the GPU."""
    from pycinder.focused.frame import rerun_policy

    plate = grid_plate(1.0, 40)
    meshes = [_wavy(plate, 0.0), _wavy(plate, 0.021)]
    monkeypatch.setattr(crossing_test, "CROSSING_BUDGET", 4000)
    cuts = []

    def split_depth(*args, cut=True, **kwargs):
        cuts.append(cut)
        return real(*args, cut=cut, **kwargs)

    real = rerun_policy.split_depth
    monkeypatch.setattr(rerun_policy, "split_depth", split_depth)
    detector = pycinder.Detector(tolerance=0.01)
    for _ in range(2):
        result = detector.find_collisions(meshes)
        assert result.pairs.tolist() == [] and result.stats.retries > 0
        assert result.stats.possibly_lost == 0
        assert not detector.strategy.recently_retried
    assert cuts and all(cuts)


@pytest.mark.filterwarnings("ignore::pycinder.OpenMeshWarning")
def test_crossing_test_that_never_fits_its_budget_warns(monkeypatch):
    """Two crossing sheets with a budget no cluster fits: the pair is not found, and says so."""
    default = crossing_test.CROSSING_BUDGET
    plate = grid_plate(1.0, 40)
    tilt = trimesh.transformations.rotation_matrix(0.05, (1, 0, 0))
    assert surface_distance(plate, plate, (np.eye(4), tilt)) <= 0
    result, lost = _crossing_test([plate, plate], [np.eye(4), tilt], 1, monkeypatch)
    assert result.pairs.tolist() == []
    assert result.stats.possibly_lost == 1 and lost
    found, lost = _crossing_test([plate, plate], [np.eye(4), tilt], default, monkeypatch)
    assert found.pairs.tolist() == [[0, 1]] and not lost


@pytest.mark.filterwarnings("ignore::pycinder.OpenMeshWarning")
def test_every_crossing_of_a_coarse_sheet_with_a_dense_one_is_recorded():
    """A sheet of two triangles through a wavy sheet of 180,000: the coarse sheet's one cluster
    meets about 2,800 clusters of the dense one, far more loop steps than llvmpipe allows one
    workgroup of pass F6 (before the budget, lavapipe recorded 4 of these 11 crossings). Every
    crossing of the coarse sheet's edges with the dense sheet is recorded, counted exactly by
    ray-triangle tests."""
    from trimesh.ray.ray_triangle import RayMeshIntersector

    coarse = grid_plate(2.0, 1)
    coarse.apply_transform(trimesh.transformations.rotation_matrix(0.3, (0, 0, 1)))
    dense = grid_plate(1.9, 300)
    v = dense.vertices.copy()
    v[:, 2] = 0.02 * np.sin(9 * v[:, 0] + 0.1) * np.cos(7 * v[:, 1] + 0.2)
    dense = trimesh.Trimesh(v, dense.faces, process=False)
    p0, p1 = coarse.vertices[coarse.edges_unique].transpose(1, 0, 2)
    hits, ray, _ = RayMeshIntersector(dense).intersects_location(p0, p1 - p0, multiple_hits=True)
    d = (p1 - p0)[ray]
    along = np.einsum("ij,ij->i", hits - p0[ray], d) / np.einsum("ij,ij->i", d, d)
    crossings = int(((along >= 0) & (along <= 1)).sum())
    assert crossings > 8
    result = pycinder.Detector(tolerance=0.005, records="all").find_collisions([coarse, dense])
    rec = result.records
    assert result.pairs.tolist() == [[0, 1]]
    assert int(((rec["penetrating"] == 0) & (rec["edge"] >= 0)).sum()) == crossings
    assert result.stats.incomplete_records == 0

"""What request.py says the options mean: the records modes and the default tolerance, checked
against hand-computed values and against what a query reports."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.request import FOUND_RECORDS_PER_PAIR, RecordMode, record_mode
from pycinder.testing import mesh_pair_tolerances
from pycinder.tolerance import DEFAULT_RELATIVE_TOLERANCE, body_sizes, default_pair_tolerances

from conftest import assert_matches_truth


def test_record_modes_mean_what_the_docs_say():
    assert FOUND_RECORDS_PER_PAIR == 16
    assert record_mode("found") == RecordMode("found", read=True, every_tile=False, probe=True,
                                              per_pair=16)
    assert record_mode("all") == RecordMode("all", read=True, every_tile=True, probe=False,
                                            per_pair=None)
    assert record_mode("none") == RecordMode("none", read=False, every_tile=False, probe=True,
                                             per_pair=0)
    assert [record_mode(m).complete for m in ("found", "all", "none")] == [False, True, False]
    assert pycinder.CollisionRequest(records="all").record_mode is record_mode("all")
    assert pycinder.CollisionRequest().record_mode.name == "found"
    for bad in ("some", "ALL", None, True):
        with pytest.raises(ValueError, match="records must be one of 'found', 'all', 'none'"):
            record_mode(bad)


def _rotation_z(degrees: float) -> np.ndarray:
    return trimesh.transformations.rotation_matrix(np.radians(degrees), (0, 0, 1))


def test_default_tolerance_is_one_percent_of_the_smaller_diagonal():
    # Boxes 3 x 4 x 12 (diagonal 13) and 1 x 2 x 2 (diagonal 3) scaled by 2 and turned: 6.
    lo = np.array([[-1.5, -2, -6], [0, 0, 0]])
    hi = np.array([[1.5, 2, 6], [1, 2, 2]])
    turned = _rotation_z(30) @ np.diag([2.0, 2.0, 2.0, 1.0])
    turned[:3, 3] = (100, -50, 7)  # a translation changes no size
    sizes = body_sizes(lo, hi, np.stack([np.eye(4), turned]))
    np.testing.assert_allclose(sizes, [13.0, 6.0], rtol=1e-12)
    assert DEFAULT_RELATIVE_TOLERANCE == 0.01
    np.testing.assert_allclose(default_pair_tolerances(sizes[[0, 0]], sizes[[1, 0]]), [0.06, 0.13],
                               rtol=1e-12)
    np.testing.assert_array_equal(default_pair_tolerances(sizes[[0, 0]], sizes[[1, 0]], 0.5),
                                  [0.5, 0.5])


def test_pair_tolerances_agree_with_the_query(detector):
    # A 3 x 4 x 12 slab (diagonal 13) crossed by a 1 x 2 x 2 box scaled by 2 (diagonal 6) and
    # holding a 0.3 x 0.4 x 1.2 bar (diagonal 1.3) near its top; the box and the bar are 2.7
    # apart along z, so the candidate pairs are (0, 1) and (0, 2), and both overlap deeply.
    slab = trimesh.creation.box((3, 4, 12))
    box = trimesh.creation.box((1, 2, 2))
    bar = trimesh.creation.box((0.3, 0.4, 1.2))
    turned = _rotation_z(30) @ np.diag([2.0, 2.0, 2.0, 1.0])
    turned[:3, 3] = (1.5, 0, 0)
    transforms = np.stack([np.eye(4), turned, trimesh.transformations.translation_matrix(
        (0, 0, 5.3))])
    meshes = [slab, box, bar]
    result = detector.find_collisions(meshes, transforms)
    assert result.pairs.tolist() == [[0, 1], [0, 2]]
    assert_matches_truth(result.pairs, pycinder.testing.ground_truth(meshes, transforms))
    expected = mesh_pair_tolerances(meshes, transforms, result.pairs, None)
    np.testing.assert_allclose(expected, [0.06, 0.013], rtol=1e-12)
    assert result.stats.candidates == 2
    # The query measures the bodies from their vertices as stored on the GPU (single precision).
    np.testing.assert_allclose(result.stats.tolerance, (0.013, 0.06), rtol=1e-6)
    # Every tile's pixel is its pair's tolerance.
    tiles = result.tiles
    pair_of = {tuple(p): t for p, t in zip(result.pairs.tolist(), expected)}
    np.testing.assert_allclose(tiles.pixel, [pair_of[tuple(b)] for b in tiles.bodies.tolist()],
                               rtol=1e-6)
    given = detector.find_collisions(meshes, transforms, records="none")
    assert given.pairs.tolist() == result.pairs.tolist() and len(given.records) == 0
    fixed = pycinder.Detector(tolerance=0.02).find_collisions(meshes, transforms)
    np.testing.assert_array_equal(mesh_pair_tolerances(meshes, transforms, fixed.pairs, 0.02),
                                  [0.02, 0.02])
    assert fixed.stats.tolerance == (0.02, 0.02)

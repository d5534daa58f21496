"""The real-model benchmark's truth (``pycinder.testing.realtruth``) on pairs whose answer is
known by construction: it must classify a contained element, a pair within a large pair's
default tolerance, and a georeferenced element wound inconsistently, as the geometry says."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
import trimesh

pytest.importorskip("manifold3d")
pytest.importorskip("fcl")

from pycinder.testing.realtruth import exact_truth, verdict  # noqa: E402

MARGIN = 0.02


@dataclass
class Body:
    mesh: trimesh.Trimesh


@dataclass
class Model:
    bodies: list[Body]


def box(extents, centre) -> trimesh.Trimesh:
    mesh = trimesh.creation.box(extents)
    mesh.apply_translation(centre)
    return mesh


def test_an_element_inside_another_overlaps_however_far_its_surfaces_are():
    """A beam 0.2 m thick inside a wall 0.3 m thick, 5 cm from each face (farther than the
    margin): its surfaces are apart, yet all of it is in the wall, a hard clash at 2 mm."""
    wall, beam = box((4.0, 0.3, 3.0), (0, 0, 0)), box((2.0, 0.2, 0.2), (0, 0, 0))
    truth = exact_truth(Model([Body(wall), Body(beam)]), MARGIN, [0.002])
    p = truth[(0, 1)]
    assert p.kind == "overlapping" and p.volume == pytest.approx(2.0 * 0.2 * 0.2)
    assert p.ball == pytest.approx(0.1, abs=2e-3)
    assert verdict(p, "min_depth", 0.002) == "must"


def test_a_pair_within_its_default_tolerance_is_in_the_truth():
    """Two 10 m slabs 5 cm apart: farther than the margin, nearer than their default tolerance
    (1% of 10 m), so the default query may report them (either way), which the truth must know
    rather than count as false."""
    a, b = box((10.0, 10.0, 0.2), (0, 0, 0)), box((10.0, 10.0, 0.2), (0, 0, 0.25))
    truth = exact_truth(Model([Body(a), Body(b)]), MARGIN)
    p = truth[(0, 1)]
    assert p.kind == "apart" and p.distance == pytest.approx(0.05)
    assert verdict(p, "default") == "either"
    assert verdict(p, "clearance", 0.01) == "never"
    far = exact_truth(Model([Body(a), Body(box((1.0, 1.0, 0.2), (0, 0, 0.25)))]), MARGIN)
    assert far == {}  # 5 cm apart, beyond the margin and the 1 m slab's tolerance


def test_a_georeferenced_element_wound_inconsistently_is_taken_as_its_solid():
    """A board 0.2 m thick with half its faces turned inward, 5,000 km from the origin (where
    single precision steps by half a metre, and both its faces round to one plane), 0.1 m into
    another board: wound outward, it overlaps by 0.1 x 1 x 0.2 cubic metres."""
    far = np.array([700_000.0, 5_000_000.1, 0.0])
    a = box((1.0, 0.2, 1.0), far)
    faces = a.faces.copy()
    faces[::2] = faces[::2, ::-1]
    a = trimesh.Trimesh(a.vertices, faces, process=False)
    b = box((1.0, 0.2, 1.0), far + (0.9, 0.0, 0.0))
    p = exact_truth(Model([Body(a), Body(b)]), MARGIN)[(0, 1)]
    assert p.kind == "overlapping" and p.volume == pytest.approx(0.02, rel=1e-6)

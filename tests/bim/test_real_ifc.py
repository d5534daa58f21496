"""Pairs of elements from real IFC models (``data/regressions/real-ifc``, see its README), against
exact geometry: manifold3d volumes in float64 and python-fcl distances.

* A window and a door in their walls' openings touch the reveals (no volume in common): no hard
  clash at any depth, while the same window pushed 10 mm into its sill is one, about 10 mm deep.
* Two ceiling boards 124 mm apart, closed but wound inconsistently (as Revit exports them): wound
  again, tested as solids and never within a clearance of 5 or 10 mm; opened (tested as surfaces),
  still never.
* A railing and a stair's pan 1.01 m apart, an open surface and a closed mesh wound again: never
  reported, however the pair is turned and moved (which moves their faces' rounding about).
* A beam wholly inside a wall: a hard clash, its depth bounded below by a ball inside both.
"""

from __future__ import annotations

import warnings
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.focused.modes import hardclash
from pycinder.testing import random_rotation, surface_distance

m3d = pytest.importorskip("manifold3d")
pytest.importorskip("fcl")

DATA = Path(__file__).parents[1] / "data" / "regressions" / "real-ifc"


@lru_cache(maxsize=None)
def pair(name: str) -> tuple[trimesh.Trimesh, trimesh.Trimesh]:
    z = np.load(DATA / f"{name}.npz")
    return (trimesh.Trimesh(z["a_vertices"], z["a_faces"], process=False),
            trimesh.Trimesh(z["b_vertices"], z["b_faces"], process=False))


def solid(mesh: trimesh.Trimesh, origin: np.ndarray, move: np.ndarray | None = None):
    """The mesh as a manifold3d solid in float64 about ``origin`` (wound consistently and
    outward first, as the truth needs it; moved by ``move``)."""
    m = mesh.copy()
    if not m.is_winding_consistent:
        trimesh.repair.fix_winding(m)
    if m.volume < 0:
        m.invert()
    v = np.asarray(m.vertices, np.float64) - origin + (0.0 if move is None else move)
    out = m3d.Mesh64(vert_properties=np.ascontiguousarray(v),
                     tri_verts=np.ascontiguousarray(m.faces, np.uint32))
    out.merge()
    return m3d.Manifold(out)


def overlap_volume(a: trimesh.Trimesh, b: trimesh.Trimesh, move_b: np.ndarray | None = None):
    origin = 0.5 * (a.bounds.mean(axis=0) + b.bounds.mean(axis=0))
    return (solid(a, origin) ^ solid(b, origin, move_b)).volume()


def moved(mesh: trimesh.Trimesh, offset) -> trimesh.Trimesh:
    out = mesh.copy()
    out.apply_translation(offset)
    return out


@pytest.mark.parametrize("name", ["fzk-wall-window", "fzk-wall-door"])
def test_doors_and_windows_in_their_openings_are_no_hard_clash(name):
    wall, filling = pair(name)
    assert wall.is_watertight and filling.is_watertight
    assert overlap_volume(wall, filling) <= 1e-12  # they touch: no volume in common
    for d in (0.002, 0.01, 0.05):
        result = pycinder.find_collisions([wall, filling], min_depth=d)
        assert result.pairs.tolist() == [], (name, d, result.depths)


def test_a_window_pushed_into_its_sill_is_a_hard_clash_about_as_deep():
    """The window 10 mm down into its sill: a ball of radius 4 mm lies inside both (so any
    translation that separates them, here or in a box around the overlap, is at least 8 mm), and
    moving it 10 mm up leaves no volume in common."""
    wall, window = pair("fzk-wall-window")
    pushed = moved(window, (0.0, 0.0, -0.01))
    origin = 0.5 * (wall.bounds.mean(axis=0) + window.bounds.mean(axis=0))
    centre = np.array([0.5 * (0.12 + 0.195), 2.2, 0.945]) - origin
    ball = m3d.Manifold.sphere(0.004, 48).translate(tuple(centre))
    assert (ball - solid(wall, origin)).volume() <= 1e-9 * ball.volume()
    assert (ball - solid(pushed, origin)).volume() <= 1e-9 * ball.volume()
    assert overlap_volume(wall, pushed, np.array([0.0, 0.0, 0.01])) <= 1e-12
    result = pycinder.find_collisions([wall, pushed], min_depth=0.002)
    assert result.pairs.tolist() == [[0, 1]]
    depth, error = result.depths[0], result.depth_errors[0]
    assert 0.008 - error <= depth <= 0.01 / hardclash.DIRECTION_COS + error


def test_ceiling_boards_wound_inconsistently_keep_the_clearance_contract():
    a, b = pair("duplex-ceilings")
    assert a.is_watertight and b.is_watertight
    assert not a.is_winding_consistent and not b.is_winding_consistent
    distance = surface_distance(a, b)
    assert distance == pytest.approx(0.124, abs=1e-9)
    with pytest.warns(pycinder.RewoundMeshWarning, match="2 bodies are closed but were wound "
                      "inconsistently") as caught:
        for c in (0.005, 0.01, 0.1):  # never more than c + c / 8 apart when reported
            assert pycinder.find_collisions([a, b], clearance=c).pairs.tolist() == [], c
    assert caught[0].message.bodies == ["body 0", "body 1"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        near = pycinder.find_collisions([a, b], clearance=0.2)
    assert near.pairs.tolist() == [[0, 1]]
    assert abs(near.distances[0] - distance) <= near.distance_errors[0] + 1e-9


@pytest.mark.filterwarnings("ignore::pycinder.MeshWarning")
def test_ceiling_boards_as_surfaces_keep_the_clearance_contract():
    """Each board less a face: open, tested as surfaces. A board's edges lie in the plane of
    the other's faces, 124 mm beyond them: they never cross it."""
    a, b = pair("duplex-ceilings")
    opened = [trimesh.Trimesh(m.vertices, m.faces[1:], process=False) for m in (a, b)]
    for bodies in (opened, [opened[0], b]):
        for c in (0.005, 0.01, 0.1):
            assert pycinder.find_collisions(bodies, clearance=c).pairs.tolist() == [], c
        for t in (0.00125, 0.0025, 0.01):
            assert pycinder.find_collisions(bodies, tolerance=t).pairs.tolist() == [], t


@pytest.mark.filterwarnings("ignore::pycinder.MeshWarning")
def test_a_railing_far_from_a_stair_is_never_reported():
    """The railing's small faces lie in the planes of the pan's edges, 1 m away: whichever way
    the pair is turned and moved, no crossing is found (at the default tolerance, 6 cm)."""
    railing, stair = pair("office-railing-stair")
    assert surface_distance(railing, stair) > 1.0
    rng = np.random.default_rng(3)
    detector = pycinder.Detector()
    for _ in range(12):
        move = random_rotation(rng)
        move[:3, 3] = rng.uniform(-50.0, 50.0, 3)
        result = detector.find_collisions([railing, stair], [move, move])
        assert result.pairs.tolist() == []


def test_a_beam_inside_a_wall_is_a_hard_clash():
    wall, beam = pair("duplex-wall-beam")
    assert overlap_volume(wall, beam) == pytest.approx(
        solid(beam, np.zeros(3)).volume(), rel=1e-9)  # wholly inside
    result = pycinder.find_collisions([wall, beam], min_depth=0.002)
    assert result.pairs.tolist() == [[0, 1]]
    # Its flange (11 mm of a W410x60) holds a ball of 5 mm inside both bodies.
    assert result.depths[0] >= 0.01 - result.depth_errors[0]

"""Hard clashes and clearance at 1 mm on bodies 500 m long, up to 10,000 km from the origin,
against exact geometry.

Pairs too large (or too far from the origin) for one frame are measured in regions where they
meet, cut to each region in float64 (:mod:`pycinder.focused.measure.regions`), so rounding scales
with the region. The truth: a 500 m beam (a box, or a 32-sided cylinder lying on one of its
edges) pressed into, touching or held above a 500 m slab by a stated amount; both are convex and
the slab is wider than the beam, so the penetration depth is the amount pressed (the slab's top
face's normal separates them, and no shorter translation does), and the distance the gap. The
whole arrangement is moved far from the origin and, in half the cases, turned about a point
there (a rigid motion leaves depths and distances unchanged).
"""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.focused.measure.regions import clip_triangles, triangles_meet_box
from pycinder.testing import random_rotation

pytest.importorskip("manifold3d", reason="solids are cut to the regions with manifold3d")

D = 1e-3
"""min_depth and clearance of every query here."""
SLAB = trimesh.creation.box((500.0, 2.0, 0.3))
BEAM = trimesh.creation.box((500.0, 0.3, 0.3))
# A cylinder lying along x on one of its edges (its lowest vertices at z = -0.1).
PIPE = trimesh.creation.cylinder(radius=0.1, height=500.0, sections=32)
PIPE.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
OFFSETS = [(0.0, 0.0, 0.0), (5e5, 0.0, 0.0), (6e6, -7e6, 2e6)]
"""At the origin, 500 km out, and 9.4e6 m out (within 10,000 km)."""
PRESSED = {"touching": 0.0, "grazing 0.5 mm": 5e-4, "overlapping 5 mm": 5e-3,
           "0.5 mm apart": -5e-4, "1.2 mm apart": -1.2e-3}
"""How far each beam is pressed into its slab (negative: the gap)."""


def _scene(beam: trimesh.Trimesh, turned: bool):
    """A slab and a beam on it per offset of OFFSETS and case of PRESSED (10 m apart), each
    offset's arrangement moved there and turned about it; returns meshes, transforms and the
    depth (positive) or gap (negative) of each pair (2 k, 2 k + 1)."""
    meshes, transforms, pressed = [], [], []
    bottom = float(beam.vertices[:, 2].min())
    for offset in OFFSETS:
        motion = np.eye(4)
        if turned:
            motion[:3, :3] = random_rotation(np.random.default_rng(37))[:3, :3]
        motion[:3, 3] = offset
        for k, amount in enumerate(PRESSED.values()):
            slab, on = np.eye(4), np.eye(4)
            slab[:3, 3] = (0.0, 10.0 * k, 0.0)
            on[:3, 3] = (0.0, 10.0 * k + 0.2, 0.15 - bottom - amount)
            meshes += [SLAB, beam]
            transforms += [motion @ slab, motion @ on]
            pressed.append(amount)
    return meshes, transforms, np.array(pressed)


def _case(k: int) -> str:
    return f"{list(PRESSED)[k % len(PRESSED)]} at {OFFSETS[k // len(PRESSED)]}"


# Turned pairs meet over about 1,100 regions and take a minute or more each on a CPU adapter: the
# turned box runs in `make test`, the other turned cases with the slow tests (`make test-slow`).
CASES = [pytest.param(BEAM, False, id="box-aligned"),
         pytest.param(PIPE, False, id="cylinder-aligned"),
         pytest.param(BEAM, True, id="box-turned"),
         pytest.param(PIPE, True, id="cylinder-turned", marks=pytest.mark.slow)]
SLOW_TURNED = [pytest.param(c.values[0], c.values[1], id=c.id,
                            marks=pytest.mark.slow if c.values[1] else ()) for c in CASES]


@pytest.mark.parametrize(("beam", "turned"), CASES)
def test_hard_clashes_of_500m_bodies_anywhere_within_10000km(beam, turned):
    meshes, transforms, pressed = _scene(beam, turned)
    result = pycinder.Detector(min_depth=D).find_collisions(meshes, transforms)
    found = {tuple(p): k for k, p in enumerate(result.pairs.tolist())}
    assert set(found) <= {(2 * k, 2 * k + 1) for k in range(len(pressed))}
    for k, amount in enumerate(pressed):
        pair = (2 * k, 2 * k + 1)
        if amount > D:
            assert pair in found, f"{_case(k)}: a pair {amount} deep is not reported"
            i = found[pair]
            depth, error = result.depths[i], result.depth_errors[i]
            # The figure bounds the depth from above up to rounding, and from below within its
            # error (convex bodies); its error includes the whole pair's rounding.
            assert depth - error <= amount <= depth + error, (_case(k), depth, error)
        elif amount <= D / 2:
            assert pair not in found, f"{_case(k)} is reported"


@pytest.mark.parametrize(("beam", "turned"), SLOW_TURNED)
def test_clearance_of_500m_bodies_anywhere_within_10000km(beam, turned):
    meshes, transforms, pressed = _scene(beam, turned)
    result = pycinder.Detector(clearance=D).find_collisions(meshes, transforms)
    found = {tuple(p): k for k, p in enumerate(result.pairs.tolist())}
    assert set(found) <= {(2 * k, 2 * k + 1) for k in range(len(pressed))}
    for k, amount in enumerate(pressed):
        pair = (2 * k, 2 * k + 1)
        gap = max(-amount, 0.0)
        if gap < D:
            assert pair in found, f"{_case(k)} is not reported"
            i = found[pair]
            assert abs(result.distances[i] - gap) <= result.distance_errors[i], \
                (_case(k), result.distances[i], result.distance_errors[i])
            assert result.distance_errors[i] <= D / 16
        elif gap > D + D / 8:
            assert pair not in found, f"{_case(k)} is reported"


@pytest.mark.parametrize("offset", OFFSETS[:2], ids=["origin", "500 km"])
def test_a_body_inside_a_large_one_near_its_face_is_at_distance_zero(offset):
    """A box inside the 500 m slab, its top face 0.5 mm below the slab's (closer than c, so
    measured in regions): the pair is at distance 0, one body inside the other, not 0.5 mm."""
    inner = trimesh.creation.box((1.0, 1.0, 0.1))
    slab, box = np.eye(4), np.eye(4)
    slab[:3, 3] = offset
    box[:3, 3] = np.add(offset, (0.0, 0.0, 0.15 - 0.05 - 5e-4))
    result = pycinder.Detector(clearance=D).find_collisions([SLAB, inner], [slab, box])
    assert result.pairs.tolist() == [[0, 1]]
    assert result.distances[0] == 0.0, (result.distances, result.distance_errors)


def test_a_pair_meeting_over_too_many_regions_is_refused_with_what_would_do():
    big = trimesh.creation.box((1e4, 1e4, 1e4))
    shift = np.eye(4)
    shift[0, 3] = 1e4 - 0.75e-3  # 0.75 mm deep: the whole pair's rounding cannot tell
    with pytest.raises(ValueError, match=r"(?s)min_depth 0.001 is too small for .*'wall'.*"
                                         r"'slab'.*use a min_depth of at least"):
        pycinder.Detector(min_depth=1e-3).find_collisions([big, big], [np.eye(4), shift],
                                                          names=["wall", "slab"])


def test_triangles_cut_to_a_box_keep_exactly_the_area_within_it():
    # A 2 m cube's surface cut to a box holding one corner: three quarter faces of 1 m2 each.
    cube = trimesh.creation.box((2.0, 2.0, 2.0))
    tris = cube.vertices[cube.faces]
    for lo, hi, area in (((0, 0, 0), (2, 2, 2), 3.0), ((-0.5, -2, -2), (0.5, 2, 2), 8 * 1.0),
                         ((-2, -2, -2), (2, 2, 2), 24.0), ((1.5, 1.5, 1.5), (3, 3, 3), 0.0)):
        lo, hi = np.array(lo, float), np.array(hi, float)
        parts = clip_triangles(tris, lo, hi)
        got = 0.5 * np.linalg.norm(np.cross(parts[:, 1] - parts[:, 0],
                                            parts[:, 2] - parts[:, 0]), axis=1).sum()
        assert got == pytest.approx(area, abs=1e-12)
        assert np.all(parts >= lo - 1e-12) and np.all(parts <= hi + 1e-12)


def test_triangles_meeting_a_box():
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    # Its box meets the unit box at (0.6, 0.6) but the triangle (x + y <= 1) does not.
    assert not triangles_meet_box(tri, np.array([0.6, 0.6, -1.0]), np.array([1.0, 1.0, 1.0]))[0]
    assert triangles_meet_box(tri, np.array([0.4, 0.4, -1.0]), np.array([1.0, 1.0, 1.0]))[0]
    assert triangles_meet_box(tri, np.array([0.5, 0.5, 0.0]), np.array([1.0, 1.0, 1.0]))[0]
    assert not triangles_meet_box(tri, np.array([0.0, 0.0, 0.1]), np.array([1.0, 1.0, 1.0]))[0]


def _lp_margin(tri: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """The largest ``m`` such that a point of the triangle lies within the box shrunk by ``m``
    (negative: how far it must grow to meet it), by linear programming over barycentric
    coordinates (scipy's HiGHS): an independent truth for triangles meeting boxes."""
    from scipy.optimize import linprog

    # Variables: three barycentric weights and m; maximise m.
    a_ub, b_ub = [], []
    for axis in range(3):
        row = list(tri[:, axis])
        a_ub.append([-x for x in row] + [1.0])   # x >= lo + m
        b_ub.append(-lo[axis])
        a_ub.append(row + [1.0])                 # x <= hi - m
        b_ub.append(hi[axis])
    out = linprog([0, 0, 0, -1.0], A_ub=a_ub, b_ub=b_ub, A_eq=[[1, 1, 1, 0]], b_eq=[1],
                  bounds=[(0, None)] * 3 + [(None, None)], method="highs")
    assert out.status == 0
    return -out.fun


def test_triangles_meeting_boxes_and_cut_to_them_against_linear_programming():
    """Random triangles and boxes, at several scales: whether each meets its box agrees with
    linear programming wherever the margin is clear of rounding; the cut keeps points of the
    triangle's plane within the box, and keeps nothing exactly where they do not meet."""
    pytest.importorskip("scipy")
    rng = np.random.default_rng(11)
    checked = 0
    for scale in (1e-3, 1.0, 1e3):
        for _ in range(150):
            tri = rng.normal(size=(3, 3)) * scale
            centre = rng.normal(size=3) * scale
            half = rng.uniform(0.05, 1.0, size=3) * scale
            lo, hi = centre - half, centre + half
            margin = _lp_margin(tri, lo, hi)
            meets = bool(triangles_meet_box(tri[None], lo, hi)[0])
            parts = clip_triangles(tri[None], lo, hi)
            if abs(margin) < 1e-7 * scale:
                continue  # touching, within rounding: either answer holds
            checked += 1
            assert meets == (margin > 0), (scale, margin)
            assert (len(parts) > 0) == (margin > 0), (scale, margin)
            if len(parts):
                assert np.all(parts >= lo - 1e-9 * scale) and np.all(parts <= hi + 1e-9 * scale)
                normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
                off = (parts.reshape(-1, 3) - tri[0]) @ normal / np.linalg.norm(normal)
                assert np.all(np.abs(off) <= 1e-9 * scale)
    assert checked > 400

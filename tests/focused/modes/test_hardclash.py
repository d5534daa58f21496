"""Hard clashes (``min_depth=d``) against exact geometry, never against the implementation.

The contract (:mod:`pycinder.hardclash`): a pair deeper than ``d`` (the shortest translation
that separates it is longer than ``d``) is always reported, whatever its shapes, open and nested
bodies included; a pair of convex bodies at most ``d/2`` deep (touching and apart included) never
is, and a non-convex pair only where its directional depth exceeds ``d``; each reported pair's
``depths[k]`` bounds its depth from above up to rounding, and for convex pairs the true depth lies
in ``[depths - depth_errors, depths + rounding]``.

The truth: analytic depths for bodies pressed into a slab, nested boxes and bars through L- and
U-shaped solids; for any two convex polyhedra the separating-axis theorem over both bodies' face
normals and every cross product of an edge of one with an edge of the other, which is exact (the
penetration depth of two convex polyhedra is the least, over those directions, of the overlap of
their projections); coal's EPA agrees with it where coal is installed; python-fcl's exact distance
for pairs that must be apart.
"""

import pickle
from dataclasses import dataclass

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder import testing
from pycinder.focused.modes import hardclash
from pycinder.testing import (grid_plate, l_shape, open_cup, open_tube, random_rotation,
                              surface_distance)

SCALES = [1e-3, 1.0, 1e3]


@pytest.fixture
def fcl():
    """python-fcl (the test extra) checks that the constructions touch, cross or are apart."""
    return pytest.importorskip("fcl", reason="exact distances come from python-fcl")


# -- Exact geometry -----------------------------------------------------------------------------

def move(x=0.0, y=0.0, z=0.0, rotation=None) -> np.ndarray:
    m = np.eye(4) if rotation is None else rotation.copy()
    m[:3, 3] = (x, y, z)
    return m


def turn(angle: float, axis) -> np.ndarray:
    return trimesh.transformations.rotation_matrix(angle, axis)


def _world(mesh: trimesh.Trimesh, t: np.ndarray) -> np.ndarray:
    return np.asarray(mesh.vertices, np.float64) @ t[:3, :3].T + t[:3, 3]


def separating_overlap(a: trimesh.Trimesh, ta: np.ndarray, b: trimesh.Trimesh,
                       tb: np.ndarray) -> float:
    """The least overlap of the projections of two convex polyhedra (affine transforms) over
    both bodies' face normals and every edge-edge cross product: their exact penetration depth
    where positive; 0 where they touch; negative where an axis separates them.

    Exact because the Minkowski difference A - B is a convex polyhedron whose facet normals are
    among these directions, the penetration depth is the distance from the origin to its boundary,
    the least of its support function over its facet normals, and the support function in any
    other unit direction is no smaller (a superset of directions leaves the least unchanged)."""
    va, vb = _world(a, ta), _world(b, tb)
    candidates = []
    for mesh, v in ((a, va), (b, vb)):
        corners = v[mesh.faces]
        candidates.append(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
    ea = va[a.edges_unique[:, 1]] - va[a.edges_unique[:, 0]]
    eb = vb[b.edges_unique[:, 1]] - vb[b.edges_unique[:, 0]]
    candidates.append(np.cross(ea[:, None, :], eb[None, :, :]).reshape(-1, 3))
    directions = []
    for c in candidates:
        length = np.linalg.norm(c, axis=1)
        keep = length > 1e-9 * length.max()
        directions.append(c[keep] / length[keep, None])
    directions = np.concatenate(directions)
    pa, pb = va @ directions.T, vb @ directions.T
    overlap = np.minimum(pa.max(axis=0) - pb.min(axis=0), pb.max(axis=0) - pa.min(axis=0))
    return float(overlap.min())


def convex_depth(a, ta, b, tb) -> float:
    """Exact penetration depth of two convex polyhedra (0 for touching and apart pairs)."""
    return max(separating_overlap(a, ta, b, tb), 0.0)


def fcl_crosses(case) -> bool:
    """Whether python-fcl finds the two surfaces in contact (a crossing, for the open cases)."""
    import fcl

    from pycinder.testing import fcl_object, world_mesh

    (a, b), (ta, tb) = case.meshes, case.transforms
    request = fcl.CollisionRequest(num_max_contacts=1, enable_contact=False)
    return fcl.collide(fcl_object(world_mesh(a, ta)), fcl_object(world_mesh(b, tb)), request,
                       fcl.CollisionResult()) > 0


def coal_depth(a, ta, b, tb) -> float:
    """coal's penetration depth (GJK/EPA signed distance) of two convex meshes."""
    return testing.coal_depth(a, ta, b, tb)


# -- Cases: pairs placed side by side in one scene ----------------------------------------------

@dataclass
class Case:
    """One pair: its meshes and transforms (about its own origin), its exact depth, whether
    both bodies are convex, and, where the contract's directional clause decides it, whether it
    must be reported (None: decided by the depth)."""

    name: str
    meshes: list
    transforms: list
    depth: float
    convex: bool = True
    reported: bool | None = None
    pair: tuple = (0, 1)

    def must(self, d: float) -> bool:
        return self.reported is True or (self.reported is None and self.depth > d)

    def must_not(self, d: float) -> bool:
        return self.reported is False or (self.reported is None and self.convex
                                          and self.depth <= d / 2)


def scaled(case: Case, k: float) -> Case:
    meshes = []
    for m in case.meshes:
        m = m.copy()
        m.apply_scale(k)
        meshes.append(m)
    transforms = []
    for t in case.transforms:
        t = t.copy()
        t[:3, 3] *= k
        transforms.append(t)
    return Case(case.name, meshes, transforms, case.depth * k, case.convex, case.reported)


def turned(case: Case, rotation: np.ndarray) -> Case:
    """The pair under a common rotation about its origin (its depth is unchanged)."""
    return Case(case.name + ", turned", case.meshes, [rotation @ t for t in case.transforms],
                case.depth, case.convex, case.reported)


def assemble(cases: list[Case], spacing: float) -> tuple[list, list]:
    """All pairs in one scene, case k's pair at (2k, 2k + 1), ``spacing`` apart along x."""
    meshes, transforms = [], []
    for k, case in enumerate(cases):
        case.pair = (len(meshes), len(meshes) + 1)
        for m, t in zip(case.meshes, case.transforms):
            t = t.copy()
            t[0, 3] += k * spacing
            meshes.append(m)
            transforms.append(t)
    return meshes, transforms


def check(result, cases: list[Case], d: float, slack: float = 0.0) -> None:
    """The contract for every case of one query: pairs by exact depth, figures within bounds.
    ``slack``: the truth's own rounding (float64), added to every bound."""
    pairs = np.asarray(result.pairs)
    assert pairs.ndim == 2 and pairs.shape[1] == 2
    assert result.depths is not None and result.depth_errors is not None
    assert result.depths.dtype == np.float64 and result.depth_errors.dtype == np.float64
    assert result.depths.shape == result.depth_errors.shape == (len(pairs),)
    assert pairs.tolist() == sorted(pairs.tolist()), "pairs are not sorted"
    assert np.all(pairs[:, 0] < pairs[:, 1])
    assert np.all(np.isfinite(result.depths)) and np.all(np.isfinite(result.depth_errors))
    assert np.all(result.depths >= 0) and np.all(result.depth_errors >= 0)
    found = {tuple(p): k for k, p in enumerate(pairs.tolist())}
    known = {c.pair: c for c in cases}
    failures = [f"pair {p} of no case reported" for p in found if p not in known]
    for case in cases:
        k = found.get(case.pair)
        where = f"{case.name} (pair {case.pair}, depth {case.depth:.6g}, d {d:g})"
        if k is None:
            if case.must(d):
                failures.append(f"{where}: not reported")
            continue
        if case.must_not(d):
            failures.append(f"{where}: reported with depth {result.depths[k]:.6g}")
        got, bound = float(result.depths[k]), float(result.depth_errors[k])
        rounding = hardclash.ERROR_SCALE * reach(case)  # a bound of the figure's rounding
        tol = slack
        if case.depth > got + rounding + tol:
            failures.append(f"{where}: depth {got:.9g} is not an upper bound of {case.depth:.9g} "
                            f"(rounding bound {rounding:.3g})")
        if case.convex and case.depth < got - bound - tol:
            failures.append(f"{where}: depth {got:.9g} too far above the exact {case.depth:.9g} "
                            f"(bound {bound:.3g})")
        if got + bound < d * (1 - 1e-9):
            failures.append(f"{where}: reported with depth {got:.6g} + error {bound:.3g} "
                            f"below d")
    assert not failures, "\n".join(failures)


def reach(case: Case) -> float:
    """How far the pair's vertices can lie from any centre within its bodies' boxes: the
    diagonal of the box around both (what the rounding bound scales with)."""
    points = np.concatenate([_world(m, t) for m, t in zip(case.meshes, case.transforms)])
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def assert_exact(cases: list[Case], tol: float = 1e-9) -> None:
    """The analytic depths of convex cases agree with the separating-axis depth."""
    for case in cases:
        if case.convex:
            (a, b), (ta, tb) = case.meshes, case.transforms
            sat = convex_depth(a, ta, b, tb)
            assert abs(sat - case.depth) <= tol, (case.name, case.depth, sat)


# -- Shapes -------------------------------------------------------------------------------------

SLAB = trimesh.creation.box((2.0, 2.0, 1.0))
"""Top face at z = 0.5, wide enough that pressing a small body into it by less than 0.3 leaves
straight up as the shortest way out."""

BOX = trimesh.creation.box((1.0, 1.0, 1.0))
BEAM = trimesh.creation.box((0.2, 0.2, 1.5))
ROD = trimesh.creation.box((2.0, 0.2, 0.2))
CYLINDER = trimesh.creation.cylinder(radius=0.3, height=1.0, sections=24)
PIPE = trimesh.creation.cylinder(radius=0.25, height=1.2, sections=16)
"""Its ring has vertices at angles 0, 90, 180 and 270 degrees: lying along x (turned about y by
90 degrees), a line of vertices is lowest, at z = -0.25, and one highest, at +0.25."""
CAPSULE = trimesh.creation.capsule(height=0.6, radius=0.25, count=[16, 16])
"""Its poles are vertices at z = +-0.55."""
LYING = turn(np.pi / 2, (0, 1, 0))


def _lowest(mesh: trimesh.Trimesh, t: np.ndarray) -> float:
    return float(_world(mesh, t)[:, 2].min())


def pressed(name: str, depth: float) -> Case:
    """A convex body pressed ``depth`` into the slab's top (negative: apart). Its depth is
    ``max(depth, 0)``: straight up is the shortest way out of a slab this wide."""
    top = 0.5 - depth
    if name == "box":
        body, t = trimesh.creation.box((0.6, 0.5, 0.4)), move(0.1, -0.05, top + 0.2)
    elif name == "beam end":
        body, t = BEAM, move(-0.3, 0.2, top + 0.75)
    elif name == "cylinder end":
        body, t = CYLINDER, move(0.0, 0.1, top + 0.5)
    elif name == "pipe":
        body, t = PIPE, move(0.05, 0.0, top + 0.25, LYING)
    elif name == "capsule":
        body, t = CAPSULE, move(-0.1, 0.0, top + 0.55)
    elif name == "capsule lying":
        body = CAPSULE
        t = move(0.0, 0.1, 0.0, LYING)
        t[2, 3] = top - _lowest(body, t)
    else:
        raise ValueError(name)
    return Case(f"{name} {depth:+.4g} into a slab", [SLAB, body], [move(), t], max(depth, 0.0))


PRESSED = ("box", "beam end", "cylinder end", "pipe", "capsule", "capsule lying")


def test_pressed_cases_are_what_they_say(fcl):
    cases = [pressed(name, depth) for name in PRESSED for depth in (0.21, 0.105, 0.05, 0.0)]
    assert_exact(cases)
    apart = pressed("pipe", -0.02)
    assert surface_distance(apart.meshes[0], apart.meshes[1], apart.transforms) == \
        pytest.approx(0.02, abs=1e-9)


@pytest.mark.parametrize("scale", SCALES, ids=lambda k: f"scale {k:g}")
def test_convex_bodies_at_the_margins_at_three_scales(scale):
    """Boxes, a beam, cylinders and capsules pressed into a slab by 2 d and 1.05 d (always
    reported), by d/2, d/4, 0 (touching) and apart (never), as placed and under a random
    common rotation: every depth analytic (straight up out of the slab)."""
    d = 0.1
    rng = np.random.default_rng(17)
    cases = []
    for name in PRESSED:
        for depth in (2 * d, 1.05 * d, d / 2, d / 4, 0.0, -d / 5):
            case = pressed(name, depth)
            cases += [case, turned(case, random_rotation(rng))]
    cases = [scaled(c, scale) for c in cases]
    meshes, transforms = assemble(cases, 4.0 * scale)
    result = pycinder.Detector(min_depth=d * scale).find_collisions(meshes, transforms)
    check(result, cases, d * scale, slack=1e-9 * scale)
    reported = {tuple(p) for p in result.pairs.tolist()}
    assert reported == {c.pair for c in cases if c.depth > d * scale}


# -- Touching pairs -----------------------------------------------------------------------------

def touching_cases() -> list[Case]:
    corner_down = trimesh.geometry.align_vectors(np.ones(3) / np.sqrt(3), (0, 0, -1))
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    across = turn(np.pi / 2, (1, 0, 0))  # the pipe along y: its ring's lowest vertex at -0.25
    cases = [
        ("face on face", [BOX, BOX], [move(), move(1.0)]),
        ("face on face, offset", [BOX, BOX], [move(), move(1.0, 0.3, -0.2)]),
        ("beam end on a face", [BOX, BEAM], [move(), move(0.1, 0.2, 0.5 + 0.75)]),
        ("cylinder end on a face", [BOX, CYLINDER], [move(), move(0.0, 0.0, 1.0)]),
        ("edge on face", [BOX, BOX], [move(), move(0.0, 0.1, 0.5 + np.sqrt(0.5),
                                                   turn(np.pi / 4, (1, 0, 0)))]),
        ("corner on face", [BOX, BOX], [move(), move(0.1, 0.0, 0.5 + np.sqrt(3) / 2,
                                                     corner_down)]),
        ("butt joint, end to end", [ROD, ROD], [move(), move(2.0)]),
        ("butt joint, corner", [ROD, ROD], [move(), move(0.9, 1.1, 0.0,
                                                         turn(np.pi / 2, (0, 0, 1)))]),
        ("pipe lying on a box", [BOX, PIPE], [move(), move(0.0, 0.1, 0.75, LYING)]),
        ("pipe across a pipe", [PIPE, PIPE], [move(rotation=LYING), move(0, 0, 0.5, across)]),
        ("capsule on a face", [BOX, CAPSULE], [move(), move(0.2, 0.0, 1.05)]),
        ("sphere on a face", [BOX, sphere], [move(), move(0.0, 0.0, 0.5 - sphere.bounds[0, 2])]),
    ]
    return [Case(name, m, t, 0.0) for name, m, t in cases]


def test_touching_cases_touch(fcl):
    for case in touching_cases():
        (a, b), (ta, tb) = case.meshes, case.transforms
        overlap = separating_overlap(a, ta, b, tb)
        assert abs(overlap) <= 1e-12, (case.name, overlap)
        assert surface_distance(a, b, [ta, tb]) <= 1e-9, case.name


@pytest.mark.parametrize("scale", SCALES, ids=lambda k: f"scale {k:g}")
def test_touching_pairs_are_never_reported(scale):
    """Face on face, beam end on a face, edge and corner on a face, butt joints, a pipe lying on
    a box and across a pipe, each as placed and under a random common rotation: depth 0."""
    d = 0.05
    rng = np.random.default_rng(23)
    cases = []
    for case in touching_cases():
        cases += [case, turned(case, random_rotation(rng)), turned(case, random_rotation(rng))]
    cases = [scaled(c, scale) for c in cases]
    meshes, transforms = assemble(cases, 4.0 * scale)
    result = pycinder.Detector(min_depth=d * scale).find_collisions(meshes, transforms)
    check(result, cases, d * scale, slack=1e-9 * scale)
    assert result.pairs.tolist() == []


# -- Random convex pairs ------------------------------------------------------------------------

def _hull(rng: np.random.Generator, points: int = 30) -> trimesh.Trimesh:
    return trimesh.convex.convex_hull(rng.normal(size=(points, 3)) * rng.uniform(0.25, 0.45))


def _at_depth(a, ta, b, tb, direction, depth) -> np.ndarray:
    """``tb`` moved along ``direction`` so that the exact depth is ``depth`` (bisection on the
    separating-axis overlap, which is continuous and 0 where the bodies first touch)."""
    far = np.linalg.norm(a.extents) + np.linalg.norm(b.extents)

    def at(s):
        t = tb.copy()
        t[:3, 3] += s * direction
        return t

    lo, hi = 0.0, far  # overlap(lo) > depth >= overlap(hi)
    assert separating_overlap(a, ta, b, at(lo)) > depth
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if separating_overlap(a, ta, b, at(mid)) > depth:
            lo = mid
        else:
            hi = mid
    return at(hi if depth > 0 else lo)


def random_convex_cases(seed: int, d: float) -> list[Case]:
    rng = np.random.default_rng(seed)
    cases = []
    for k, target in enumerate([0.0, 0.25 * d, 0.5 * d, 1.05 * d, 1.5 * d, 3 * d, -0.3 * d] * 2):
        a, b = _hull(rng), _hull(rng)
        ta, tb = move(rotation=random_rotation(rng)), move(rotation=random_rotation(rng))
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        if target < 0:  # apart: past first contact by -target along the direction
            tb = _at_depth(a, ta, b, tb, direction, 0.0)
            tb[:3, 3] -= target * direction
        else:
            tb = _at_depth(a, ta, b, tb, direction, target)
        cases.append(Case(f"random hulls {k}, depth {target:.4g}", [a, b], [ta, tb],
                          convex_depth(a, ta, b, tb)))
    return cases


def test_separating_axes_agree_with_coal():
    """The separating-axis depth is coal's EPA penetration depth (coal: an optional check)."""
    pytest.importorskip("coal", reason="coal's EPA is the optional second truth")
    for case in random_convex_cases(29, 0.1):
        (a, b), (ta, tb) = case.meshes, case.transforms
        assert coal_depth(a, ta, b, tb) == pytest.approx(case.depth, abs=1e-6), case.name


def test_random_convex_pairs_against_exact_depths():
    """Random convex hulls, randomly turned, placed at depths from apart to 3 d along a random
    direction: every pair deeper than d reported, none at most d/2 deep, each figure within its
    bound of the exact depth."""
    d = 0.08
    cases = random_convex_cases(31, d)
    for case, target in zip(cases, [0.0, 0.25 * d, 0.5 * d, 1.05 * d, 1.5 * d, 3 * d, 0.0] * 2):
        assert case.depth == pytest.approx(target, abs=1e-9), case.name
    meshes, transforms = assemble(cases, 5.0)
    result = pycinder.Detector(min_depth=d).find_collisions(meshes, transforms)
    check(result, cases, d, slack=1e-9)
    assert {tuple(p) for p in result.pairs.tolist()} >= {c.pair for c in cases if c.depth > d}


# -- Non-convex and nested bodies ---------------------------------------------------------------

def u_shape() -> trimesh.Trimesh:
    """A block 1 x 0.6 x 0.6 about the origin with a slot 0.6 wide and 0.4 deep along y, open to
    +z: prongs at |x| in [0.3, 0.5], z in [-0.1, 0.3]; its base z in [-0.3, -0.1]."""
    from pycinder.testing import _manifold3d

    m3d = _manifold3d()
    block = m3d.Manifold.cube((1.0, 0.6, 0.6), center=True)
    slot = m3d.Manifold.cube((0.6, 1.0, 0.5), center=True).translate((0.0, 0.0, 0.15))
    mesh = (block - slot).to_mesh()
    return _snapped(trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3],
                                    np.asarray(mesh.tri_verts)))


def _snapped(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """manifold3d's vertices are single precision: back on the grid of the dimensions given."""
    return trimesh.Trimesh(np.round(np.asarray(mesh.vertices, np.float64), 6), mesh.faces,
                           process=False)


def nonconvex_cases() -> list[Case]:
    """Depths by hand (both bodies are prisms, so a pair overlaps where both projections do).

    L (:func:`l_shape`): arm x in [-0.5, 0.5], y in [-0.5, -0.2]; leg x in [-0.5, -0.2],
    y in [-0.5, 0.5]; z in [-0.25, 0.25]. A bar 0.1 x 0.1 x 2 along z through the arm at
    x 0.2, y -0.35 leaves it by 0.2 along +-y (+x: 0.35; -x: through the leg; z: 1.25).
    U (:func:`u_shape`): a bar 0.1 x 0.1 x 2 along x through both prongs at z 0.15 leaves
    them by 0.2 up (y: 0.35; down: 0.5; x: 1.5). A small box inside the L's arm leaves by 0.2
    along +-y. A bar in the U's slot, along it: apart, touching its floor, or pressed 0.02
    into the floor: up (z, one of the directions) takes it out by at most that, so its
    directional depth is at most 0.02."""
    bar_z = trimesh.creation.box((0.1, 0.1, 2.0))
    bar_x = trimesh.creation.box((2.0, 0.1, 0.1))
    slot_bar = trimesh.creation.box((0.2, 1.0, 0.1))
    small = trimesh.creation.box((0.1, 0.1, 0.1))
    ell, you = _snapped(l_shape()), u_shape()
    return [
        Case("bar through the L's arm", [ell, bar_z], [move(), move(0.2, -0.35)], 0.2, False),
        Case("bar through both prongs of the U", [you, bar_x], [move(), move(0, 0, 0.15)], 0.2,
             False),
        Case("small box inside the L's arm", [ell, small], [move(), move(0.2, -0.35)], 0.2,
             False),
        Case("bar grazing the L's arm", [ell, bar_z], [move(), move(0.2, -0.175)], 0.025, False,
             reported=False),
        Case("bar in the U's slot, apart", [you, slot_bar], [move(), move(0, 0, -0.03)], 0.0,
             False, reported=False),
        Case("bar in the U's slot, on its floor", [you, slot_bar], [move(), move(0, 0, -0.05)],
             0.0, False, reported=False),
        Case("bar in the U's slot, pressed 0.02", [you, slot_bar], [move(), move(0, 0, -0.07)],
             0.02, False, reported=False),
    ]


def nested_cases() -> list[Case]:
    """A small box (0.2) inside a unit box: out along x by 0.5 + 0.1 - 0.25 = 0.35, or 0.2 where
    it is flush with the wall; a turned one and a ball inside, by the separating axes (both
    convex)."""
    small = trimesh.creation.box((0.2, 0.2, 0.2))
    ball = trimesh.creation.icosphere(subdivisions=1, radius=0.15)
    rng = np.random.default_rng(41)
    cases = [Case("small box inside a box", [BOX, small], [move(), move(0.25, 0.1, -0.05)],
                  0.35),
             Case("small box inside a box, flush with its wall", [BOX, small],
                  [move(), move(0.4, 0.1, -0.05)], 0.2)]
    for name, body, t in (("turned small box inside a box", small,
                           move(-0.1, 0.2, 0.05, random_rotation(rng))),
                          ("ball inside a box", ball, move(0.0, -0.2, 0.1))):
        cases.append(Case(name, [BOX, body], [move(), t], convex_depth(BOX, move(), body, t)))
    return cases


def test_nonconvex_cases_are_what_they_say(fcl):
    assert_exact(nested_cases())
    you = u_shape()
    assert you.is_watertight and you.is_volume and not you.is_convex
    assert np.allclose(you.bounds, [[-0.5, -0.3, -0.3], [0.5, 0.3, 0.3]])
    assert you.volume == pytest.approx(0.36 - 0.6 * 0.6 * 0.4)
    cases = {c.name: c for c in nonconvex_cases()}
    for name, distance in (("bar in the U's slot, apart", 0.02),
                           ("bar in the U's slot, on its floor", 0.0)):
        (a, b), t = cases[name].meshes, cases[name].transforms
        assert surface_distance(a, b, t) == pytest.approx(distance, abs=1e-7), name
    # The small box in the L's arm: inside it (no surface crossing), its depth from the arm
    # (a box, convex) alone, which the way out along +y also clears the leg.
    arm = trimesh.creation.box((1.0, 0.3, 0.5))
    case = cases["small box inside the L's arm"]
    assert convex_depth(arm, move(0.0, -0.35), case.meshes[1], case.transforms[1]) == \
        pytest.approx(0.2)


def test_nonconvex_and_nested_bodies():
    """Bars through an L's arm and a U's prongs, boxes and a ball inside other bodies:
    reported with figures bounding their depths; bars in a U's slot (apart, touching, pressed
    less than d) and grazing the L are not."""
    d = 0.1
    cases = nonconvex_cases() + nested_cases()
    meshes, transforms = assemble(cases, 4.0)
    result = pycinder.Detector(min_depth=d).find_collisions(meshes, transforms)
    check(result, cases, d, slack=1e-9)


def test_nested_bodies_at_most_half_d_deep_are_not_reported():
    """Convex bodies inside a box, at most 0.47 deep: with d = 1, none is reported."""
    cases = nested_cases()
    assert max(c.depth for c in cases) <= 0.5
    meshes, transforms = assemble(cases, 4.0)
    result = pycinder.Detector(min_depth=1.0).find_collisions(meshes, transforms)
    check(result, cases, 1.0, slack=1e-9)
    assert result.pairs.tolist() == []


def test_coincident_thin_and_scaled_convex_bodies():
    """A box on itself, a bar through a thin plate, boxes stretched by their transforms (not
    rigid), each as placed and turned: depths by the separating axes."""
    d = 0.1
    plate = trimesh.creation.box((1.0, 1.0, 0.02))
    bar = trimesh.creation.box((0.1, 0.1, 1.0))
    stretch = move(1.2)
    stretch[:3, :3] = np.diag([2.0, 0.5, 1.0])
    shear = move(0.2, 0.7, 0.1)
    shear[:3, :3] = [[1.0, 0.3, 0.0], [0.0, 0.8, 0.0], [0.0, 0.2, 1.2]]
    rng = np.random.default_rng(53)
    cases = []
    for name, meshes, transforms in (
            ("box on itself", [BOX, BOX], [move(), move()]),
            ("bar through a thin plate", [plate, bar], [move(), move(0.1, -0.2, 0.1)]),
            ("bar through a thin plate, slanted", [plate, bar],
             [move(), move(0.1, 0.0, 0.0, turn(0.5, (1, 1, 0)))]),
            ("box stretched by its transform", [BOX, BOX], [move(), stretch]),
            ("box sheared by its transform", [BOX, BOX], [move(), shear])):
        depth = convex_depth(meshes[0], transforms[0], meshes[1], transforms[1])
        case = Case(name, meshes, transforms, depth)
        cases += [case, turned(case, random_rotation(rng))]
    assert [round(c.depth, 9) for c in cases[:8:2]] == [1.0, 0.35, round(cases[4].depth, 9), 0.3]
    assert all(c.depth > d for c in cases)
    meshes, transforms = assemble(cases, 5.0)
    result = pycinder.Detector(min_depth=d).find_collisions(meshes, transforms)
    check(result, cases, d, slack=1e-9)


# -- Open bodies --------------------------------------------------------------------------------

def open_cases() -> list[Case]:
    """Open bodies are surfaces: depth is the translation that uncrosses them.

    Cup (:func:`open_cup`, the unit box without its top): a bar 0.7 x 0.1 x 0.1 through its
    wall x = 0.5, from x 0.2 to 0.9, uncrosses by 0.3 along +x (-x: 0.4; up, down, y: 0.55); a
    box 0.4 wide through its floor z = -0.5, up to z -0.2, by 0.3 down (sideways: 0.7). A
    sheet (:func:`grid_plate`, 2 wide, z = 0) through a box 0.6 high by 0.3 up or down
    (sideways: 1.3). A sheet lying on a box, a ball inside the cup clear of its walls: their
    surfaces do not cross, and their directional depth is 0 (up: the cup is open to +z)."""
    cup = open_cup(1.0)
    sheet = grid_plate(2.0, 4)
    bar = trimesh.creation.box((0.7, 0.1, 0.1))
    block = trimesh.creation.box((0.4, 0.4, 0.6))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    cube = trimesh.creation.box((0.6, 0.6, 0.6))
    small_sheet = grid_plate(1.0, 4)
    tube = open_tube(0.4, 1.0, 16)
    rng = np.random.default_rng(43)
    cases = [
        Case("bar through a cup's wall", [cup, bar], [move(), move(0.55, 0.1, 0.0)], 0.3, False),
        Case("box through a cup's floor", [cup, block], [move(), move(0.05, 0.0, -0.5)], 0.3,
             False),
        Case("sheet through a box", [sheet, cube], [move(), move(0.1, 0.0, 0.0)], 0.3, False),
        Case("sheet lying on a box", [sheet, cube], [move(), move(0.0, 0.2, -0.3)], 0.0, False,
             reported=False),
        Case("ball in a cup", [cup, ball], [move(), move(0.0, 0.0, -0.2)], 0.0, False,
             reported=False),
        Case("sheet inside a box", [BOX, grid_plate(0.4, 2)], [move(), move(0.1, 0.0, 0.05)],
             0.45, False),
        Case("box around a sheet", [grid_plate(0.4, 2), BOX], [move(0.1, 0.0, 0.05), move()],
             0.45, False),
        Case("sheets crossing", [sheet, small_sheet], [move(), move(0.3, 0.0, 0.0, LYING)], 0.5,
             False),
        Case("bar through a tube's wall", [tube, trimesh.creation.box((0.1, 0.1, 0.6))],
             [move(), move(0.4, 0.0, 0.1, LYING)], 0.3, False),
    ]
    return cases + [turned(c, random_rotation(rng)) for c in cases]


def test_open_cases_are_what_they_say(fcl):
    for case in open_cases():
        distance = surface_distance(*case.meshes, case.transforms)
        if "inside" in case.name or "around" in case.name:
            assert distance > 0.1, (case.name, distance)  # inside, not crossing
        elif case.depth > 0:
            assert distance <= 0.0, (case.name, distance)  # the surfaces cross
            assert fcl_crosses(case), case.name
        elif "lying" in case.name:
            assert abs(distance) <= 1e-9, (case.name, distance)  # they touch
        else:
            assert distance > 0.05, (case.name, distance)


@pytest.mark.filterwarnings("ignore::pycinder.OpenMeshWarning")
def test_open_bodies_crossing_deeply_are_reported():
    """Open bodies through and inside solids and each other deeper than d: reported, with
    figures bounding their depths; touching and clear of each other: not."""
    d = 0.1
    cases = open_cases()
    meshes, transforms = assemble(cases, 4.0)
    result = pycinder.Detector(min_depth=d).find_collisions(meshes, transforms)
    check(result, cases, d, slack=1e-9)


# -- A dense scene ------------------------------------------------------------------------------

def test_dense_scene_of_boxes_against_separating_axes():
    """Thirty random boxes, randomly turned, crowded in a cube: every pair's depth exact."""
    rng = np.random.default_rng(47)
    meshes, transforms = [], []
    for _ in range(30):
        meshes.append(trimesh.creation.box(rng.uniform(0.15, 0.5, 3)))
        transforms.append(move(*rng.uniform(0.0, 1.3, 3), random_rotation(rng)))
    d = 0.04
    cases = []
    for i in range(len(meshes)):
        for j in range(i + 1, len(meshes)):
            depth = convex_depth(meshes[i], transforms[i], meshes[j], transforms[j])
            cases.append(Case(f"boxes {i} and {j}", [meshes[i], meshes[j]],
                              [transforms[i], transforms[j]], depth, pair=(i, j)))
    assert sum(c.depth > d for c in cases) >= 5
    assert sum(0 < c.depth <= d / 2 for c in cases) >= 3
    result = pycinder.Detector(min_depth=d).find_collisions(meshes, transforms)
    check(result, cases, d, slack=1e-9)


# -- Entry points, options, results -------------------------------------------------------------

def _two_boxes(overlap: float) -> list:
    """Two unit boxes side by side, overlapping by ``overlap`` along x (depth: overlap)."""
    return [move(), move(1.0 - overlap, 0.2, -0.1)]


def _depth_ok(result, k: int, exact: float) -> None:
    assert abs(result.depths[k] - exact) <= result.depth_errors[k] + 1e-9, \
        (result.depths[k], exact, result.depth_errors[k])


def test_every_entry_point_carries_depths():
    d = 0.1
    det = pycinder.Detector(min_depth=d)
    for result in (det.find_collisions([BOX, BOX], _two_boxes(0.3)),
                   pycinder.find_collisions([BOX, BOX], _two_boxes(0.3), min_depth=d),
                   det.find_collisions(det.prepare([BOX, BOX]), _two_boxes(0.3))):
        assert result.pairs.tolist() == [[0, 1]]
        _depth_ok(result, 0, 0.3)
    shallow = det.find_collisions([BOX, BOX], _two_boxes(0.04))
    assert shallow.pairs.tolist() == [] and len(shallow.depths) == 0
    assert shallow.depths.dtype == np.float64
    assert pycinder.Detector().find_collisions([BOX, BOX], _two_boxes(0.3)).depths is None
    prepared = det.prepare([BOX, BOX, BOX])
    result = det.find_collisions(prepared, [move(), move(0.75), move(2.0)])
    assert result.pairs.tolist() == [[0, 1]]
    _depth_ok(result, 0, 0.25)


def test_batches_carry_depths():
    from pycinder.batch import find_collisions_batch

    det = pycinder.Detector(min_depth=0.1)
    scenes = [([BOX, BOX], _two_boxes(0.3)), ([BOX, BOX], _two_boxes(0.04)),
              ([BOX, BOX, BOX], [move(), move(0.8), move(1.4)])]
    for deep, shallow, three in (det.find_collisions_batch(scenes),
                                 find_collisions_batch(det, scenes)):
        assert deep.pairs.tolist() == [[0, 1]]
        _depth_ok(deep, 0, 0.3)
        assert shallow.pairs.tolist() == [] and len(shallow.depths) == 0
        assert three.pairs.tolist() == [[0, 1], [1, 2]]
        _depth_ok(three, 0, 0.2)
        _depth_ok(three, 1, 0.4)


def test_records_none_still_answers_with_figures():
    """No record kept: every pair still answered, with its figure."""
    d = 0.1
    cases = [Case("boxes 0.3 deep", [BOX, BOX], _two_boxes(0.3), 0.3),
             Case("boxes 0.03 deep", [BOX, BOX], _two_boxes(0.03), 0.03),
             nested_cases()[0]]
    meshes, transforms = assemble(cases, 4.0)
    for result in (pycinder.Detector(min_depth=d, records="none").find_collisions(meshes,
                                                                                  transforms),
                   pycinder.Detector(min_depth=d).find_collisions(meshes, transforms,
                                                                  records="none")):
        check(result, cases, d, slack=1e-9)
        assert result.pairs.tolist() == [[0, 1], [4, 5]]


def test_result_with_depths_pickles():
    result = pycinder.Detector(min_depth=0.1).find_collisions([BOX, BOX], _two_boxes(0.3))
    copy = pickle.loads(pickle.dumps(result))
    assert copy.pairs.tolist() == result.pairs.tolist() == [[0, 1]]
    assert copy.depths.tolist() == result.depths.tolist()
    assert copy.depth_errors.tolist() == result.depth_errors.tolist()
    assert copy.distances is None


def test_options_are_checked():
    for bad in (0, -1.0, float("nan"), float("inf"), True, "1"):
        with pytest.raises(ValueError, match="min_depth must be a positive number"):
            pycinder.Detector(min_depth=bad)
    with pytest.raises(ValueError, match="min_depth must be a positive number"):
        pycinder.find_collisions([BOX, BOX], _two_boxes(0.3), min_depth=-0.1)
    with pytest.raises(ValueError, match="min_depth and clearance"):
        pycinder.Detector(min_depth=0.1, clearance=0.1)
    with pytest.raises(ValueError, match="min_depth applies to strategy='focused'"):
        pycinder.Detector(min_depth=0.1, strategy="scene")
    with pytest.raises(ValueError, match="contacts=True and min_depth"):
        pycinder.Detector(min_depth=0.1, contacts=True)
    with pytest.raises(ValueError, match="contacts=True and min_depth"):
        pycinder.find_collisions([BOX, BOX], _two_boxes(0.3), min_depth=0.1, contacts=True)


def test_contacts_of_a_depth_result_say_where_its_figures_are():
    result = pycinder.Detector(min_depth=0.1).find_collisions([BOX, BOX], _two_boxes(0.3))
    with pytest.raises(ValueError, match=r"result\.depths"):
        result.contacts()


def test_a_min_depth_too_small_for_single_precision_is_refused():
    """Two 10 km boxes: a figure whose rounding cannot tell whether they are deeper than 1 mm
    would need too many regions, and the pair is refused by name; 0.5 m deep they are deeper
    than 1 mm whatever the rounding, and reported with a depth within its stated error."""
    big = trimesh.creation.box((1e4, 1e4, 1e4))
    with pytest.raises(ValueError, match=r"(?s)min_depth.*too small.*'wall'.*'slab'"):
        pycinder.Detector(min_depth=1e-3).find_collisions(
            [big, big], [move(), move(1e4 - 0.75e-3)], names=["wall", "slab"])
    deep = pycinder.Detector(min_depth=1e-3).find_collisions(
        [big, big], [move(), move(1e4 - 0.5)], names=["wall", "slab"])
    assert deep.pairs.tolist() == [[0, 1]]
    assert deep.depths[0] - deep.depth_errors[0] <= 0.5 <= deep.depths[0] + 1e-6 * 1e4


def test_groups_one_body_far_bodies_and_a_body_far_from_the_origin():
    det = pycinder.Detector(min_depth=0.1)
    result = det.find_collisions([BOX, BOX, BOX], [move(), move(0.5), move(0.2, 0.3)],
                                 groups=[0, 0, 1])
    assert result.pairs.tolist() == [[0, 2], [1, 2]]  # (0, 1) is 0.5 deep, in one group
    _depth_ok(result, 0, 0.7)
    _depth_ok(result, 1, 0.7)
    for meshes, transforms in (([BOX], [move()]), ([BOX, BOX], [move(), move(5.0)])):
        result = det.find_collisions(meshes, transforms)
        assert result.pairs.shape == (0, 2) and result.depths.shape == (0,)
        assert result.depth_errors.shape == (0,)
    far = det.find_collisions([BOX, BOX, BOX], [move(1e6), move(1e6 + 0.7), move(1e6, 0.97)])
    assert far.pairs.tolist() == [[0, 1]]  # (0, 2) and (1, 2): 0.03 deep
    _depth_ok(far, 0, 0.3)


def test_in_collision_and_submit_answer_the_hard_clash_question():
    det = pycinder.Detector(min_depth=0.1)
    assert det.in_collision([BOX, BOX], _two_boxes(0.3))
    assert not det.in_collision([BOX, BOX], _two_boxes(0.04))
    pending = det.submit([BOX, BOX], _two_boxes(0.25))
    result = pending.result()
    assert result.pairs.tolist() == [[0, 1]]
    _depth_ok(result, 0, 0.25)


def test_per_call_contacts_are_refused_as_the_detector_option_is():
    det = pycinder.Detector(min_depth=0.1)
    with pytest.raises(ValueError, match=r"contacts=True is not available with min_depth"):
        det.find_collisions([BOX, BOX], _two_boxes(0.3), contacts=True)
    result = det.find_collisions([BOX, BOX], _two_boxes(0.3), contacts=False)
    assert result.pairs.tolist() == [[0, 1]]
    _depth_ok(result, 0, 0.3)


def test_a_deforming_body_is_measured_as_it_is_now():
    """The same detector, a box whose vertices change every query (same faces): each query
    measures the box as it is then, not as the first query saw it."""
    det = pycinder.Detector(min_depth=0.1)
    v, f = np.asarray(BOX.vertices), np.asarray(BOX.faces)
    prepared = det.prepare([BOX, (v * [0.3, 1.0, 1.0], f)])
    for width, overlap in ((0.3, 0.2), (0.5, 0.03), (0.56, 0.15), (0.44, 0.04), (0.2, 0.19)):
        # Box b spans width along x; it reaches overlap into box a (its depth: overlap).
        transforms = [move(), move(0.5 - overlap + width / 2)]
        prepared.update(1, v * [width, 1.0, 1.0])
        for result in (det.find_collisions([BOX, (v * [width, 1.0, 1.0], f)], transforms),
                       det.find_collisions(prepared, transforms)):
            if overlap > 0.1:
                assert result.pairs.tolist() == [[0, 1]], (width, overlap)
                _depth_ok(result, 0, overlap)
            else:
                assert result.pairs.tolist() == [], (width, overlap)


def test_contacts_of_pairs_whose_records_were_all_dropped_are_measured(monkeypatch):
    """Records beyond one buffer of the device are dropped: the pairs left with none still get
    a contact, measured whole by pass H1 (depth, and the direction that clears the pair),
    batches included.

    Which records a full buffer keeps depends on the order the device's threads append them.
    A buffer of one record keeps at most one pair's, on any device, so that at least two of
    the three pairs are left with none."""
    from pycinder.focused.frame.atlas_buffers import AtlasBuffers, Caps

    monkeypatch.setattr(AtlasBuffers, "limits", property(lambda self: Caps(
        tris=self.tris.limit // 48, records=1, edges=self.edge_list.limit // 16)))
    det = pycinder.Detector(contacts=True, tolerance=0.01)
    # Three pairs, each overlapping 0.3 along x: thousands of records each.
    meshes = [BOX] * 6
    transforms = [move(3 * k + dx) for k in range(3) for dx in (0.0, 0.7)]
    with pytest.warns(pycinder.LossWarning, match="measured per pair"):
        result = det.find_collisions(meshes, transforms)
    pairs = {(0, 1), (2, 3), (4, 5)}
    assert result.pairs.tolist() == sorted(map(list, pairs))
    assert result.stats.dropped_records > 0 and len(result.records) <= 1
    kept = {tuple(sorted(p)) for p in zip(result.records["penetrating"].tolist(),
                                           result.records["penetrated"].tolist())}
    measured = result.measured_contacts
    assert measured is not None
    # exactly the pairs left with no record are measured, each once
    assert sorted(map(tuple, measured.pair.tolist())) == sorted(pairs - kept)
    assert len(pairs - kept) >= 2
    for k in range(len(measured)):
        assert measured.depth[k] == pytest.approx(0.3, abs=1e-5)
        assert measured.normal[k] == pytest.approx([1.0, 0.0, 0.0], abs=1e-6)  # from a into b
    contacts = result.contacts()
    assert set(map(tuple, contacts.pair.tolist())) == pairs
    # Batches give each scene its own measured contacts, in its own indices.
    with pytest.warns(pycinder.LossWarning, match="measured per pair"):
        results = det.find_collisions_batch([([BOX, BOX], [move(), move(0.7)])] * 3)
    assert sum(one.measured_contacts is not None for one in results) >= 2
    for one in results:
        assert set(map(tuple, one.contacts().pair.tolist())) == {(0, 1)}


# The direction worst covered by the 26 world directions (cosine 0.88645 to the nearest).
WORST = np.array([0.88645189, -0.36718039, -0.28174743]) / np.linalg.norm(
    [0.88645189, -0.36718039, -0.28174743])


def test_sliver_faces_on_the_contact_do_not_make_a_touching_pair_a_clash():
    """A convex tetrahedron whose top face is split into thin slivers along its edges, and a
    prism standing on that face overhanging its corners, touching along the direction the lines
    cover worst: depth 0, never reported (a point beyond a sliver's sharp corner, along an edge's
    line, is not inside it)."""
    m = WORST
    t1 = np.cross(m, [0, 0, 1.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(m, t1)
    c = np.array([np.cos(t) * t1 + np.sin(t) * t2 for t in np.radians([90, 210, 330])]) * 10
    edge = np.linalg.norm(c[1] - c[0])
    s = [0.5 * (c[j] + c[(j + 1) % 3])
         * (1 - 2e-3 * edge / np.linalg.norm(c[j] + c[(j + 1) % 3])) for j in range(3)]
    v = np.vstack([c, s, -8 * m])
    f = [(0, 1, 3), (1, 2, 4), (2, 0, 5), (3, 4, 5), (0, 3, 5), (1, 4, 3), (2, 5, 4), (6, 1, 0),
         (6, 2, 1), (6, 0, 2)]
    f = [x if np.cross(v[x[1]] - v[x[0]], v[x[2]] - v[x[0]]) @ (v[list(x)].mean(0) - v.mean(0))
         > 0 else x[::-1] for x in f]
    a = trimesh.Trimesh(v, f, process=False)
    p = np.array([c[j] + 0.003 * (c[j] - c[k]) for j in range(3) for k in ((j + 1) % 3,
                                                                          (j + 2) % 3)])
    b = trimesh.convex.convex_hull(np.vstack([p, p + 5 * m]))
    assert a.is_watertight and a.is_convex and b.is_convex
    result = pycinder.Detector(min_depth=0.01).find_collisions([a, b])
    assert result.pairs.tolist() == []


def test_edges_crossing_at_a_shallow_angle_on_a_touching_face_are_not_a_clash():
    """Two unit cubes face to face along the worst-covered direction, one turned a few
    micro-radians about the normal: their edges cross at shallow angles on screen, and both
    depths of a crossing are taken at one point. At the smallest d single precision allows,
    never reported."""
    z = np.array([0, 0, 1.0])
    turn = trimesh.transformations.rotation_matrix(np.arccos(z @ WORST), np.cross(z, WORST))
    for delta in (*np.geomspace(4e-6, 2e-5, 5), 6.93e-6, 1.176e-5):
        for off in ((1e-6, 0.0), (2e-6, 0.0), (5e-7, 0.0), (0.0, 1e-6)):
            a = trimesh.creation.box((1, 1, 1))
            a.apply_translation((0, 0, -0.5))
            b = trimesh.creation.box((1, 1, 1))
            b.apply_translation((0, 0, 0.5))
            b.apply_transform(trimesh.transformations.rotation_matrix(delta, z))
            b.apply_translation((*off, 0))
            a.apply_transform(turn)
            b.apply_transform(turn)
            lo = np.maximum(a.bounds[0], b.bounds[0])
            hi = np.minimum(a.bounds[1], b.bounds[1])
            o = (lo + hi) / 2
            reach = np.sqrt((np.abs(np.stack([*a.bounds, *b.bounds]) - o).max(0) ** 2).sum())
            d = 16 * hardclash.ERROR_SCALE * reach * 1.001
            result = pycinder.Detector(min_depth=d).find_collisions([a, b])
            assert result.pairs.tolist() == [], (delta, off)


@pytest.mark.parametrize("ball, sections", [(4, None), (None, 768)])
def test_a_whole_item_of_many_rounds_keeps_every_figure(ball, sections):
    """A pair measured as one whole item of many rounds (a 5,120-face ball, a 3,072-face
    cylinder, each against a box 0.25 m inside it): every thread of the workgroup must finish,
    or the figures are lost and the pair is missed (a CPU adapter ended such workgroups early;
    they are measured again in items of a cluster of each body). Both bodies reach x = 1 m
    exactly (a vertex of each), so the box's shortest separating translation is 0.25 m along
    x (any other way it must travel farther)."""
    body = (trimesh.creation.icosphere(subdivisions=ball) if ball is not None
            else trimesh.creation.cylinder(radius=1.0, height=1.0, sections=sections))
    assert body.vertices[:, 0].max() == pytest.approx(1.0)
    box = trimesh.creation.box((0.5, 0.5, 0.5))
    place = move(1.0)
    result = pycinder.Detector(min_depth=0.01).find_collisions([body, box], [np.eye(4), place])
    assert result.pairs.tolist() == [[0, 1]]
    assert result.depths[0] - result.depth_errors[0] - 1e-6 <= 0.25 <= result.depths[0] + 1e-6


def test_pairs_whose_threads_did_not_all_finish_are_measured_again(monkeypatch):
    """A dispatch whose word DONE says some threads of a pair's items did not finish: the pair is
    measured again, every line, in items of a cluster of each body, with the same answer; if
    that fails too, a RuntimeError (never figures that miss a clash)."""
    from pycinder.focused.measure import h1_depth

    meshes = [trimesh.creation.icosphere(subdivisions=3), BOX]
    transforms = [np.eye(4), move(1.2)]
    expected = pycinder.Detector(min_depth=0.01).find_collisions(meshes, transforms)
    real = h1_depth.Depth.words
    calls = []

    def short(self, positions, faces, items, frames):
        words = real(self, positions, faces, items, frames)
        calls.append(len(items))
        if len(calls) == 1:
            words[:, h1_depth.DONE] = 8  # as a CPU adapter cut the workgroups short
        return words

    monkeypatch.setattr(h1_depth.Depth, "words", short)
    again = pycinder.Detector(min_depth=0.01).find_collisions(meshes, transforms)
    assert len(calls) == 2 and calls[1] > calls[0]  # measured again in more, smaller items
    assert again.pairs.tolist() == expected.pairs.tolist() == [[0, 1]]
    assert again.depths[0] == pytest.approx(expected.depths[0], abs=1e-5)

    def never(self, positions, faces, items, frames):
        words = real(self, positions, faces, items, frames)
        words[:, h1_depth.DONE] = 0
        return words

    monkeypatch.setattr(h1_depth.Depth, "words", never)
    with pytest.raises(RuntimeError, match="before all their threads finished"):
        pycinder.Detector(min_depth=0.01).find_collisions(meshes, transforms)


def test_split_items_cover_every_face_pair_once():
    from pycinder.focused.measure.h1_depth import ITEM, ITEM_FLIPPED, ITEM_WHOLE, split_items

    items = ITEM.zeros(2)
    items[0] = (0, 10, 200, 500, 70, ITEM_WHOLE)
    items[1] = (1, 900, 40, 1000, 130, ITEM_WHOLE | ITEM_FLIPPED)  # a's faces are 1000...
    parts = split_items(items)
    assert np.all(parts["a_count"] <= 64) and np.all(parts["b_count"] <= 64)
    assert np.all(parts["whole"] == 0)
    for pair, (a0, na, b0, nb) in ((0, (10, 200, 500, 70)), (1, (1000, 130, 900, 40))):
        mine = parts[parts["pair"] == pair]
        covered = np.zeros((na, nb), int)
        for p in mine:
            covered[p["a_start"] - a0:p["a_start"] - a0 + p["a_count"],
                    p["b_start"] - b0:p["b_start"] - b0 + p["b_count"]] += 1
        assert np.all(covered == 1)


@pytest.mark.parametrize("pressed, reported", [(0.0004, False), (0.003, True)])
def test_pairs_their_boxes_clear_by_half_d_take_no_pass(monkeypatch, pressed, reported):
    """An L-shaped column and a box turned 30 degrees about z stand on a slab, pressed into it by
    0.4 mm or by 3 mm, with d = 2 mm. Lifting either by how far it is pressed in separates it
    from the slab, so that is how deep it is. Pressed 0.4 mm (at most d / 2), their world
    boxes show it: neither pair is reported, and pass H1 measures neither. Pressed 3 mm, both
    are measured and reported, 3 mm deep within their bounds."""
    from pycinder.focused.measure import h1_depth

    slab = trimesh.creation.box((4.0, 4.0, 0.2))
    column, box = l_shape(), trimesh.creation.box((0.5, 0.5, 0.5))
    turn = trimesh.transformations.rotation_matrix(np.pi / 6, (0, 0, 1))
    up = 0.25 - pressed  # the column's and the box's centres: their bottoms at z = -pressed
    transforms = [move(z=-0.1), move(-1.0, 0.0, up), move(1.0, 0.0, up, turn)]
    measured = []
    real = h1_depth.Depth.run

    def counted(self, positions, faces, items, frames):
        measured.append(len(frames))
        return real(self, positions, faces, items, frames)

    monkeypatch.setattr(h1_depth.Depth, "run", counted)
    result = pycinder.Detector(min_depth=0.002).find_collisions([slab, column, box], transforms)
    if not reported:
        assert result.pairs.tolist() == [] and sum(measured) == 0
        return
    assert result.pairs.tolist() == [[0, 1], [0, 2]] and sum(measured) > 0
    for depth, error in zip(result.depths, result.depth_errors):
        assert depth - error - 1e-6 <= pressed <= depth + 1e-6

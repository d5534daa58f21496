"""Local depth: interlocking pairs (a pipe in a sleeve, a duct in a wall's opening, a beam in a
column's slot, two linked rings) at a graze of 0.5 mm and an overlap of 5 mm, hard clashes at
d = 2 mm, against exact geometry (manifold3d's float64 booleans):

* a graze: moving one body 0.5 mm (and a little) along a known direction leaves no volume in
  common, so its local depth is at most that: never reported (at most d / 2);
* an overlap: a ball of radius 1.2 mm lies inside both bodies where they overlap, so any
  translation that separates them, here or in a box around the overlap, is at least 2.4 mm:
  always reported (deeper than d), with a depth between that and the clearing translation.

Each pair also interlocks: on a ray across it, one body must pass the other's far side to leave
it behind, which is what a whole-pair figure reports (0.28 m for the sleeve).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.focused.modes import hardclash
from pycinder.focused.measure.local_depth import shape_convex

m3d = pytest.importorskip("manifold3d")

D = 0.002
GRAZE, OVERLAP = 0.0005, 0.005
BALL = 0.0012
"""Radius of the ball checked inside both bodies of an overlapping pair (2 x 1.2 mm > d)."""


def _mesh(manifold) -> trimesh.Trimesh:
    mesh = manifold.to_mesh()
    return trimesh.Trimesh(np.asarray(mesh.vert_properties, np.float64)[:, :3],
                           np.asarray(mesh.tri_verts), process=False)


def _solid(mesh: trimesh.Trimesh, t: np.ndarray):
    v = np.asarray(mesh.vertices, np.float64) @ t[:3, :3].T + t[:3, 3]
    out = m3d.Mesh64(vert_properties=np.ascontiguousarray(v),
                     tri_verts=np.ascontiguousarray(mesh.faces, np.uint32))
    out.merge()
    return m3d.Manifold(out)


def move(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = (x, y, z)
    return t


@dataclass
class Case:
    """An interlocking pair: body b moved along ``way`` by about ``overlap`` shares no volume
    with body a (:func:`clearing` finds how far exactly); ``ball``: a point inside both where
    they overlap."""

    name: str
    meshes: list
    transforms: list
    way: np.ndarray
    overlap: float
    ball: np.ndarray | None = None

    def placed(self, rotation: np.ndarray, offset: np.ndarray) -> Case:
        m = np.eye(4)
        m[:3, :3] = rotation
        m[:3, 3] = offset
        ball = None if self.ball is None else rotation @ self.ball + offset
        return Case(self.name, self.meshes, [m @ t for t in self.transforms],
                    rotation @ self.way, self.overlap, ball)


def sleeve_case(overlap: float, angle: float) -> Case:
    """A pipe (radius 0.1) through a ring-shaped sleeve (hole 0.12, outside 0.14, 0.3 long),
    off the axis along ``angle`` so that it presses ``overlap`` into the sleeve's inside."""
    ring = m3d.Manifold.cylinder(0.3, 0.14, 0.14, 96, True) - m3d.Manifold.cylinder(
        0.6, 0.12, 0.12, 96, True)
    pipe = m3d.Manifold.cylinder(2.0, 0.1, 0.1, 96, True)
    out = np.array([np.cos(angle), np.sin(angle), 0.0])
    e = 0.02 + overlap
    return Case(f"pipe in a sleeve, {overlap * 1e3:g} mm at {angle:g} rad",
                [_mesh(ring), _mesh(pipe)], [move(), move(*(e * out))], -out, overlap,
                (0.12 + overlap / 2) * out)


def opening_case(overlap: float) -> Case:
    """A duct 0.2 x 0.2 along y through a wall (1 x 0.2 x 1) with an opening 0.3 x 0.3,
    pressed ``overlap`` into the opening's side at x = 0.15."""
    wall = m3d.Manifold.cube((1.0, 0.2, 1.0), True) - m3d.Manifold.cube((0.3, 0.4, 0.3), True)
    duct = m3d.Manifold.cube((0.2, 1.0, 0.2), True)
    x = 0.15 - 0.1 + overlap
    return Case(f"duct in a wall's opening, {overlap * 1e3:g} mm", [_mesh(wall), _mesh(duct)],
                [move(), move(x, 0, 0.02)], np.array([-1.0, 0, 0]), overlap,
                np.array([0.15 + overlap / 2, 0.0, 0.02]))


def slot_case(overlap: float) -> Case:
    """A beam 0.2 x 1 x 0.2 along y in a slot 0.3 high cut 0.25 deep into a column
    (0.4 x 0.4 x 2), pressed ``overlap`` into the slot's floor at z = -0.15."""
    column = m3d.Manifold.cube((0.4, 0.4, 2.0), True) - m3d.Manifold.cube(
        (0.5, 1.0, 0.3), True).translate((0.2, 0.0, 0.0))
    beam = m3d.Manifold.cube((0.2, 1.0, 0.2), True)
    z = -0.15 + 0.1 - overlap
    return Case(f"beam in a column's slot, {overlap * 1e3:g} mm", [_mesh(column), _mesh(beam)],
                [move(), move(0.1, 0, z)], np.array([0, 0, 1.0]), overlap,
                np.array([0.1, 0.0, -0.15 - overlap / 2]))


def rings_case(overlap: float) -> Case:
    """Two linked rings (radius 0.1, tube 0.02): the second in the xz plane, centred
    ``0.04 - overlap`` along x, so that its tube overlaps the first's by ``overlap`` on both
    sides (where the rings cross the x axis)."""
    ring = trimesh.creation.torus(0.1, 0.02, major_sections=96, minor_sections=32)
    standing = trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0))
    c = 0.04 - overlap
    return Case(f"linked rings, {overlap * 1e3:g} mm", [ring, ring],
                [move(), move(c) @ standing], np.array([1.0, 0, 0]), overlap,
                np.array([0.12 - overlap / 2, 0.0, 0.0]))


def cases(overlap: float) -> list[Case]:
    return [sleeve_case(overlap, 0.0), sleeve_case(overlap, 0.3), opening_case(overlap),
            slot_case(overlap), rings_case(overlap)]


def clearing(case: Case) -> float:
    """How far body b moves along ``way`` before no volume is shared (bisection on exact
    volumes; body a stays)."""
    a = _solid(case.meshes[0], case.transforms[0])
    b = _solid(case.meshes[1], case.transforms[1])
    scale = float(np.max(np.abs(np.asarray(a.bounding_box())))) + 1.0

    def shared(t: float) -> bool:
        return (a ^ b.translate(tuple(t * case.way))).volume() > 1e-15 * scale**3

    lo, hi = 0.0, 4 * case.overlap + 1e-3
    assert shared(lo) and not shared(hi), case.name
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if shared(mid) else (lo, mid)
    return hi


def ball_inside_both(case: Case) -> bool:
    ball = m3d.Manifold.sphere(BALL, 48).translate(tuple(case.ball))
    return all((ball - _solid(m, t)).volume() <= 1e-9 * ball.volume()
               for m, t in zip(case.meshes, case.transforms))


def assemble(chosen: list[Case], spacing: float = 3.0) -> tuple[list, list]:
    meshes, transforms = [], []
    for k, case in enumerate(chosen):
        for m, t in zip(case.meshes, case.transforms):
            meshes.append(m)
            transforms.append(move(k * spacing) @ t)
    return meshes, transforms


@pytest.mark.parametrize("overlap", [GRAZE, OVERLAP])
def test_cases_are_what_they_say(overlap):
    for case in cases(overlap):
        assert all(m.is_watertight and m.is_volume for m in case.meshes), case.name
        clear = clearing(case)
        assert overlap * 0.99 <= clear <= overlap * 1.05 + 1e-6, (case.name, clear)
        if overlap == OVERLAP:
            assert ball_inside_both(case), case.name


def check(result, chosen: list[Case], d: float, truth: list[Case] | None = None) -> None:
    """Grazes never reported; overlaps always, with a depth between the ball's bound and the
    clearing translation (over the lines' cosine), plus the rounding it states. ``truth``: the
    same pairs nearer the origin, for the exact volumes (translation changes no depth)."""
    found = {tuple(p): k for k, p in enumerate(result.pairs.tolist())}
    failures = []
    for k, case in enumerate(chosen):
        pair = (2 * k, 2 * k + 1)
        if case.overlap <= d / 2:
            if pair in found:
                failures.append(f"{case.name}: reported, depth {result.depths[found[pair]]:.6g}")
            continue
        if pair not in found:
            failures.append(f"{case.name}: not reported")
            continue
        got, error = result.depths[found[pair]], result.depth_errors[found[pair]]
        clear = clearing((truth or chosen)[k])
        if not 2 * BALL - error <= got <= clear / hardclash.DIRECTION_COS + error:
            failures.append(f"{case.name}: depth {got:.6g} outside [{2 * BALL:g}, "
                            f"{clear / hardclash.DIRECTION_COS:.6g}] (error {error:.3g})")
        if error > d / 32:  # the regions are small enough for that (tile_side)
            failures.append(f"{case.name}: depth error {error:.3g} is not the rounding")
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("overlap", [GRAZE, OVERLAP])
def test_interlocking_pairs_are_measured_where_they_overlap(overlap):
    chosen = cases(overlap)
    meshes, transforms = assemble(chosen)
    result = pycinder.Detector(min_depth=D).find_collisions(meshes, transforms)
    check(result, chosen, D)


def test_turned_and_in_map_coordinates():
    """The same pairs turned (and mirrored: a transform that mirrors a solid turns its faces
    inside out for the cuts) and moved 707 km from the origin: grazes and overlaps alike."""
    rng = np.random.default_rng(5)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    rotation = q * np.sign(np.linalg.det(q))
    mirror = rotation @ np.diag([1.0, 1.0, -1.0])
    pairs = cases(GRAZE)[:3] + cases(OVERLAP)[:3]
    turns = [rotation, mirror] * 3
    far = np.array([5e5, 5e5, 0.0])
    chosen = [c.placed(m, far + k * np.array([3.0, 0, 0]))
              for k, (c, m) in enumerate(zip(pairs, turns))]
    truth = [c.placed(m, np.zeros(3)) for c, m in zip(pairs, turns)]
    meshes, transforms = [], []
    for case in chosen:
        meshes += case.meshes
        transforms += case.transforms
    result = pycinder.Detector(min_depth=D).find_collisions(meshes, transforms)
    check(result, chosen, D, truth)


def test_the_sleeve_is_not_convex_and_the_pipe_is():
    case = sleeve_case(GRAZE, 0.0)
    detector = pycinder.Detector(min_depth=D)
    result = detector.find_collisions(case.meshes, case.transforms)
    shapes = result.scene.shapes
    assert [shape_convex(s) for s in shapes] == [False, True]


def test_a_body_inside_a_nonconvex_one_is_deep():
    """A 1 mm cube inside the sleeve's wall: any translation that takes it out is at least
    its distance to the wall's faces plus its size (over d); reported, never dropped by
    local depth."""
    case = sleeve_case(GRAZE, 0.0)
    small = trimesh.creation.box((0.001, 0.001, 0.001))
    result = pycinder.Detector(min_depth=D).find_collisions(
        [case.meshes[0], small], [move(), move(0.13, 0, 0)])
    assert result.pairs.tolist() == [[0, 1]]
    assert result.depths[0] >= 0.001 + 0.001 - result.depth_errors[0]


def test_convex_pairs_get_depth_bounds_near_rounding():
    """Boxes meeting face to face, turned any way: the best direction is one of a body's
    axes, so the hull of the measured points bounds the depth within rounding (the cosine of
    the 26 directions alone would allow 11 % of it)."""
    pytest.importorskip("scipy")
    rng = np.random.default_rng(2)
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    slab = trimesh.creation.box((3.0, 3.0, 1.0))
    meshes, transforms, depths = [], [], []
    for k, depth in enumerate([0.01, 0.05, 0.2, 0.3]):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        q *= np.sign(np.linalg.det(q))
        turn = np.eye(4)
        turn[:3, :3] = q
        base = move(5.0 * k) @ turn
        meshes += [slab, box]
        transforms += [base, base @ move(0.3, -0.2, 1.0 - depth)]
        depths.append(depth)
    result = pycinder.Detector(min_depth=0.005).find_collisions(meshes, transforms)
    assert result.pairs.tolist() == [[2 * k, 2 * k + 1] for k in range(4)]
    for k, depth in enumerate(depths):
        got, error = result.depths[k], result.depth_errors[k]
        assert got - error <= depth + 1e-9 <= got + 1e-5, (depth, got, error)
        rounding = hardclash.ERROR_SCALE * np.sqrt(3**2 + 3**2 + 2**2)  # the pair's reach
        assert error <= 1e-3 * depth + 3 * rounding, (depth, got, error)


def test_a_solid_flattened_as_placed_is_named(monkeypatch):
    """A body that is a solid in its own space but not where it is placed cannot be cut: the
    pair is refused by name, never measured as if it did not overlap."""
    from pycinder.focused.measure import regions

    case = sleeve_case(OVERLAP, 0.0)
    real = regions.body_vertices

    def flattened(scene, body, origin):
        vertices, faces = real(scene, body, origin)
        if body == 1:  # the pipe, as placed: every vertex in one plane
            vertices = vertices.copy()
            vertices[:, 2] = 0.0
        return vertices, faces

    monkeypatch.setattr(regions, "body_vertices", flattened)
    with pytest.raises(ValueError, match="not as placed"):
        pycinder.Detector(min_depth=D).find_collisions(case.meshes, case.transforms)


def test_a_sleeve_wound_inside_out_is_measured_whole():
    """A closed non-convex body wound inside out (warned about, and tested as a solid all the
    same) cannot be cut as a solid: its pair keeps the whole pair's figure, so a 5 mm overlap is
    still reported, and a graze is reported too (the whole figure is the sleeve's width)."""
    import warnings

    for overlap in (OVERLAP, GRAZE):
        case = sleeve_case(overlap, 0.3)
        sleeve = case.meshes[0].copy()
        sleeve.invert()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = pycinder.Detector(min_depth=D).find_collisions(
                [sleeve, case.meshes[1]], case.transforms)
        assert result.pairs.tolist() == [[0, 1]], overlap
        assert result.depths[0] >= clearing(case) - result.depth_errors[0]


@pytest.mark.parametrize("overlap", [GRAZE, OVERLAP])
def test_dense_pairs_go_straight_to_their_local_depth(overlap, monkeypatch):
    """A pair measured locally whose bodies make more than ``LOCAL_FIRST_WORK`` face pairs skips
    the whole-pair pass: with the threshold at 0, every interlocking pair does, and grazes and
    overlaps keep the contract against exact geometry, turned and 707 km out as well; a convex
    pair above the threshold keeps the whole-pair pass."""
    calls = []
    real = hardclash.local_first

    def spy(scene, pack, pairs, kinds=None):
        out = real(scene, pack, pairs, kinds)
        calls.append({tuple(p) for p in np.asarray(pairs)[out].tolist()})
        return out

    monkeypatch.setattr(hardclash, "LOCAL_FIRST_WORK", 0)
    monkeypatch.setattr(hardclash, "local_first", spy)
    rng = np.random.default_rng(9)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    turn = q * np.sign(np.linalg.det(q))
    chosen = cases(overlap)
    far = [c.placed(turn, np.array([5e5, 5e5, 0.0]) + k * np.array([3.0, 0, 0]))
           for k, c in enumerate(chosen)]
    for placed, truth in ((chosen, None), (far, [c.placed(turn, np.zeros(3)) for c in chosen])):
        calls.clear()
        meshes, transforms = [], []
        for case in placed:
            meshes += case.meshes
            transforms += case.transforms
        result = pycinder.Detector(min_depth=D).find_collisions(meshes, transforms)
        assert len(calls) == 1, calls
        assert {(2 * k, 2 * k + 1) for k in range(len(placed))} <= calls[0]  # went straight
        check(result, placed, D, truth)
    ball = trimesh.creation.icosphere(subdivisions=2)
    calls.clear()
    pycinder.Detector(min_depth=D).find_collisions([ball, ball], [move(), move(0.5)])
    assert calls == [set()]  # convex: the whole-pair figure is its depth


def _steps() -> trimesh.Trimesh:
    """Two 1 m boxes meeting along an edge, one vertex list: a balanced mesh with four faces on
    that edge (a stair's steps modelled as boxes), which manifold3d does not take whole."""
    low = trimesh.creation.box((1.0, 1.0, 1.0))
    high = trimesh.creation.box((1.0, 1.0, 1.0))
    high.apply_translation((1.0, 0.0, 1.0))
    steps = trimesh.util.concatenate([low, high])
    steps.merge_vertices()
    return steps


@pytest.mark.filterwarnings("ignore::pycinder.OpenMeshWarning")
def test_a_solid_of_parts_sharing_an_edge_is_cut_as_their_union():
    """Boxes meeting along an edge are a solid cut as the union of their parts: two pieces, a
    block resting on the low step and against the high one is a touching pair (no volume, not
    reported, as exact geometry says), and pressed 5 mm down into the low step it is reported
    with its local depth."""
    from pycinder.focused.measure.local_depth import solid_facts
    from pycinder.focused.measure.regions import manifold_pieces

    steps = _steps()
    assert not steps.is_watertight  # four faces on the shared edge
    assert sorted(len(p) for p in manifold_pieces(steps.faces)) == [12, 12]
    block = trimesh.creation.box((0.4, 0.6, 0.3))
    resting = np.eye(4)
    resting[:3, 3] = (0.3, 0.0, 0.65)  # on the low step's top (z 0.5), against x 0.5
    pressed = resting.copy()
    pressed[2, 3] -= OVERLAP
    det = pycinder.Detector(min_depth=D)
    result = det.find_collisions([steps, block], [np.eye(4), resting])
    shape = result.scene.shape_of(0)
    assert solid_facts(shape).solid and not solid_facts(shape).convex
    assert result.pairs.shape == (0, 2)
    result = det.find_collisions([steps, block], [np.eye(4), pressed])
    assert result.pairs.tolist() == [[0, 1]]
    assert abs(result.depths[0] - OVERLAP) <= result.depth_errors[0] + 1e-6

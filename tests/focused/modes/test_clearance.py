"""Clearance queries (``clearance=c``) against exact geometry: a pair closer than c is always
reported, overlapping pairs included; a pair more than c + c/8 apart never is; every reported
pair's distance is within its stated bound of the exact one (python-fcl's distance, or the
analytic one), at several scales, for convex, non-convex, nested, touching and open bodies."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing import holed_plate, l_shape, open_cup, random_rotation, surface_distance

fcl = pytest.importorskip("fcl", reason="exact distances come from python-fcl (the test extra)")

BOX = trimesh.creation.box((1.0, 1.0, 1.0))


def move(x=0.0, y=0.0, z=0.0, rotation=None):
    m = np.eye(4) if rotation is None else rotation.copy()
    m[:3, 3] = (x, y, z)
    return m


def _check(result, meshes, transforms, c, exact):
    """The contract for one query: pairs by exact distance, figures within their bounds."""
    reported = {tuple(p) for p in result.pairs.tolist()}
    figures = dict(zip(map(tuple, result.pairs.tolist()), zip(result.distances,
                                                              result.distance_errors)))
    for (i, j), d in exact.items():
        if d < c:
            assert (i, j) in reported, f"pair {i, j} {d:.6g} apart (< {c:g}) was not reported"
        if d > c * 9 / 8:
            assert (i, j) not in reported, f"pair {i, j} {d:.6g} apart (> 9/8 {c:g}) reported"
        if (i, j) in figures:
            got, bound = figures[(i, j)]
            assert abs(got - d) <= bound + 1e-12, \
                f"pair {i, j}: distance {got:.9g}, exact {d:.9g}, bound {bound:.3g}"


def _exact(meshes, transforms, pairs=None):
    n = len(meshes)
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)] if pairs is None else pairs
    return {(i, j): surface_distance(meshes[i], meshes[j], [transforms[i], transforms[j]])
            for i, j in pairs}


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_boxes_at_the_margins_at_three_scales(scale):
    """Two unit boxes (scaled) side by side at gaps around c: analytic distances."""
    c = 0.1 * scale
    box = BOX.copy()
    box.apply_scale(scale)
    det = pycinder.Detector(clearance=c)
    for gap in (-0.3, 0.0, 0.25, 0.5, 0.9, 0.99, 1.13, 1.3, 3.0):
        transforms = [move(), move((1.0 + gap * 0.1) * scale)]
        result = det.find_collisions([box, box], transforms)
        exact = {(0, 1): max(gap, 0.0) * c}
        _check(result, [box, box], transforms, c, exact)
        if gap < 1.0:
            assert result.pairs.tolist() == [[0, 1]]
            assert result.distances[0] == pytest.approx(max(gap, 0.0) * c,
                                                        abs=result.distance_errors[0] + 1e-15)


def test_touching_face_on_face_edge_on_face_and_end_to_end_are_reported_at_zero():
    c = 0.05
    beam = trimesh.creation.box((2.0, 0.2, 0.2))
    turned = random_rotation(np.random.default_rng(3))
    cases = {
        "face on face": ([BOX, BOX], [move(), move(1.0)]),
        "end to end": ([beam, beam], [move(), move(2.0)]),
        "edge on face": ([BOX, BOX], [move(), move(0.5 + np.sqrt(0.5), 0, 0,
                                                   trimesh.transformations.rotation_matrix(
                                                       np.pi / 4, (0, 0, 1)))]),
        "corner region": ([BOX, BOX], [move(), move(1.0, 1.0, 1.0)]),
        "turned, apart": ([BOX, BOX], [move(), move(3.0, 0, 0, turned)]),
    }
    det = pycinder.Detector(clearance=c)
    for name, (meshes, transforms) in cases.items():
        result = det.find_collisions(meshes, transforms)
        exact = _exact(meshes, transforms)
        _check(result, meshes, transforms, c, exact)
        if exact[(0, 1)] == 0.0:
            assert result.pairs.tolist() == [[0, 1]], name
            assert result.distances[0] <= result.distance_errors[0], name


def _at_gap(meshes, a, b, gap):
    """``b`` moved along x so that the exact distance to ``a`` is ``gap`` (bisection)."""
    lo, hi = -3.0, 3.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        moved = b.copy()
        moved[0, 3] += mid
        if surface_distance(meshes[0], meshes[1], [a, moved]) > gap:
            hi = mid
        else:
            lo = mid
    moved = b.copy()
    moved[0, 3] += hi
    return moved


def test_random_convex_pairs_against_fcl():
    """Random convex hulls placed at gaps from inside the clearance to past its band."""
    rng = np.random.default_rng(11)
    c = 0.08
    det = pycinder.Detector(clearance=c)
    gaps = [0.0, 0.2 * c, 0.6 * c, 0.95 * c, 1.05 * c, 1.2 * c, 2 * c] * 2
    for gap in gaps:
        meshes = [trimesh.convex.convex_hull(rng.normal(size=(40, 3)) * rng.uniform(0.3, 0.6))
                  for _ in range(2)]
        a = move(rotation=random_rotation(rng))
        b = _at_gap(meshes, a, move(rotation=random_rotation(rng)), gap)
        transforms = [a, b]
        exact = _exact(meshes, transforms)
        assert abs(exact[(0, 1)] - gap) < 1e-6
        result = det.find_collisions(meshes, transforms)
        _check(result, meshes, transforms, c, exact)


def test_non_convex_and_nested_bodies_against_fcl():
    """L-shapes reaching around each other, a holed plate, a box inside a box (overlapping,
    surfaces apart: distance 0) and a box inside a box near its wall."""
    c = 0.06
    small = trimesh.creation.box((0.2, 0.2, 0.2))
    meshes = [l_shape(), l_shape(), holed_plate(), small, BOX, small]
    transforms = [move(), move(0.35, 0.33, 0.0, trimesh.transformations.rotation_matrix(
        np.pi, (0, 0, 1))), move(0, 0, 0.55), move(5.0), move(5.0), move(8.0)]
    det = pycinder.Detector(clearance=c)
    result = det.find_collisions(meshes, transforms)
    exact = _exact(meshes, transforms)
    exact[(3, 4)] = 0.0  # nested: the small box is inside the closed big one
    _check(result, meshes, transforms, c, exact)
    assert (3, 4) in {tuple(p) for p in result.pairs.tolist()}
    k = result.pairs.tolist().index([3, 4])
    assert result.distances[k] == 0.0


@pytest.mark.filterwarnings("ignore::pycinder.OpenMeshWarning")
def test_open_body_is_a_surface():
    """A ball in a cup, clear of its walls, is as far as its surface is from the cup's."""
    cup = open_cup(1.0)
    ball = trimesh.creation.icosphere(2, radius=0.2)
    det = pycinder.Detector(clearance=0.05)
    lo, hi = cup.bounds
    centre = 0.5 * (lo + hi)
    bottom = lo[2] + 0.2
    for z in (centre[2], bottom + 0.03, bottom + 0.08, bottom - 0.1):
        transforms = [move(), move(centre[0], centre[1], z)]
        result = det.find_collisions([cup, ball], transforms)
        _check(result, [cup, ball], transforms, 0.05, _exact([cup, ball], transforms))


def test_dense_scene_against_fcl():
    rng = np.random.default_rng(5)
    meshes, transforms = [], []
    for k in range(14):
        meshes.append(trimesh.creation.icosphere(1, radius=rng.uniform(0.15, 0.3)))
        transforms.append(move(*rng.uniform(0, 1.6, 3)))
    c = 0.1
    result = pycinder.Detector(clearance=c).find_collisions(meshes, transforms)
    _check(result, meshes, transforms, c, _exact(meshes, transforms))


def test_batches_and_prepared_bodies_carry_distances():
    det = pycinder.Detector(clearance=0.1)
    scenes = [([BOX, BOX], [move(), move(1.05)]), ([BOX, BOX], [move(), move(1.5)])]
    near, far = det.find_collisions_batch(scenes)
    assert near.pairs.tolist() == [[0, 1]] and far.pairs.tolist() == []
    assert near.distances[0] == pytest.approx(0.05, abs=near.distance_errors[0])
    assert len(far.distances) == 0
    prepared = det.prepare([BOX, BOX])
    result = det.find_collisions(prepared, [move(), move(1.02)])
    assert result.distances[0] == pytest.approx(0.02, abs=result.distance_errors[0])
    plain = pycinder.Detector().find_collisions([BOX, BOX], [move(), move(1.02)])
    assert plain.distances is None


def test_options_are_checked_once():
    for bad in (0, -1.0, float("nan"), True, "1"):
        with pytest.raises(ValueError, match="clearance must be a positive number"):
            pycinder.Detector(clearance=bad)
    with pytest.raises(ValueError, match="strategy='focused'"):
        pycinder.Detector(clearance=0.1, strategy="scene")
    with pytest.raises(ValueError, match="contacts=True and clearance"):
        pycinder.Detector(clearance=0.1, contacts=True)


def test_a_clearance_too_small_for_single_precision_is_refused():
    big = trimesh.creation.box((1e4, 1e4, 1e4))
    with pytest.raises(ValueError, match="clearance 0.001 is too small"):
        pycinder.Detector(clearance=1e-3).find_collisions([big, big], [move(), move(1e4 + 5e-4)])


def test_result_with_distances_pickles():
    import pickle

    result = pycinder.Detector(clearance=0.1).find_collisions([BOX, BOX], [move(), move(1.05)])
    copy = pickle.loads(pickle.dumps(result))
    assert copy.distances.tolist() == result.distances.tolist()
    assert copy.distance_errors.tolist() == result.distance_errors.tolist()


def test_cli_check_with_clearance(tmp_path, capsys):
    import json

    from pycinder.cli import main

    for name, x in (("a.stl", 0.0), ("b.stl", 1.05), ("c.stl", 3.0)):
        BOX.copy().apply_translation((x, 0, 0)).export(tmp_path / name)
    code = main(["check", "--json", "--clearance", "0.1",
                 *(str(tmp_path / n) for n in ("a.stl", "b.stl", "c.stl"))])
    report = json.loads(capsys.readouterr().out)
    assert code == 1 and report["mode"] == "clearance"
    (pair,) = report["pairs"]
    assert (pair["a"], pair["b"]) == ("a.stl", "b.stl")
    assert abs(pair["distance"] - 0.05) <= pair["distance_error"]


def test_a_deforming_body_is_measured_as_it_is_now():
    """The same detector, a box whose vertices change every query (same faces): each query
    measures the box as it is then, not as the first query saw it."""
    det = pycinder.Detector(clearance=0.1)
    v, f = np.asarray(BOX.vertices), np.asarray(BOX.faces)
    for width, gap in ((0.3, 0.15), (0.5, 0.05), (0.56, 0.02), (0.44, 0.08), (0.2, 0.2)):
        stretched = v * [width, 1.0, 1.0]
        # Box b spans width along x about its centre: its near face is gap from box a.
        transforms = [move(), move(0.5 + gap + width / 2)]
        result = det.find_collisions([BOX, (stretched.copy(), f)], transforms)
        if gap < 0.1:
            assert result.pairs.tolist() == [[0, 1]], (width, gap)
            assert abs(result.distances[0] - gap) <= result.distance_errors[0], (width, gap)
        else:
            assert result.pairs.tolist() == [], (width, gap)


def test_contacts_of_a_clearance_result_say_where_its_figures_are():
    result = pycinder.Detector(clearance=0.1).find_collisions([BOX, BOX], [move(), move(0.9)])
    with pytest.raises(ValueError, match=r"result\.distances"):
        result.contacts()

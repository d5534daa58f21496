"""What a result tells a user: a short repr, contacts when the query asked for them (and a
ValueError naming ``contacts=True`` when it did not), the names it was given, records named for
what they hold, normals filled when asked for, stats per strategy; and a result is plain data,
with no GPU object in it."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.contacts import reduce_contacts


def box_and_ball():
    """A unit box at the origin and a ball of radius 0.4 centred at x = 0.6: they overlap in
    x from 0.2 to 0.5, so the exact penetration is 0.3 along +x (from box into ball)."""
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.4)
    ball.apply_translation((0.6, 0, 0))
    return box, ball


def test_repr_is_short_and_names_the_pairs(detector):
    box, ball = box_and_ball()
    far = trimesh.creation.icosphere(radius=0.2)
    far.apply_translation((5, 0, 0))
    result = detector.find_collisions([box, ball, far], names=["box", "ball", "far"],
                                      records="all")
    assert len(result.records) > 100
    text = repr(result)
    assert len(text) < 300 and "\n" not in text, text
    assert "1 pair: (box, ball)" in text and f"{len(result.records):,} records" in text
    assert "tolerance" in text and result.stats.adapter in text
    assert "point" not in text  # no record array
    stats = repr(result.stats)
    assert stats.count("\n") < 8 and "tiles=" in stats and "resolution" not in stats


def test_records_are_decoded_when_first_read(detector, monkeypatch):
    """A query returns before its records are decoded; reading them decodes them once, and
    they hold the geometry: every record's point lies inside the body it penetrates (within a
    tolerance), on the penetrating body's surface."""
    import threading

    from pycinder.focused import focused_strategy

    calls = []
    decode = focused_strategy.decode_records
    monkeypatch.setattr(focused_strategy, "decode_records",
                        lambda *a: calls.append(1) or decode(*a))
    box, ball = box_and_ball()
    result = detector.find_collisions([box, ball], records="all")
    count = result.stats.records
    assert count > 100 and result.pairs.tolist() == [[0, 1]]
    assert f"{count:,} records" in repr(result) and not calls  # not decoded by the query
    readers = [threading.Thread(target=lambda: result.records) for _ in range(4)]
    for t in readers:
        t.start()
    for t in readers:
        t.join()
    rec = result.records
    assert 1 <= len(calls) <= 4 and len(rec) == count
    assert result.records is rec  # kept
    tol = result.stats.tolerance[1]
    meshes = (box, ball)
    for body in (0, 1):
        mine = rec[rec["penetrating"] == body]
        assert len(mine) and (mine["penetrated"] == 1 - body).all()
        inside = trimesh.proximity.signed_distance(meshes[1 - body], mine["point"])
        on = trimesh.proximity.signed_distance(meshes[body], mine["point"])
        assert (inside > -tol).all() and (np.abs(on) < tol).all()


@pytest.mark.parametrize("tol", [0.005, 0.001])
def test_contacts_asked_with_the_query_measure_the_exact_overlap(tol):
    """One contact region, whatever the tolerance (at 0.001 the ball's cap is sampled at a
    grazing angle near its pole, and those thin samples stay in the one region)."""
    box, ball = box_and_ball()
    det = pycinder.Detector(tolerance=tol)
    result = det.find_collisions([box, ball], names=["box", "ball"], contacts=True)
    assert result.records_kept == "all"
    contacts = result.contacts()
    assert len(contacts) == 1
    (c,) = list(contacts)
    assert c.pair == ("box", "ball") and c.names == {"box", "ball"}
    # normal from the box into the ball: +x; depth: 0.3 (exact, from the geometry above)
    assert np.degrees(np.arccos(np.clip(c.normal @ [1, 0, 0], -1, 1))) < 10
    assert abs(c.depth - 0.3) < 0.03 + tol
    # the point lies in both bodies (within a tolerance)
    for mesh in (box, ball):
        assert trimesh.proximity.signed_distance(mesh, [c.point])[0] > -tol
    # contacts=True is records="all": the same contacts as reducing such a query directly;
    # computed once
    everything = det.find_collisions([box, ball], records="all")
    direct = reduce_contacts(everything.records, everything.scene, everything.tiles)
    assert np.allclose(direct.normal, contacts.normal) and np.allclose(direct.depth, contacts.depth)
    assert result.contacts() is contacts


def test_contacts_of_a_probe(detector):
    box, ball = box_and_ball()
    far = trimesh.creation.icosphere(radius=0.2)
    far.apply_translation((0.6, 0.0, 0.0))  # inside the ball, touching nothing else
    result = detector.find_collisions([box, ball, far], groups=[0, 1, 0], contacts=True)
    assert result.pairs.tolist() == [[0, 1], [1, 2]]
    contacts = result.contacts()
    assert sorted({tuple(p) for p in contacts.pair.tolist()}) == [(0, 1), (1, 2)]
    # unnamed bodies are named by their indices
    assert {c.pair for c in contacts} == {(0, 1), (1, 2)}


@pytest.mark.parametrize("records", ["found", "none"])
def test_contacts_not_asked_for_say_how_to_ask(detector, records, monkeypatch):
    """A result that kept fewer than every record runs nothing again: contacts() raises, naming
    contacts=True, whether or not it has pairs, here and once pickled."""
    import pickle

    from pycinder import detector as detector_module

    box, ball = box_and_ball()
    result = detector.find_collisions([box, ball], records=records)
    assert result.records_kept == records and result.pairs.tolist() == [[0, 1]]
    copy = pickle.loads(pickle.dumps(result))
    monkeypatch.setattr(detector_module.Detector, "_submit",
                        lambda *a, **k: pytest.fail("contacts() ran a query"))
    for r in (result, copy):
        with pytest.raises(ValueError, match=rf"kept records='{records}'.*contacts=True"):
            r.contacts()
    ball.apply_translation((2, 0, 0))
    monkeypatch.undo()
    apart = detector.find_collisions([box, ball], records=records)
    with pytest.raises(ValueError, match="contacts=True"):
        apart.contacts()


def test_contacts_option_is_checked_once_with_the_others(detector):
    box, ball = box_and_ball()
    for bad in ("found", "none"):
        with pytest.raises(ValueError, match=rf"contacts=True.*records='{bad}'"):
            pycinder.CollisionRequest(contacts=True, records=bad)
        with pytest.raises(ValueError, match=rf"contacts=True.*records='{bad}'"):
            detector.find_collisions([box, ball], contacts=True, records=bad)
        with pytest.raises(ValueError, match=rf"contacts=True.*records='{bad}'"):
            detector.find_collisions_batch([([box, ball], None)], contacts=True, records=bad)
    with pytest.raises(ValueError, match="contacts must be True or False"):
        pycinder.CollisionRequest(contacts=1)
    with pytest.raises(ValueError, match="contacts must be True or False"):
        detector.find_collisions([box, ball], contacts="yes")
    with pytest.raises(ValueError, match="focused strategy"):
        pycinder.CollisionRequest(strategy="scene", contacts=True)
    with pytest.raises(ValueError, match="focused strategy"):
        pycinder.Detector(strategy="scene", resolution=64).find_collisions([box, ball],
                                                                           contacts=True)
    # records follow contacts; contacts=True with records="all" is the same request
    assert pycinder.CollisionRequest(contacts=True).records == "all"
    assert pycinder.CollisionRequest(contacts=True) == pycinder.CollisionRequest(
        contacts=True, records="all")
    assert pycinder.CollisionRequest().replace(contacts=True).records == "all"
    assert pycinder.CollisionRequest(contacts=True).replace(contacts=False).records == "found"
    # per call: True asks for every record, False for none beyond the request's default
    det = pycinder.Detector(contacts=True)
    assert det.find_collisions([box, ball]).records_kept == "all"
    assert det.find_collisions([box, ball], contacts=False).records_kept == "found"
    assert det.find_collisions([box, ball], records="none").records_kept == "none"


def test_batch_results_give_their_contacts(detector):
    """Each scene's result of a batch asked for contacts gives that scene's, equal to a query
    of the scene alone asked for them."""
    box, ball = box_and_ball()
    near = trimesh.creation.icosphere(subdivisions=3, radius=0.4).apply_translation((0, 0.65, 0))
    scenes = [([box, ball], None, ["box", "ball"]), ([near, box], None)]
    batch = detector.find_collisions_batch(scenes, tolerance=0.005, contacts=True)
    single = pycinder.Detector(tolerance=0.005, contacts=True)
    for part, scene in zip(batch, scenes):
        alone = single.find_collisions(scene[0], names=scene[2] if len(scene) == 3 else None)
        assert part.records_kept == "all"
        np.testing.assert_array_equal(part.pairs, alone.pairs)
        mine, theirs = part.contacts(), alone.contacts()
        assert len(mine) == len(theirs) == 1 and mine.names == theirs.names
        np.testing.assert_array_equal(mine.pair, theirs.pair)
        assert np.allclose(mine.normal, theirs.normal, atol=1e-3)
        assert np.allclose(mine.depth, theirs.depth, atol=0.01)
    assert {c.pair for c in batch[0].contacts()} == {("box", "ball")}


def _gpu_objects(root: object) -> list[str]:
    """Paths to every wgpu object, Detector, strategy or function reachable from ``root``
    through attributes, containers, partials' arguments and arrays' bases."""
    import functools

    import wgpu

    from pycinder.detector import Detector

    found, seen = [], set()
    stack = [(root, "result")]
    while stack:
        obj, path = stack.pop()
        if id(obj) in seen or obj is None or isinstance(obj, (str, bytes, int, float, bool)):
            continue
        seen.add(id(obj))
        module = type(obj).__module__ or ""
        if module.startswith(("wgpu", "_cffi")) or isinstance(obj, Detector) \
                or type(obj).__name__ in ("FocusedStrategy", "SceneStrategy", "WholeSceneStrategy",
                                          "Gpu", "FocusedFrames") \
                or isinstance(obj, (wgpu.GPUObjectBase, wgpu.GPUDevice)):
            found.append(f"{path}: {type(obj).__name__}")
            continue
        if isinstance(obj, np.ndarray):
            if obj.base is not None:
                stack.append((obj.base, path + ".base"))
            if obj.dtype == object:
                stack += [(v, f"{path}[{k}]") for k, v in enumerate(obj.ravel().tolist())]
            continue
        if isinstance(obj, memoryview):
            stack.append((obj.obj, path + ".obj"))
            continue
        if isinstance(obj, functools.partial):
            stack += [(obj.func, path + ".func")] + [(a, f"{path}.args[{k}]")
                                                     for k, a in enumerate(obj.args)]
            continue
        if isinstance(obj, dict):
            stack += [(v, f"{path}[{k!r}]") for k, v in obj.items()]
            continue
        if isinstance(obj, (list, tuple, set, frozenset)):
            stack += [(v, f"{path}[{k}]") for k, v in enumerate(obj)]
            continue
        if callable(obj) and not hasattr(obj, "__dict__"):
            continue  # a builtin function
        if hasattr(obj, "__dict__"):
            stack += [(v, f"{path}.{k}") for k, v in vars(obj).items()]
        for slot in getattr(type(obj), "__slots__", ()):
            if hasattr(obj, slot):
                stack.append((getattr(obj, slot), f"{path}.{slot}"))
    return found


@pytest.mark.parametrize("options", [{"contacts": True}, {}, {"records": "none"},
                                     {"strategy": "scene", "resolution": 128}])
def test_a_result_holds_no_gpu_object(options):
    """Walking a result's attributes (before and after its records and contacts are read) finds
    no wgpu object, detector, strategy or GPU: it is plain data."""
    box, ball = box_and_ball()
    det = pycinder.Detector(**options)
    result = det.find_collisions([box, ball], names=["box", "ball"])
    assert result.pairs.tolist() == [[0, 1]]
    assert _gpu_objects(result) == []
    result.records
    if options.get("contacts"):
        result.contacts()
    assert _gpu_objects(result) == []
    assert _gpu_objects(det)  # the walk does find them where they are
    batch = pycinder.Detector(contacts=True).find_collisions_batch([([box, ball], None)])
    assert _gpu_objects(batch) == []


def test_no_contacts_without_pairs_and_none_from_the_scene_strategy():
    box, ball = box_and_ball()
    ball.apply_translation((2, 0, 0))
    assert len(pycinder.find_collisions([box, ball], contacts=True).contacts()) == 0
    ball.apply_translation((-2, 0, 0))
    scene = pycinder.find_collisions([box, ball], strategy="scene", resolution=256)
    assert scene.records_kept is None
    with pytest.raises(ValueError, match="focused strategy"):
        scene.contacts()


def test_pair_names_remember_the_names(detector):
    box, ball = box_and_ball()
    result = detector.find_collisions([box, ball], names=["zeta", "alpha"])
    assert result.pair_names() == {("alpha", "zeta")}
    assert result.pair_names(["b", "a"]) == {("a", "b")}  # still accepted
    assert detector.find_collisions([box, ball]).pair_names() == {(0, 1)}


def test_stats_are_split_by_strategy(detector):
    box, ball = box_and_ball()
    focused = detector.find_collisions([box, ball]).stats
    assert isinstance(focused.detail, pycinder.FocusedStats)
    assert focused.tiles > 0 and focused.candidates == 1 and focused.records > 0
    with pytest.raises(AttributeError, match="scene strategy"):
        focused.resolution
    scene = pycinder.find_collisions([box, ball], strategy="scene", resolution=128).stats
    assert isinstance(scene.detail, pycinder.SceneStats) and scene.resolution == (128, 128)
    with pytest.raises(AttributeError, match="focused strategy"):
        scene.tiles
    assert "tiles" not in repr(scene) and "resolution=(128, 128)" in repr(scene)


@pytest.mark.parametrize("options", [{"tolerance": 0.01}, {"strategy": "scene",
                                                            "resolution": 256}])
def test_records_carry_pixels_and_normals_when_asked(options):
    box, ball = box_and_ball()
    centres = np.array([[0, 0, 0], [0.6, 0, 0]])
    plain = pycinder.Detector(**options).find_collisions([box, ball])
    assert {"pixel_x", "pixel_y", "pixel_z"} <= set(plain.records.dtype.names)
    assert "depth" not in plain.records.dtype.names and "x" not in plain.records.dtype.names
    assert np.isnan(plain.records["normal"]).all()
    result = pycinder.Detector(encode="normal", **options).find_collisions([box, ball])
    rec = result.records
    assert len(rec) >= 16  # records="found" keeps 16 per pair
    normal = rec["normal"].astype(float)
    # Filled on every record, unit length, pointing out of the (convex) penetrating body.
    assert np.isfinite(normal).all()
    assert np.allclose(np.linalg.norm(normal, axis=1), 1, atol=2e-3)
    outward = rec["point"] - centres[rec["penetrating"]]
    assert (np.einsum("ij,ij->i", normal, outward) > 0).all()


@pytest.mark.parametrize("fresh_arrays", [False, True])
def test_a_warning_comes_once_per_cause_not_per_frame(fresh_arrays):
    """An open body in a loop of 5 frames, passed as the same mesh or as fresh arrays every
    frame: one warning for it, not one per frame."""
    import warnings

    box = trimesh.creation.box((1, 1, 1))
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-2], process=False)
    ball = trimesh.creation.icosphere(radius=0.3)
    det = pycinder.Detector()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(5):
            body = (np.array(open_box.vertices), np.array(open_box.faces)) if fresh_arrays \
                else open_box
            det.find_collisions([body, ball])
    about = [w for w in caught if issubclass(w.category, pycinder.OpenMeshWarning)]
    assert len(about) == 1, [str(w.message) for w in about]


def test_unique_pairs_sorts_and_dedups_whatever_the_order():
    """Pairs come back unique, ``i < j`` and sorted, whether given sorted and unique already
    (the candidate pairs, kept as they are), shuffled, repeated or reversed."""
    from pycinder.records import unique_pairs

    rng = np.random.default_rng(5)
    a, b = rng.integers(0, 50, 400), rng.integers(0, 50, 400)
    keep = a != b
    a, b = a[keep], b[keep]
    truth = sorted({(min(i, j), max(i, j)) for i, j in zip(a.tolist(), b.tolist())})
    assert unique_pairs(a, b).tolist() == [list(p) for p in truth]
    first, second = np.array(truth).T
    assert unique_pairs(first, second).tolist() == [list(p) for p in truth]
    assert unique_pairs(second, first).tolist() == [list(p) for p in truth]
    assert unique_pairs(first[:1], second[:1]).tolist() == [list(truth[0])]
    assert unique_pairs(np.r_[first, first[:3]], np.r_[second, second[:3]]).tolist() == \
        [list(p) for p in truth]
    assert unique_pairs(np.zeros(0, int), np.zeros(0, int)).shape == (0, 2)

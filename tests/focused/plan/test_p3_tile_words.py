"""Pass P3 of the GPU tile planner (:mod:`pycinder.focused.plan.p3_tile_words`): the tiles as the
frame's passes read them, written on the GPU after passes P1 and P2 in the same submission, against
the host's float64 composition of the same plan (``tile_words(plan, plan.tile_from_body(...))``,
with ``plan`` the :class:`~pycinder.focused.plan.plan_numpy.TilePlan` that
:class:`~pycinder.focused.plan.plan_gpu.GpuPlanner` builds from the same windows and atlas), never
against the GPU's own output.

Integer fields and the slab must be equal; the matrices equal up to single precision's rounding
relative to each tile's own size: the rotation rows relative to their size (``|R| / pixel``), the
last column (pixel coordinates) within 1e-3 pixel, and the error at the tile's window's corners
(body points mapped there) within 1e-3 pixel. Far from the world's origin (1e13) the reference is
also composed relative to the pair's anchor in float64, since the absolute float64 composition
itself rounds at ``2**-53`` of that distance.

Measured on lavapipe (these scenes): rotation rows within 2.2e-7 of their size; the last column
and the error at the windows' corners within 2e-5 pixel for windows of about a hundred pixels,
1.8e-4 pixel for windows of thousands, against the composition relative to the pair's anchor;
against the absolute one at 1e13, its own rounding (up to 2e-2 pixel for pixels of 0.1).
"""

import time

import numpy as np
import pytest

from pycinder.gpu.device import get_gpu
from pycinder.focused.plan.plan_gpu import GpuPlanner
from pycinder.gpu.layout import TILE
from pycinder.focused.plan.p2_atlas import atlas_windows
from pycinder.focused.frame.frameio import tile_words
from pycinder.testing import random_boxes
from pycinder.focused.plan.plan_numpy import PROBE_FACES


@pytest.fixture(scope="module")
def planner():
    return GpuPlanner(get_gpu())


def plan_with_words(planner: GpuPlanner, inputs: dict, budget: int):
    """The planner's own plan and tile words (:meth:`GpuPlanner.plan`, then pass P3's buffer
    read back), with P1's windows and P2's atlas of the same inputs (the passes run again on the
    same uploads: the same values) for the reference composed relative to the anchors."""
    pairs, tol = inputs["pairs"], inputs["pair_tolerances"]
    plan, buffer = planner.plan(pairs, tol, inputs["local_lo"], inputs["local_hi"],
                                inputs["world_lo"], inputs["world_hi"], inputs["transforms"],
                                budget_pixels=budget, open_bodies=inputs["open_bodies"],
                                faces=inputs["faces"])
    assert buffer is planner.words.tiles.buffer
    words = planner.words.read(len(plan))
    raw = planner.windows.windows_of(pairs, tol)
    faces = inputs["faces"]
    dense = faces[pairs[:, 0]] + faces[pairs[:, 1]] >= PROBE_FACES
    atlas = planner.atlas.run(atlas_windows(raw["kept"] != 0, raw["w"], raw["h"], dense),
                              budget_pixels=budget, faces=True)
    again = planner._tiles(raw, atlas, pairs, tol)
    for name in ("pair", "window", "round", "flags", "origin", "axes", "slab"):
        np.testing.assert_array_equal(getattr(again, name), getattr(plan, name))
    return plan, words, raw, atlas


def anchored_matrices(plan, raw, atlas, transforms, anchor) -> np.ndarray:
    """(T, 2, 3, 4) tile-from-body matrices composed in float64 relative to each pair's anchor
    (the same windows, tile places and tolerances as ``plan``): what the absolute float64
    composition would be without its rounding at the distance from the world's origin."""
    r = raw.take(atlas.pair)
    axes = r["axes"][:, :, :3].astype(np.float64)
    pixel = plan.pixel
    u = np.where(atlas.moved, atlas.u0, 0) + atlas.shift
    v = np.where(atlas.moved, atlas.v0, 0)
    corner = r["origin"].astype(np.float64) + (u * pixel)[:, None] * axes[:, 0] \
        + (v * pixel)[:, None] * axes[:, 1]
    a = anchor.take(r["anchor"], axis=0)                                  # (T, 3)
    t = transforms.take(plan.bodies, axis=0)                              # (T, 2, 4, 4)
    d = (t[:, :, :3, 3] - a[:, None]) - corner[:, None]                   # (T, 2, 3)
    rot = axes[:, None] @ t[:, :, :3, :3] / pixel[:, None, None, None]
    shift = np.einsum("tij,tsj->tsi", axes, d) / pixel[:, None, None]
    return np.concatenate([rot, shift[..., None]], axis=3)


def _matrices(words: np.ndarray) -> np.ndarray:
    return np.stack([words["m0"], words["m1"]], axis=1).astype(np.float64)


def corner_errors(plan, got: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(T,) the largest error, in pixels, of ``got`` at the body points that ``ref`` maps to the
    corners of each tile's window and slab."""
    w, h = plan.window[:, 2].astype(np.float64), plan.window[:, 3].astype(np.float64)
    corners = []
    for cu in (0.0, 1.0):
        for cv in (0.0, 1.0):
            for z in (plan.slab[:, 0], plan.slab[:, 1]):
                corners.append(np.stack([cu * w, cv * h, z], axis=1))
    q = np.stack(corners, axis=1)                                         # (T, 8, 3)
    lin, c = ref[..., :3], ref[..., 3]                                    # (T, 2, 3, 3), (T, 2, 3)
    p = np.linalg.solve(lin[:, :, None], (q[:, None] - c[:, :, None])[..., None])  # (T,2,8,3,1)
    delta = got - ref
    err = (delta[:, :, None, :, :3] @ p)[..., 0] + delta[:, :, None, :, 3]
    return np.abs(err).max(axis=(1, 2, 3))


def host_rounding(plan) -> np.ndarray:
    """(T,) pixels by which the absolute float64 composition itself may be off: a few roundings
    at ``2**-53`` of the tile's distance from the world's origin (its origin, ``t - origin``)."""
    return 4 * 2.0**-53 * np.abs(plan.origin).max(axis=1) / plan.pixel


def check_words(plan, words, ref_words, ref_matrices=None, *, context: str,
                slack: np.ndarray | float = 0.0) -> dict:
    """Integer fields and the slab exactly; the matrices within single precision's rounding of
    each tile's own size, and ``slack`` pixels (per tile) of the reference's own rounding.
    Returns the largest errors."""
    assert len(words) == len(ref_words) == len(plan), context
    for name in ("window", "bodies", "flags", "pair", "slab"):
        np.testing.assert_array_equal(words[name], ref_words[name], err_msg=f"{context}: {name}")
    got = _matrices(words)
    ref = _matrices(ref_words) if ref_matrices is None else ref_matrices
    rot, size = np.abs(got[..., :3] - ref[..., :3]), np.abs(ref[..., :3]).max(axis=(1, 2, 3))
    rot_rel = (rot.max(axis=(1, 2, 3)) / size).max()
    shift = np.abs(got[..., 3] - ref[..., 3]).max(axis=(1, 2))
    shift_bound = 1e-3 + slack + 2.0**-22 * np.abs(ref[..., 3]).max(axis=(1, 2))
    corner = corner_errors(plan, got, ref)
    assert rot_rel <= 1e-5, f"{context}: rotation rows {rot_rel:.3g} of their size apart"
    assert (shift <= shift_bound).all(), \
        f"{context}: last column {shift.max():.3g} pixel apart (tile {np.argmax(shift)})"
    assert (corner <= 1e-3 + slack).all(), \
        f"{context}: {corner.max():.3g} pixel apart at a window's corner (tile {np.argmax(corner)})"
    return {"rot": rot_rel, "shift": shift.max(), "corner": corner.max()}


SCENES = [
    # (seed, bodies, scale, offset from the world's origin, tolerance factor)
    (1, 60, 1.0, 0.0, 1.0), (3, 60, 1e-3, 0.0, 1.0), (4, 60, 1e3, 0.0, 1.0),
    (5, 60, 1.0, 1e7, 1.0), (6, 60, 1e3, 1e13, 1.0), (7, 400, 0.05, -3.0, 1.0),
    (21, 40, 1.0, 0.0, 0.1), (22, 40, 1e3, 1e13, 0.03),
]


@pytest.mark.parametrize("seed,n,scale,offset,fine", SCENES)
@pytest.mark.parametrize("budget", [2**22, 2**14])
def test_tile_words_equal_the_host_composition(planner, seed, n, scale, offset, fine, budget):
    """Random scenes (rotated, scaled, sheared, mirrored, flat; near the origin, at 1e7 and at
    1e13; 1e-3, 1 and 1e3 across), in one round and in many; with finer tolerances, large
    windows in pieces (tiles moved in their windows) and band cuts' second parts."""
    inputs = random_boxes(n, seed, scale=scale, offset=offset)
    inputs["pair_tolerances"] *= fine
    plan, words, raw, atlas = plan_with_words(planner, inputs, budget)
    context = f"seed {seed}, {len(plan)} tiles, budget {budget}"
    assert len(plan) > n // 2, context
    assert atlas.moved.any(), context
    if seed in (7, 21):  # band cuts
        assert (atlas.shift > 0).any(), context
    if fine < 1:
        assert atlas.u0.max() > 300, context
    ref = tile_words(plan, plan.tile_from_body(inputs["transforms"]))
    check_words(plan, words, ref, context=context, slack=host_rounding(plan))
    anchored = anchored_matrices(plan, raw, atlas, inputs["transforms"], planner.windows.anchor)
    check_words(plan, words, ref, anchored, context=f"{context}, anchored")


def test_far_from_the_origin_keeps_the_pairs_precision(planner):
    """Bodies 10 across at 1e13 from the world's origin (pixels of 0.1 to 0.4, above the
    tolerance policy's floor there): the words keep the precision of the pair's own size, where
    a composition measured from the world's origin in float32 is off by about the bodies' size
    (a hundred pixels), one in two float32 (48 bits) by up to 0.08 pixel, and the absolute
    float64 one by up to 0.02 pixel."""
    for offset in (1e13, -3e12):
        inputs = random_boxes(80, 11, scale=10.0, offset=offset)
        plan, words, raw, atlas = plan_with_words(planner, inputs, 2**16)
        context = f"{len(plan)} tiles at {offset:g}"
        assert len(plan) > 40, context
        ref = tile_words(plan, plan.tile_from_body(inputs["transforms"]))
        anchored = anchored_matrices(plan, raw, atlas, inputs["transforms"],
                                     planner.windows.anchor)
        check_words(plan, words, ref, context=context, slack=host_rounding(plan))
        errors = check_words(plan, words, ref, anchored, context=context)
        assert errors["shift"] < 1e-4 and errors["corner"] < 1e-4, context


def test_a_plan_grown_and_planned_again(planner):
    """A plan of more tiles than P2's first capacity: P2 runs again with grown buffers, and P3's
    buffer grows with them."""
    fresh = GpuPlanner(planner.gpu)
    p3 = fresh.words
    inputs = random_boxes(12, 8)
    inputs["pair_tolerances"] = np.full(len(inputs["pairs"]), 5e-4)
    plan, words, _, _ = plan_with_words(fresh, inputs, 2**22)
    assert len(plan) > 2 * len(inputs["pairs"]) + 16
    assert p3.tiles.buffer.size >= len(plan) * TILE.size
    ref = tile_words(plan, plan.tile_from_body(inputs["transforms"]))
    check_words(plan, words, ref, context="grown")
    # The records past the plan's tiles are left alone, and read() reads the same words.
    np.testing.assert_array_equal(p3.read(len(plan)).view(np.uint32), words.view(np.uint32))


def test_no_tile_and_bad_input(planner):
    p3 = planner.words
    inputs = random_boxes(30, 9)
    inputs["transforms"][:, :3, 3] += np.arange(30)[:, None] * 100.0   # every pair apart
    inputs["world_lo"] += np.arange(30)[:, None] * 100.0
    inputs["world_hi"] += np.arange(30)[:, None] * 100.0
    i, j = np.triu_indices(30, 1)
    inputs["pairs"] = np.stack([i[:5], j[:5]], axis=1)
    inputs["pair_tolerances"] = np.full(5, 0.02)
    t0 = time.perf_counter()
    plan, words, _, _ = plan_with_words(planner, inputs, 2**22)
    assert len(plan) == len(words) == 0 and plan.separated == 5
    assert time.perf_counter() - t0 < 10
    with pytest.raises(ValueError, match="do not match"):
        p3.upload_bodies(inputs["transforms"], np.zeros((29, 3)))

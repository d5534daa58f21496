"""Pass P1 (:mod:`pycinder.focused.plan.p1_windows`) against the NumPy planner it ports
(:func:`pycinder.focused.plan.plan_numpy_windows._plan_chunk`), never against its own output.

Random scenes (rotated, non-uniformly scaled, sheared and mirrored boxes, flat ones, equal
extents, touching and apart pairs, far and tiny bodies, several scales) are planned both ways and
compared up to float rounding:

- the same pairs are kept, except pairs whose overlap box is within a relative 1e-5 of empty;
- where NumPy's choices (the frame of the smallest window, the order of the box's extents, the
  window's long side) have a clear margin: the same frame, axes within 1e-5, origin and slab
  within 1e-2 pixel, the same sizes (or one off where an extent is within 1e-3 of a whole number
  of pixels) and the same flags (the count side may differ where the pair is as deep in front as
  behind, within rounding);
- where a choice is near a tie: a frame whose window is within 1e-4 of the smallest;
- always: the GPU's window holds NumPy's overlap box (in the frame the GPU chose).

The float64 planner rounds at ``2**-52`` of the distance from the world's origin; that (``NOISE``
ulps of the pair's distance from the origin) is allowed on top everywhere.
"""

import numpy as np
import pytest

from pycinder.focused.plan import plan_numpy_windows
from pycinder.focused.plan.p0_bodies import BODY, anchors, plan_bodies
from pycinder.focused.plan.p1_windows import WINDOW, GpuWindows
from pycinder.gpu.bindings import workgroup_grid
from pycinder.gpu.device import get_gpu
from pycinder.gpu.layout import FLAG_COUNT_BACK, FLAG_MIRROR, FLAG_OPEN
from pycinder.testing import box_world_bounds, random_box_bodies

NOISE = 2.0 ** -49
"""The float64 planner's own rounding allowed, per unit of the pair's distance from the origin
(8 ulps)."""
PX_TOL = 1e-2
"""Origin and slab: within this many pixels."""
AXES_TOL = 1e-5
TIE = 1e-4
"""Relative margin under which a choice (frame, extent order, long side) is a near tie."""
EMPTY = 1e-5
"""Relative margin of an overlap box under which the pair may be kept by one planner only."""

STATS: dict[str, float] = {}
"""Largest differences seen, per field (for the record; see ``check``)."""


@pytest.fixture(scope="module")
def gw() -> GpuWindows:
    return GpuWindows(get_gpu())


def _note(key: str, value: float) -> None:
    STATS[key] = max(STATS.get(key, 0.0), float(value))


def random_scene(rng: np.random.Generator, n: int, *, scale: float = 1.0, spread: float = 1.5,
                 offset: float = 0.0, quantum: float | None = None) -> dict:
    """``body_bounds``'s inputs for ``n`` random boxes about ``scale`` across within ``spread *
    scale`` of ``offset``: rotated, non-uniformly scaled, sheared and mirrored; some flat, some of
    equal extents, some open. World boxes are the transformed boxes' (some shrunk a little, as a
    mesh's own box is tighter). With ``quantum``, translations and world boxes are multiples of
    it (so that the scene moves to another offset exactly)."""
    lo, hi, transforms = random_box_bodies(rng, n, scale=scale, spread=spread)
    if quantum is not None:
        transforms[:, :3, 3] = np.round(transforms[:, :3, 3] / quantum) * quantum
    world_lo, world_hi = box_world_bounds(lo, hi, transforms)
    shrink = np.where(rng.random(n) < 0.3, rng.uniform(0.0, 0.2, n), 0.0)[:, None] \
        * (world_hi - world_lo)
    world_lo, world_hi = world_lo + 0.5 * shrink, world_hi - 0.5 * shrink
    if quantum is not None:
        world_lo = np.floor(world_lo / quantum) * quantum
        world_hi = np.ceil(world_hi / quantum) * quantum
    transforms[:, :3, 3] += offset
    return {"local_lo": lo, "local_hi": hi, "world_lo": world_lo + offset,
            "world_hi": world_hi + offset, "transforms": transforms,
            "open_bodies": rng.random(n) < 0.2}


def without_open(scene: dict) -> dict:
    return {key: value for key, value in scene.items() if key != "open_bodies"}


def all_pairs(n: int) -> np.ndarray:
    i, j = np.triu_indices(n, 1)
    return np.stack([i, j], axis=1)


def tolerances(rng: np.random.Generator, scene: dict, pairs: np.ndarray,
               lo: float = 0.01, hi: float = 0.05) -> np.ndarray:
    """Per pair, a random share of the smaller body's world box (windows of tens of pixels)."""
    size = (scene["world_hi"] - scene["world_lo"]).max(axis=1)
    return rng.uniform(lo, hi, len(pairs)) * np.minimum(size[pairs[:, 0]], size[pairs[:, 1]])


def frame_boxes(pairs: np.ndarray, bounds: plan_numpy_windows.BodyBounds
                ) -> tuple[np.ndarray, np.ndarray]:
    """NumPy's overlap box of every pair in each frame (world, a's, b's): lo, hi (3, K, 3), as
    ``_plan_chunk`` finds them (for the tests' margins: which decisions are close)."""
    a, b = pairs[:, 0], pairs[:, 1]
    lo = np.empty((3, len(pairs), 3))
    hi = np.empty((3, len(pairs), 3))
    lo[0] = np.maximum(bounds.world[a, 0], bounds.world[b, 0])
    hi[0] = np.minimum(bounds.world[a, 1], bounds.world[b, 1])
    for f, (me, other) in ((1, (a, b)), (2, (b, a))):
        rows = bounds.frames[me]
        h1 = np.abs(rows @ bounds.obb_axes[other]).sum(axis=2)
        c1 = np.einsum("kij,kj->ki", rows, bounds.obb_centre[other])
        c2 = np.einsum("kij,kj->ki", rows, bounds.aabb_centre[other])
        h2 = np.einsum("kij,kj->ki", np.abs(rows), bounds.aabb_half[other])
        lo[f] = np.maximum(bounds.own[me, 0], np.maximum(c1 - h1, c2 - h2))
        hi[f] = np.minimum(bounds.own[me, 1], np.minimum(c1 + h1, c2 + h2))
    return lo, hi


def window_areas(extent: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """``_plan_chunk``'s estimated window area of boxes of extents (..., 3)."""
    e = np.sort(extent, axis=-1)
    w = plan_numpy_windows
    win_x = (e[..., 2] * w._SIN + e[..., 1] * w._COS) / tol + 2 * w.MARGIN_PX + 1
    win_y = e[..., 0] / tol + 2 * w.MARGIN_PX + 1
    return win_x * win_y


def view_box(axes: np.ndarray, frame: np.ndarray, lo: np.ndarray, hi: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """Centre and half extents (K, 3) along ``axes`` (K, 3, 3) of the boxes ``lo``, ``hi``
    (K, 3) of frames ``frame`` (K, 3, 3), rows = axes."""
    m = axes @ np.transpose(frame, (0, 2, 1))
    return (np.einsum("kij,kj->ki", m, 0.5 * (lo + hi)),
            np.einsum("kij,kj->ki", np.abs(m), 0.5 * (hi - lo)))


def check(gw: GpuWindows, scene: dict, pairs: np.ndarray, tol: np.ndarray, *,
          reference: dict | None = None, shift: np.ndarray | float = 0.0) -> dict:
    """Plan ``pairs`` of ``scene`` on the GPU and compare with ``_plan_chunk`` (of
    ``reference``, default the scene itself, whose world is the scene's less ``shift``); returns
    counts of the pairs compared, near ties and pairs excused."""
    gw.upload_bodies(**scene)
    raw = gw.windows_of(pairs, tol)
    got = gw.to_plan(raw, pairs, tol)
    rb = plan_numpy_windows.body_bounds(**(scene if reference is None else reference))
    ref = plan_numpy_windows._plan_chunk(pairs, tol, rb, 0)
    k = len(pairs)
    a, b = pairs[:, 0], pairs[:, 1]
    centres = np.abs(rb.obb_centre).max(axis=1)
    noise = NOISE * np.maximum(centres[a], centres[b])                            # (K,)
    size = (rb.aabb_half * 2).max(axis=1)
    small = np.minimum(size[a], size[b])
    lo, hi = frame_boxes(pairs, rb)
    # Kept pairs: the same, but for boxes within EMPTY of empty.
    gap = (lo - hi).max(axis=(0, 2))
    near_empty = np.abs(gap) <= EMPTY * small + noise
    kept_ref = np.zeros(k, bool)
    if ref is not None:
        kept_ref[ref["pair"]] = True
    kept_gpu = raw["kept"] != 0
    assert set(np.unique(raw["kept"])) <= {0, 1}
    differ = np.flatnonzero(kept_ref != kept_gpu)
    assert near_empty[differ].all(), \
        f"kept differs for pairs {differ[~near_empty[differ]][:10]} (gap {gap[differ][:10]})"
    assert (raw["w"][~kept_gpu] == 0).all() and (raw["h"][~kept_gpu] == 0).all()
    counts = {"pairs": k, "kept": int(kept_ref.sum()), "excused": len(differ)}
    if ref is None:
        assert got is None or not kept_gpu.any() or near_empty[kept_gpu].all()
        return counts
    both = np.flatnonzero(kept_ref & kept_gpu)
    ir = np.searchsorted(ref["pair"], both)
    ig = np.searchsorted(got["pair"], both)
    assert (ref["pair"][ir] == both).all() and (got["pair"][ig] == both).all()
    assert (got["bodies"][ig] == pairs[both]).all()
    assert np.array_equal(got["pixel"][ig], ref["pixel"][ir])
    px = tol[both]
    nz = noise[both]
    m = len(both)
    # Near ties: NumPy's frame choice, the order of its box's extents, the long side.
    area = window_areas(hi[:, both] - lo[:, both], px)                            # (3, m)
    f_ref = np.argmin(area, axis=0)
    f_gpu = raw["frame"][both].astype(np.intp)
    cols = np.arange(m)
    smallest = area[f_ref, cols]
    # (a tie of frames with the same axes, such as the world's and an unturned body's, is none)
    frames = rb.choices[np.stack([np.zeros(m, np.intp), pairs[both, 0] + 1, pairs[both, 1] + 1])]
    frame = frames[f_ref, cols]                                                  # (m, 3, 3)
    same = np.abs(frames - frame).max(axis=(2, 3)) <= 1e-12                      # (3, m)
    frame_tie = ((area <= smallest * (1 + TIE)) & ~same).any(axis=0)
    flo, fhi = lo[f_ref, both], hi[f_ref, both]
    e = fhi - flo
    order_tie = np.zeros(m, bool)
    for i, j in ((0, 1), (0, 2), (1, 2)):
        order_tie |= np.abs(e[:, i] - e[:, j]) <= TIE * np.maximum(e[:, i], e[:, j]) + nz
    axes_ref = ref["axes"][ir]
    vc, vh = view_box(axes_ref, frame, flo, fhi)
    ext = 2 * vh                                                          # (vhi - vlo) per axis
    swap_tie = np.abs(ext[:, 0] - ext[:, 1]) <= TIE * np.maximum(ext[:, 0], ext[:, 1]) + nz
    tie = frame_tie | order_tie | swap_tie
    counts["compared"] = int((~tie).sum())
    counts["ties"] = int(tie.sum())
    counts["frame ties"], counts["order ties"], counts["side ties"] = \
        int(frame_tie.sum()), int(order_tie.sum()), int(swap_tie.sum())
    # Always: the GPU's frame is within TIE of the smallest window, and its window holds NumPy's
    # box of that frame.
    assert (area[f_gpu, cols] <= smallest * (1 + TIE)).all()
    assert same[f_gpu, cols][~tie].all()
    g_axes = got["axes"][ig]
    # (the origin as the pass gives it, relative to its anchor: at 1e13 a float64 world point
    # itself rounds to 1e-3)
    g_origin = (gw.anchor[raw["anchor"][both]] - shift) + raw["origin"][both]
    assert np.allclose(g_origin + shift, got["origin"][ig], rtol=2.0 ** -50, atol=0)
    g_w, g_h, g_slab = got["w"][ig], got["h"][ig], got["slab"][ig]
    g_frame = frames[f_gpu, cols]
    glo, ghi = lo[f_gpu, both], hi[f_gpu, both]
    corners = np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), -1).reshape(8, 3)
    box = glo[:, None] + corners[None] * (ghi - glo)[:, None]                    # (m, 8, 3)
    world = np.einsum("kji,kcj->kci", g_frame, box)                     # frame rows: x = R^T y
    uvz = np.einsum("kij,kcj->kci", g_axes, world - g_origin[:, None]) / px[:, None, None]
    slack = PX_TOL + nz / px
    margin = plan_numpy_windows.MARGIN_PX
    outside = np.maximum.reduce([
        margin - uvz[..., 0].min(axis=1), uvz[..., 0].max(axis=1) - (g_w - margin),
        margin - uvz[..., 1].min(axis=1), uvz[..., 1].max(axis=1) - (g_h - margin),
        g_slab[:, 0] - uvz[..., 2].min(axis=1), uvz[..., 2].max(axis=1) - g_slab[:, 1]])
    _note("box outside window (pixels)", outside.max())
    assert (outside <= slack).all(), f"window misses the box by {outside.max()} pixels"
    assert (np.abs(np.linalg.det(g_axes) - 1) < 1e-5).all()
    # Near ties: the window's area is NumPy's, but for a pixel along each side.
    wh, rwh = g_w * g_h, ref["w"][ir] * ref["h"][ir]
    assert (np.abs(wh - rwh)[tie] <= (TIE * rwh + ref["w"][ir] + ref["h"][ir] + g_w + g_h)[tie]
            ).all()
    # Clear choices: the same window.
    c = ~tie
    d_axes = np.abs(g_axes - axes_ref).max(axis=(1, 2))[c]
    d_origin = (np.abs(g_origin - ref["origin"][ir]).max(axis=1) / px)[c]
    d_slab = np.abs(g_slab - ref["slab"][ir]).max(axis=1)[c]
    if c.any():
        _note("axes", d_axes.max())
        _note("origin (pixels)", d_origin.max())
        _note("slab (pixels)", d_slab.max())
    assert (d_axes <= AXES_TOL).all(), f"axes differ by {d_axes.max()}"
    assert (d_origin <= slack[c]).all(), f"origins differ by {d_origin.max()} pixels"
    assert (d_slab <= slack[c]).all(), f"slabs differ by {d_slab.max()} pixels"
    for name, r in (("w", 0), ("h", 1)):
        x = ext[:, r] / px                      # NumPy's extent in pixels, before its ceil
        near_whole = np.abs(x - np.round(x)) <= 1e-3 + nz / px
        dw = np.abs(got[name][ig] - ref[name][ir])
        assert (dw[c & ~near_whole] == 0).all(), f"{name} differs"
        assert (dw[c & near_whole] <= 1).all(), f"{name} differs by more than one"
        counts[f"{name} one off"] = int((dw[c] == 1).sum())
    # Flags: the bodies' bits always; the count side unless front and back are as deep.
    g_flags, r_flags = got["flags"][ig], ref["flags"][ir]
    assert ((g_flags ^ r_flags) & ~FLAG_COUNT_BACK == 0).all()
    view = axes_ref[:, 2]
    vlo2, vhi2 = vc[:, 2] - vh[:, 2], vc[:, 2] + vh[:, 2]
    ends = []
    for body in (pairs[both, 0], pairs[both, 1]):
        centre = np.einsum("kj,kj->k", view, rb.obb_centre[body])
        half = np.abs(np.einsum("kj,kjc->kc", view, rb.obb_axes[body])).sum(axis=1)
        ends.append((centre - half, centre + half))
    front = vlo2 - np.minimum(ends[0][0], ends[1][0])
    back = np.maximum(ends[0][1], ends[1][1]) - vhi2
    as_deep = np.abs(front - back) <= 1e-5 * (np.abs(front) + np.abs(back)) + PX_TOL * px + nz
    side_differs = ((g_flags ^ r_flags) & FLAG_COUNT_BACK) != 0
    assert (as_deep | ~side_differs)[c].all(), "count side differs"
    counts["count side differs"] = int(side_differs.sum())
    return counts


@pytest.mark.parametrize("scale, offset", [(1.0, 0.0), (1e-3, 0.0), (1e3, 0.0), (1.0, 1e7),
                                           (1e3, 1e13)])
def test_random_scenes(gw, scale, offset):
    rng = np.random.default_rng(int(np.log10(scale) + 3 + 10 * np.log10(offset + 1)))
    total = {"pairs": 0, "kept": 0, "excused": 0, "ties": 0, "compared": 0}
    for n, spread in ((60, 0.6), (30, 0.25)):
        scene = random_scene(rng, n, scale=scale, spread=spread, offset=offset)
        pairs = all_pairs(n)
        counts = check(gw, scene, pairs, tolerances(rng, scene, pairs))
        for key in total:
            total[key] += counts.get(key, 0)
    assert total["kept"] > 0.1 * total["pairs"]          # touching and apart pairs both
    assert total["kept"] < 0.9 * total["pairs"]
    assert total["compared"] > 0.8 * total["kept"]       # few near ties
    assert total["excused"] <= 0.002 * total["pairs"] + 1


def test_far_pair_keeps_its_precision(gw):
    """A scene 1e13 from the origin, with pixels of 1/30 of the bodies, planned as the same
    scene at the origin is (where float64 is exact enough): float32 measured from each pair's
    anchor loses nothing to the distance."""
    rng = np.random.default_rng(7)
    n, offset = 40, 1e13
    quantum = 2.0 ** -8                     # translations exact at the origin and at 1e13
    near = random_scene(rng, n, scale=30.0, spread=0.4, quantum=quantum)
    far = {**near, "transforms": near["transforms"].copy(),
           "world_lo": near["world_lo"] + offset, "world_hi": near["world_hi"] + offset}
    far["transforms"][:, :3, 3] += offset
    assert np.array_equal(far["transforms"][:, :3, 3] - offset, near["transforms"][:, :3, 3])
    pairs = all_pairs(n)
    tol = tolerances(rng, near, pairs, 0.02, 0.05)
    counts = check(gw, far, pairs, tol, reference=near, shift=offset)
    assert counts["compared"] > 100


def test_tiny_inside_huge(gw):
    """1e-6 boxes inside a 1e6 one (and beside each other), pixels of a fiftieth of the tiny
    ones: the tiny pairs and the tiny-huge pairs are planned to the tiny bodies' pixel."""
    rng = np.random.default_rng(11)
    tiny = random_scene(rng, 12, scale=1e-6, spread=0.8)
    huge = random_scene(rng, 2, scale=1e6, spread=0.01)
    huge["local_lo"], huge["local_hi"] = np.full((2, 3), -5e5), np.full((2, 3), 5e5)
    huge["world_lo"], huge["world_hi"] = box_world_bounds(huge["local_lo"], huge["local_hi"],
                                                          huge["transforms"])
    scene = {key: np.concatenate([huge[key], tiny[key]]) for key in tiny}
    place = np.array([1234.5, -678.9, 42.1])
    scene["transforms"][2:, :3, 3] += place
    scene["world_lo"][2:] += place
    scene["world_hi"][2:] += place
    for h in range(2):  # the huge boxes hold the place, far from their faces
        assert (scene["world_lo"][h] < place - 1e5).all()
        assert (scene["world_hi"][h] > place + 1e5).all()
    pairs = all_pairs(len(scene["transforms"]))
    tol = tolerances(rng, scene, pairs, 0.02, 0.05)
    counts = check(gw, scene, pairs, tol)
    assert counts["excused"] == 0
    gw.upload_bodies(**scene)
    raw = gw.windows_of(pairs, tol)
    with_huge = (pairs[:, 0] < 2) & (pairs[:, 1] >= 2)
    assert raw["kept"][with_huge].all()
    assert (raw["anchor"][with_huge] >= 2).all()        # the tiny body anchors the pair
    assert (raw["w"][with_huge] < 200).all()


def test_equal_touching_and_apart_boxes(gw):
    """Axis-aligned equal cubes: face to face (touching), overlapping, an exact gap apart, edge
    to edge, just apart and just overlapping (by 2**-15); every frame ties, every extent ties."""
    n = 10
    lo = np.zeros((n, 3))
    hi = np.ones((n, 3))
    t = np.tile(np.eye(4), (n, 1, 1))
    t[:, :3, 3] = [(0, 0, 0), (1, 0, 0), (0.5, 0.5, 0), (2.25, 0, 0), (1, 1, 0), (0, 0, 1),
                   (0.5, 0.5, 0.5), (-1.0, -1.0, -1.0), (0, 0, 0), (0.3, -1 - 2**-15, 0.2)]
    t[7, :3, :3] = np.diag([1.0, -1.0, 1.0])          # mirrored, same box
    t[7, :3, 3] = (0, 1, 0)
    scene = {"local_lo": lo, "local_hi": hi, "transforms": t,
             "world_lo": t[:, :3, 3] + np.minimum(0, np.diagonal(t[:, :3, :3], axis1=1, axis2=2)),
             "world_hi": t[:, :3, 3] + np.maximum(0, np.diagonal(t[:, :3, :3], axis1=1, axis2=2)),
             "open_bodies": np.arange(n) % 3 == 0}
    t[8, :3, 3] = (0.3, -1 + 2**-15, 0.2)
    scene["world_lo"][8:] = t[8:, :3, 3]
    scene["world_hi"][8:] = t[8:, :3, 3] + 1
    pairs = all_pairs(n)
    tol = np.full(len(pairs), 0.05)
    counts = check(gw, scene, pairs, tol)
    assert counts["excused"] == 0
    kept = gw.to_plan(gw.windows_of(pairs, tol), pairs, tol)["bodies"].tolist()
    assert [0, 8] in kept and [0, 9] not in kept
    ref = plan_numpy_windows._plan_chunk(pairs, tol, plan_numpy_windows.body_bounds(**scene), 0)
    got = gw.run(pairs, tol, **scene)
    assert np.array_equal(got["pair"], ref["pair"])
    flags = got["flags"] & ~FLAG_COUNT_BACK
    assert np.array_equal(flags, ref["flags"] & ~FLAG_COUNT_BACK)
    assert (flags & (FLAG_MIRROR[0] | FLAG_MIRROR[1] | FLAG_OPEN[0] | FLAG_OPEN[1])).any()


def test_all_apart_is_none(gw):
    rng = np.random.default_rng(3)
    scene = random_scene(rng, 10, spread=1.0)
    step = np.arange(10)[:, None] * 100.0
    scene["transforms"][:, :3, 3] += step
    scene["world_lo"] = scene["world_lo"] + step
    scene["world_hi"] = scene["world_hi"] + step
    pairs = all_pairs(10)
    assert gw.run(pairs, np.full(len(pairs), 0.01), **scene) is None
    assert plan_numpy_windows._plan_chunk(pairs, np.full(len(pairs), 0.01),
                             plan_numpy_windows.body_bounds(**scene), 0) is None


def test_anchors_are_exact_in_two_floats():
    rng = np.random.default_rng(5)
    c = rng.normal(size=(1000, 3)) * 10.0 ** rng.integers(-8, 14, (1000, 1))
    c[:5] = [(0, 0, 0), (1e13, 1e13 + 0.1, -3), (0.1, 0.2, 0.3), (-1e-30, 0, 1), (2**40, 1, 0)]
    anchor = anchors(c)
    hi = anchor.astype(np.float32)
    lo = (anchor - hi).astype(np.float32)
    assert np.array_equal(hi.astype(np.float64) + lo.astype(np.float64), anchor)
    assert (np.abs(anchor - c) <= 2.0 ** -46 * 2 * np.abs(c).max(axis=1, keepdims=True)).all()
    scene = random_scene(rng, 20, offset=1e7)
    bodies, anchor = plan_bodies(**without_open(scene),
                                 bounds=plan_numpy_windows.body_bounds(**scene))
    assert bodies.dtype == BODY.dtype
    assert np.array_equal(bodies["hi"].astype(np.float64) + bodies["lo"], anchor)
    assert (np.abs(bodies["centre"]) < 1e-6).all()


def test_many_pairs_take_a_grid_of_workgroups(gw):
    """70,000 pairs, one per workgroup: more workgroups than one dispatch dimension holds (the
    grid's rows), and the same pairs with the usual workgroups."""
    rng = np.random.default_rng(9)
    n = 400
    scene = random_scene(rng, n, scale=1.0, spread=1.2)
    pairs = all_pairs(n)[rng.permutation(n * (n - 1) // 2)[:70000]]
    tol = tolerances(rng, scene, pairs)
    one = GpuWindows(get_gpu(), workgroup=1)
    assert workgroup_grid(len(pairs))[1] > 1 and len(pairs) > 65535
    counts = check(one, scene, pairs, tol)
    assert counts["kept"] > 2000
    got = one.run(pairs, tol, **scene)
    again = gw.run(pairs, tol, **scene)
    for key in got:
        assert np.array_equal(got[key], again[key]), key


def test_buffers_are_reused(gw):
    """A second, smaller call reuses every buffer and plans its own pairs only."""
    rng = np.random.default_rng(13)
    big = random_scene(rng, 80)
    pairs = all_pairs(80)
    check(gw, big, pairs, tolerances(rng, big, pairs))
    buffers = [b.buffer for b in (gw.p0.bodies, gw.pairs, gw.pair_tolerances, gw.windows)]
    small = random_scene(rng, 25, spread=0.3)
    pairs = all_pairs(25)[::3]
    counts = check(gw, small, pairs, tolerances(rng, small, pairs))
    assert counts["kept"] > 20
    kept = (gw.p0.bodies, gw.pairs, gw.pair_tolerances, gw.windows)
    assert all(b.buffer is old for b, old in zip(kept, buffers))
    raw = gw.windows_of(pairs[:0], np.zeros(0))
    assert raw.dtype == WINDOW.dtype and len(raw) == 0


def test_encode_chains_into_a_callers_encoder(gw):
    """The pass records into a caller's encoder, reading pairs from the caller's buffer; its
    windows buffer holds one WINDOW per pair."""
    import wgpu

    rng = np.random.default_rng(17)
    scene = random_scene(rng, 30, spread=0.8)
    pairs = all_pairs(30)
    tol = tolerances(rng, scene, pairs)
    gw.upload_bodies(**scene)
    bounds = plan_numpy_windows.body_bounds(**scene)
    device = gw.gpu.device
    usage = wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_DST
    mine = device.create_buffer_with_data(data=pairs.astype(np.uint32), usage=usage)
    tols = device.create_buffer_with_data(data=tol.astype(np.float32), usage=usage)
    encoder = device.create_command_encoder()
    gw.encode(encoder, len(pairs), pairs=mine, pair_tolerances=tols)
    nbytes = len(pairs) * WINDOW.size
    staging = gw.readback.ensure(nbytes)
    encoder.copy_buffer_to_buffer(gw.buffer.buffer, 0, staging, 0, nbytes)
    device.queue.submit([encoder.finish()])
    raw = gw.readback.read(nbytes, np.uint8).view(WINDOW.dtype)
    got = gw.to_plan(raw, pairs, tol)
    ref = plan_numpy_windows._plan_chunk(pairs, tol, bounds, 0)
    assert np.array_equal(got["pair"], ref["pair"])
    assert np.abs(got["origin"] - ref["origin"]).max() < 1e-3 * tol.min()

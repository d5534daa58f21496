"""Pass P0 (:mod:`pycinder.focused.plan.p0_bodies`) against its float64 reference
(:func:`pycinder.focused.plan.p0_bodies.plan_bodies`, from
:func:`pycinder.focused.plan.plan_numpy_windows.body_bounds` and NumPy's QR), never against its own
output.

- Random bodies (rotated, non-uniformly scaled, sheared, mirrored, flat, open) at several scales
  and far from the world's origin: what the host rounds once (anchors, centres, world boxes) is
  the same bits; the frames, half axes and intervals are within a few float32 roundings of their
  own size (never of the distance from the origin); the flags are the same.
- Frames whose QR meets exact zeros (every signed permutation, with ``+0.0`` and ``-0.0``, scaled
  or not, and the identity): the very frame NumPy's QR makes, axis signs included.
"""

import itertools

import numpy as np
import pytest

from pycinder.focused.plan import plan_numpy_windows
from pycinder.focused.plan.p0_bodies import BODY, GpuBodies, body_inputs, plan_bodies
from pycinder.gpu.device import get_gpu
from pycinder.gpu.layout import FLAG_MIRROR
from pycinder.testing import box_world_bounds, random_box_bodies, random_rotation

EPS = 2.0 ** -24

STATS: dict[str, float] = {}
"""Largest differences seen, in units of EPS times each field's own size (for the record)."""


@pytest.fixture(scope="module")
def p0() -> GpuBodies:
    return GpuBodies(get_gpu())


def scene(rng: np.random.Generator, n: int, scale: float, offset: float) -> dict:
    lo, hi, transforms = random_box_bodies(rng, n, scale=scale, spread=1.5)
    world_lo, world_hi = box_world_bounds(lo, hi, transforms)
    transforms[:, :3, 3] += offset
    return {"local_lo": lo, "local_hi": hi, "world_lo": world_lo + offset,
            "world_hi": world_hi + offset, "transforms": transforms,
            "open_bodies": rng.random(n) < 0.3}


def compare(p0: GpuBodies, inputs: dict) -> tuple[np.ndarray, np.ndarray]:
    """Upload ``inputs``, run P0 and compare with ``plan_bodies``; returns both records."""
    anchor = p0.upload(**inputs)
    got = p0.read()
    bounds = plan_numpy_windows.body_bounds(**inputs)
    ref, ref_anchor = plan_bodies(**{k: v for k, v in inputs.items() if k != "open_bodies"},
                                  bounds=bounds)
    assert got.dtype == BODY.dtype and len(got) == len(ref)
    assert np.array_equal(anchor, ref_anchor)
    # Rounded once on the host, from the same float64 values: the same bits.
    for field in ("hi", "lo", "centre", "aabb_centre", "aabb_half"):
        assert np.array_equal(got[field], ref[field]), field
    assert np.array_equal(got["flags_a"], ref["flags_a"])
    assert np.array_equal(got["flags_b"], ref["flags_b"])
    assert np.array_equal(got["flags_a"] & FLAG_MIRROR[0] != 0, bounds.mirrored)
    # Unit axes: within a few roundings of 1 (a sign of difference would be 2).
    frame = np.abs(got["frame"][:, :, :3] - ref["frame"][:, :, :3]).max(axis=(1, 2))
    _note("frame", frame.max())
    assert (frame <= 16 * EPS).all(), f"frames differ: {frame.max() / EPS:.1f} eps"
    # Half axes: within a few roundings of each axis's length.
    half = np.abs(got["half_axes"][:, :, :3] - ref["half_axes"][:, :, :3]).max(axis=2)
    length = np.linalg.norm(ref["half_axes"][:, :, :3].astype(np.float64), axis=2)
    _note("half_axes", (half / np.maximum(length, 1e-300)).max())
    assert (half <= 4 * EPS * length).all()
    # Intervals: within a few roundings of the body's own extent from its anchor.
    extent = (np.abs(ref["centre"]).max(axis=1) + length.sum(axis=1)
              + np.abs(ref["aabb_centre"]).max(axis=1) + np.abs(ref["aabb_half"]).max(axis=1))
    for field in ("world_lo", "world_hi", "own_lo", "own_hi"):
        err = np.abs(got[field].astype(np.float64) - ref[field]).max(axis=1)
        _note(field, (err / extent).max())
        assert (err <= 16 * EPS * extent).all(), field
    size = np.abs(got["size"].astype(np.float64) - ref["size"])
    assert (size <= 4 * EPS * ref["size"]).all()
    return got, ref


def _note(key: str, value: float) -> None:
    STATS[key] = max(STATS.get(key, 0.0), float(value) / EPS)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
@pytest.mark.parametrize("offset", [0.0, 1e7, 1e13])
def test_random_bodies_match_the_float64_reference(p0, scale, offset):
    rng = np.random.default_rng(int(np.log10(scale) + 10 * np.log10(offset + 1)) + 40)
    got, _ = compare(p0, scene(rng, 300, scale, offset * scale))
    assert (got["flags_a"] & FLAG_MIRROR[0]).any() and not (got["flags_a"] & FLAG_MIRROR[0]).all()


def signed_permutations() -> np.ndarray:
    """Every signed permutation matrix (48), with its zeros signed along columns and along rows
    (``-0.0`` where a zero shares a column or row with a -1), each also scaled per axis: 192."""
    out = []
    for perm in itertools.permutations(range(3)):
        p = np.eye(3)[list(perm)]
        for signs in itertools.product((1.0, -1.0), repeat=3):
            s = np.array(signs)
            for m in (p * s[None, :], s[:, None] * p):
                out.append(m)
                out.append(m * np.array([0.5, 2.0, 3.0]))
    return np.array(out)


def test_frames_take_numpys_signs_where_qr_meets_exact_zeros(p0):
    """LAPACK leaves a column whose part below the diagonal is exactly zero unreflected, and
    takes ``-0.0`` as negative: P0's frames are NumPy's, sign for sign (every value here is
    exact, so any difference is a sign)."""
    m = signed_permutations()
    assert (np.signbit(m) & (m == 0)).any()
    got, ref = compare(p0, boxes_of(m))
    frames = np.transpose(plan_numpy_windows._qr_frames(m), (0, 2, 1))
    assert np.array_equal(got["frame"][:, :, :3], frames)
    assert np.array_equal(ref["frame"][:, :, :3], frames)


def quarter_turns() -> np.ndarray:
    """Rotations composed of quarter turns about the axes, built from ``np.pi`` (every pair and
    triple of multiples of pi / 2 about x, y and z, in two axis orders): their zeros are not
    zeros but residues such as ``6e-17`` and their products (``4e-33``, ``2e-49``), which
    LAPACK reflects where they are not exactly zero."""
    import trimesh

    out = []
    angles = np.arange(4) * (np.pi / 2)
    for axes in ("sxyz", "rzyx"):
        for a, b, c in itertools.product(angles, repeat=3):
            out.append(trimesh.transformations.euler_matrix(a, b, c, axes)[:3, :3])
    return np.array(out)


def boxes_of(m: np.ndarray) -> dict:
    """Unit boxes under linear parts ``m`` (n, 3, 3), placed apart."""
    n = len(m)
    transforms = np.tile(np.eye(4), (n, 1, 1))
    transforms[:, :3, :3] = m
    transforms[:, :3, 3] = np.arange(n)[:, None] * 3.0
    lo, hi = -np.ones((n, 3)), np.ones((n, 3))
    world_lo, world_hi = box_world_bounds(lo, hi, transforms)
    return {"local_lo": lo, "local_hi": hi, "world_lo": world_lo, "world_hi": world_hi,
            "transforms": transforms}


def test_frames_of_quarter_turns_built_from_pi_are_numpys(p0):
    """Composed quarter and half turns: residues far below 1 (some below float32's smallest
    normal number) decide LAPACK's reflections; P0's frames are NumPy's, sign for sign."""
    m = quarter_turns()
    tiny = (np.abs(m) > 0) & (np.abs(m) < 1e-30)
    assert tiny.any() and ((np.abs(m) > 1e-40) & (np.abs(m) < 1e-19)).any()
    got, ref = compare(p0, boxes_of(m))
    frames = np.transpose(plan_numpy_windows._qr_frames(m), (0, 2, 1))
    assert np.abs(got["frame"][:, :, :3] - frames).max() <= 16 * EPS


def test_mirror_flags_are_the_float64_determinants_sign(p0):
    """Bodies flattened to 1e-9 along one turned axis, or scaled by 1e-14 (their float32
    determinant rounds to zero or to the wrong sign), mirrored or not: P0's flags are the
    NumPy planner's."""
    rng = np.random.default_rng(12)
    turns = [random_rotation(rng)[:3, :3] for _ in range(40)]
    m = []
    for k, r in enumerate(turns):
        flat = r @ np.diag([1.0, 1.0, 1e-9]) @ r.T
        m.append(flat @ np.diag([1.0, 1.0, -1.0]) if k % 2 else flat)
        m.append(1e-14 * (r @ np.diag([1.0, 1.0, -1.0 if k % 2 else 1.0])))
    m = np.array(m)
    got, _ = compare(p0, boxes_of(m))
    mirrored = np.linalg.det(m) < 0
    assert mirrored.any() and not mirrored.all()
    assert np.array_equal(got["flags_a"] & FLAG_MIRROR[0] != 0, mirrored)
    assert np.array_equal(got["flags_b"] & FLAG_MIRROR[1] != 0, mirrored)


def test_float32_transforms_and_a_second_smaller_upload(p0):
    """Float32 transforms are taken as given (the host's QR of them is the reference), and a
    smaller upload after a larger one plans its own bodies only, in the same buffers."""
    rng = np.random.default_rng(3)
    big = scene(rng, 120, 1.0, 0.0)
    compare(p0, big)
    buffers = (p0.poses.buffer, p0.extents.buffer, p0.bodies.buffer)
    small = scene(rng, 17, 2.0, 5.0)
    small["transforms"] = small["transforms"].astype(np.float32)
    got, _ = compare(p0, small)
    assert len(got) == 17
    assert (p0.poses.buffer, p0.extents.buffer, p0.bodies.buffer) == buffers


def test_no_bodies(p0):
    none = np.zeros((0, 3))
    p0.upload(none, none, none, none, np.zeros((0, 4, 4)))
    assert p0.count == 0 and len(p0.read()) == 0


def test_inputs_keep_float64_offsets_from_the_anchor():
    """A body far from the origin whose box lies far from its own origin (map coordinates in
    the mesh, an identity transform): its centre from the anchor is computed in float64 before
    rounding, so it is the rounding of a tiny offset, not of 5e5."""
    lo = np.array([[5e5, 5e5, 0.0]])
    hi = lo + 1.0
    transforms = np.eye(4)[None]
    poses, extents, anchor = body_inputs(lo, hi, lo, hi, transforms)
    centre = 0.5 * (lo + hi)
    assert np.abs(anchor - centre).max() < 2.0 ** -26
    assert np.abs(extents["centre"]).max() < 2.0 ** -26
    assert np.array_equal(poses["rows"][0, :, 3], (-anchor[0]).astype(np.float32))

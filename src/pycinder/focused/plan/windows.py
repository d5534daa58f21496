"""Pass P1 of the GPU tile planner, windows: each candidate pair's window, as
:func:`pycinder.focused.plan.hostwindows._plan_chunk` plans it, in single precision
(``plan_windows.wgsl``).

One invocation per candidate pair (a, b) finds where the pair's bounding volumes overlap in each
of three frames (the world's axes, body a's and body b's), whether they are apart, the frame of
the smallest window, and that window: its view axes (tilted, flipped to stay right-handed, long
side along screen x), size in pixels, origin, pixel size, depth slab and flags. The windows stay
on the GPU (:attr:`GpuWindows.buffer`, one :data:`WINDOW` per pair) for the passes that pack
them into the atlas; :meth:`GpuWindows.run` reads them back as ``_plan_chunk``'s dict.

Precision
---------
WGSL has no float64, and a scene may lie far from the world's origin, or hold a tiny body inside
a huge one. So nothing is measured from the world's origin on the GPU:

- The host (float64, O(N) in the bodies) computes every body's bounds as
  :func:`pycinder.focused.plan.hostwindows.body_bounds` does, and picks the body's *anchor*: its
  oriented box's centre ``c``, rounded to a multiple of ``2**(e - 46)`` (where ``max |c| < 2**e``),
  so that the anchor is exactly ``hi + lo`` of two float32 vectors. Every other quantity of the
  body is taken relative to its own anchor and rounded to float32 (:data:`BODY`): its boxes'
  centres (measured from the inputs, the translation and the world box's bounds less the anchor, so
  that they do not round at the anchor's distance from the origin as ``body_bounds``'s do), its
  intervals along the world's axes and its own frame's (from those centres), its half axes and
  frame.
- Per pair, the shader anchors the pair at the body with the smaller world box (ties: a), and
  moves the other body's quantities by the offset between the anchors,
  ``d = (hi_o - hi_p) + (lo_o - lo_p)``. Both differences are exact for bodies whose anchors are
  within about ``2**-22`` of their distance from the world's origin of each other (then ``d`` is
  rounded once, to ``2**-24 |d|``); farther apart, each is rounded relative to ``|d|``.
- All the planning is done relative to the pair's anchor; the window's origin is written
  relative to it (:data:`WINDOW` ``origin``, with the anchor body's index), and the host adds the
  anchor back in float64.

Error bound: each bound of the overlap box comes from one body's bound (a max or min selects it,
exactly), so it is off by a few float32 roundings of that bound's own terms: about
``2**-24 * (r + |d|)``, with ``r`` the extent of that body's boxes from its anchor and ``d`` the
pair's anchor offset (0 for the anchor body's own bounds). The window's origin, slab and sizes
inherit that, plus a few roundings of the window's own extent; the view axes are within a few
``2**-24`` of the float64 ones. None of it grows with the distance from the world's origin: a
pair 1e13 from it, or a tiny body inside a huge one, keeps the precision of its own size (but
where a huge body's face cuts a tiny body's box, that face is only as precise as ``2**-24`` of
the huge body's extent). The float64 planner itself rounds at ``2**-53`` of the distance from the
origin (1e-3 at 1e13). Measured against it (``tests/test_gpu_windows.py``), the origin and slab
are within 1e-4 pixel and the axes within 1e-7 where its choices are clear. Where the float64
and the float32 planner round a close decision differently (a frame's area, the order of equal
extents, a pair whose boxes just touch, an extent of almost a whole number of pixels, the count
side of a pair as deep in front as behind), the two plans differ there, each a valid window of
the pair.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import wgpu

from ...gpu.bindings import Resource, Stage, dispatch
from ...gpu.buffers import DEFAULT_TIMEOUT, GrowableBuffer, Readback
from ...gpu import native
from ...gpu.device import Gpu, get_gpu
from ...gpu.layout import FLAG_COUNT_BACK, ROW, WORKGROUP
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .atlas import WINDOW as ATLAS_WINDOW
from .hostwindows import MARGIN_PX, TILT, BodyBounds, body_bounds, interval_meet, sum3
from .tiles import PROBE_FACES

BODY = Struct("PlanBody", [
    ("hi", "vec3f", "the body's anchor, high part: f32(anchor)"),
    ("size", "f32", "its world box's half extents, summed: the smaller body anchors a pair"),
    ("lo", "vec3f", "the anchor's low part: anchor - hi (exact)"),
    ("flags_a", "u32", "FLAG_* bits the body brings as body a of a pair"),
    ("centre", "vec3f", "the oriented box's centre - anchor"),
    ("flags_b", "u32", "FLAG_* bits the body brings as body b"),
    ("half_axes", "array<vec4f, 3>", "the oriented box's half axes (xyz; w unused)"),
    ("frame", "array<vec4f, 3>", "the body's orthonormal frame, one axis per element (xyz)"),
    ("aabb_centre", "vec3f", "the world box's centre - anchor"),
    ("aabb_half", "vec3f", "the world box's half extents"),
    ("world_lo", "vec3f", "where both boxes hold along the world's axes, - anchor"),
    ("world_hi", "vec3f", ""),
    ("own_lo", "vec3f", "where both boxes hold along the frame's axes, - dot(axis, anchor)"),
    ("own_hi", "vec3f", ""),
], doc="One body's bounds for pass P1, relative to the body's anchor (pycinder/passes/windows.py).")

WINDOW = Struct("PlanWindow", [
    ("axes", "array<vec4f, 3>", "rows: world directions of screen x, screen y and the view (xyz)"),
    ("origin", "vec3f", "world point at u = v = z = 0, relative to the anchor body's anchor"),
    ("pixel", "f32", "world size of one pixel (the pair's tolerance)"),
    ("slab", "vec2f", "depth range (z0, z1) of the overlap box, in pixels"),
    ("w", "u32", "window width in pixels (0 when apart; 2^32 - 1: too wide to count)"),
    ("h", "u32", "window height in pixels"),
    ("flags", "u32", "FLAG_* bits: count back, body a's and b's mirror and open bits"),
    ("anchor", "u32", "the body whose anchor the origin is relative to"),
    ("kept", "u32", "1: the pair's bounding volumes meet; 0: apart (no window)"),
    ("frame", "u32", "the frame the window was planned in: 0 world, 1 body a's, 2 body b's"),
], doc="One candidate pair's window, written by pass P1 (pycinder/passes/windows.py).")

PARAMS = Struct("PlanParams", [("count", "u32", "pairs of the dispatch")], uniform=True)

ANCHOR_BITS = 46
"""Bits of an anchor below its largest coordinate's power of two: an anchor is exactly the sum
of two float32 vectors (a float32 holds 24)."""

_U = wgpu.BufferUsage


def anchors(centres: np.ndarray) -> np.ndarray:
    """Each body's anchor: ``centres`` rounded to a multiple of ``2**(e - ANCHOR_BITS)``, where
    ``2**e`` is above the largest coordinate of the body's centre, so that it is the sum of two
    float32 vectors exactly (``hi = float32(anchor)``, ``lo = float32(anchor - hi)``).

    Parameters
    ----------
    centres : (N, 3) float64

    Returns
    -------
    (N, 3) float64
    """
    centres = np.asarray(centres, np.float64)
    _, e = np.frexp(np.abs(centres).max(axis=1) if len(centres) else np.zeros(0))
    step = np.ldexp(1.0, np.maximum(e, -80) - ANCHOR_BITS)[:, None]
    return np.round(centres / step) * step


def anchor_parts(anchor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Anchors (N, 3) of :func:`anchors` as the GPU takes them: ``hi = float32(anchor)`` and
    ``lo = anchor - hi`` (N, 3) float32, whose sum is the anchor exactly (what passes P1 and P3
    both take the offset between two anchors from)."""
    hi = np.asarray(anchor, np.float64).astype(np.float32)
    return hi, (anchor - hi).astype(np.float32)


def plan_bodies(local_lo: np.ndarray, local_hi: np.ndarray, world_lo: np.ndarray,
                world_hi: np.ndarray, transforms: np.ndarray, bounds: BodyBounds
                ) -> tuple[np.ndarray, np.ndarray]:
    """Every body's :data:`BODY`, relative to its anchor (see the module's docstring).

    The boxes' centres are measured from the anchor in float64 from the inputs themselves
    (the translation less the anchor, plus the linear part's share; the world box's bounds less
    the anchor), so that they do not round at the anchor's distance from the world's origin.

    Parameters
    ----------
    local_lo, local_hi : (N, 3) float
        Body-space bounding boxes.
    world_lo, world_hi : (N, 3) float
        World bounding boxes.
    transforms : (N, 4, 4) float
        World-from-body matrices.
    bounds : BodyBounds
        Their bounds, from :func:`pycinder.focused.plan.hostwindows.body_bounds`.

    Returns
    -------
    bodies : (N,) structured array of :data:`BODY`
    anchor : (N, 3) float64
        Each body's anchor (what the windows' origins are relative to).
    """
    n = len(bounds.obb_centre)
    anchor = anchors(bounds.obb_centre)
    out = BODY.zeros(n)
    out["hi"], out["lo"] = anchor_parts(anchor)
    out["size"] = bounds.aabb_half.sum(axis=1)
    out["flags_a"] = bounds.flags[0]
    out["flags_b"] = bounds.flags[1]
    transforms = np.asarray(transforms, np.float64)
    local = 0.5 * (np.asarray(local_lo, np.float64) + np.asarray(local_hi, np.float64))
    centre = np.einsum("nij,nj->ni", transforms[:, :3, :3], local) \
        + (transforms[:, :3, 3] - anchor)
    aabb_centre = 0.5 * ((np.asarray(world_lo, np.float64) - anchor)
                         + (np.asarray(world_hi, np.float64) - anchor))
    obb_m = bounds.obb_axes                              # (N, 3, 3): columns are half axes
    frames = bounds.frames                               # (N, 3, 3): rows are axes
    out["centre"] = centre
    out["half_axes"][:, :, :3] = np.transpose(obb_m, (0, 2, 1))
    out["frame"][:, :, :3] = frames
    out["aabb_centre"] = aabb_centre
    out["aabb_half"] = bounds.aabb_half
    # Where both boxes hold, along the world's axes and the frame's (as body_bounds finds
    # them, measured from the anchor).
    world = interval_meet((centre, sum3(np.abs(obb_m))), (aabb_centre, bounds.aabb_half))
    out["world_lo"], out["world_hi"] = world[:, 0], world[:, 1]
    h1 = sum3(np.abs(frames @ obb_m))
    own = interval_meet((np.einsum("nij,nj->ni", frames, centre), h1),
                (np.einsum("nij,nj->ni", frames, aabb_centre),
                 np.einsum("nij,nj->ni", np.abs(frames), bounds.aabb_half)))
    out["own_lo"], out["own_hi"] = own[:, 0], own[:, 1]
    return out, anchor


class GpuWindows:
    """P1: one invocation per candidate pair, the pair's window (:data:`WINDOW`).

    The pipeline and buffers are made once; buffers grow when a call needs more and are reused.

    Parameters
    ----------
    gpu : Gpu, optional
        The device (default: pycinder's).
    timeout : float
        Seconds a readback may wait for the GPU.
    workgroup : int
        Invocations (pairs) per workgroup.
    """

    INFO: ClassVar[PassInfo] = PassInfo(
        "P1", "windows", "each candidate pair's window: whether its bounding volumes meet, the "
        "frame of the smallest window, its view axes, size, origin and depth slab",
        when="when tiles are planned on the GPU")
    SHADER, ENTRY = "plan_windows", "plan_windows"

    def __init__(self, gpu: Gpu | None = None, timeout: float = DEFAULT_TIMEOUT, *,
                 workgroup: int = WORKGROUP) -> None:
        self.gpu = gpu = gpu or get_gpu()
        self.timeout = float(timeout)
        self.workgroup = int(workgroup)
        consts = {"WORKGROUP": self.workgroup, "ROW": ROW, "MARGIN_PX": MARGIN_PX,
                  "FLAG_COUNT_BACK": FLAG_COUNT_BACK, "COS_TILT": float(np.float32(np.cos(TILT))),
                  "SIN_TILT": float(np.float32(np.sin(TILT))), "PROBE_FACES": PROBE_FACES}
        self.stage = Stage(gpu, self.SHADER, self.ENTRY, label=self.INFO.title,
                           structs=(BODY, WINDOW, PARAMS, ATLAS_WINDOW), consts=consts)
        device = gpu.device

        def grow(label: str, usage: int = _U.STORAGE | _U.COPY_DST) -> GrowableBuffer:
            return GrowableBuffer(device, f"{self.INFO.name} {label}", usage)

        self.bodies = grow("bodies")
        self.pairs, self.tolerance = grow("pairs"), grow("tolerances")
        self.windows = grow("windows", _U.STORAGE | _U.COPY_SRC)
        self.faces = grow("faces")
        self.atlas = grow("atlas windows", _U.STORAGE)
        self.params = device.create_buffer(label=f"{self.INFO.name} parameters", size=16,
                                           usage=_U.UNIFORM | _U.COPY_DST)
        self.readback = Readback(device, f"{self.INFO.name} readback")
        self.anchor = np.zeros((0, 3))
        """(N, 3) float64: the anchors of the bodies uploaded last (see :func:`plan_bodies`)."""

    @property
    def buffer(self) -> GrowableBuffer:
        """The windows, one :data:`WINDOW` per pair of the last :meth:`encode` (the buffer may
        be replaced when an encode needs more room: bind it after encoding)."""
        return self.windows

    def upload_bodies(self, local_lo: np.ndarray, local_hi: np.ndarray, world_lo: np.ndarray,
                      world_hi: np.ndarray, transforms: np.ndarray,
                      open_bodies: np.ndarray | None = None, *,
                      bounds: BodyBounds | None = None,
                      faces: np.ndarray | None = None) -> BodyBounds:
        """Upload every body's bounds (:func:`plan_bodies`), relative to its anchor.

        Parameters
        ----------
        local_lo, local_hi : (N, 3) float
            Body-space bounding boxes.
        world_lo, world_hi : (N, 3) float
            World bounding boxes.
        transforms : (N, 4, 4) float
            World-from-body matrices.
        open_bodies : (N,) bool, optional
            Bodies that are not solids.
        bounds : BodyBounds, optional
            :func:`pycinder.focused.plan.hostwindows.body_bounds` of the same arguments, when the
            caller has it.
        faces : (N,) int, optional
            Faces of each body: a pair is dense (its large window is probed in a plan of any size)
            when its bodies have :data:`~pycinder.focused.plan.tiles.PROBE_FACES` or more together.
            Default: none is (pass P2 is then told that every pair is).

        Returns
        -------
        BodyBounds
            ``bounds``, or the bounds computed.
        """
        if bounds is None:
            bounds = body_bounds(local_lo, local_hi, world_lo, world_hi, transforms,
                                  open_bodies)
        bodies, self.anchor = plan_bodies(local_lo, local_hi, world_lo, world_hi, transforms,
                                          bounds)
        self.bodies.ensure(max(bodies.nbytes, BODY.size))
        self.bodies.write(bodies)
        counts = np.zeros(len(bodies), np.uint32) if faces is None else \
            np.minimum(np.asarray(faces), PROBE_FACES).astype(np.uint32)
        self.faces.ensure(max(counts.nbytes, 4))
        self.faces.write(counts)
        return bounds

    def upload_pairs(self, pairs: np.ndarray, tolerance: np.ndarray) -> None:
        """Upload candidate pairs and their tolerances to this pass's own buffers.

        Parameters
        ----------
        pairs : (K, 2) int
            Bodies of each pair, indices into the bodies uploaded last.
        tolerance : (K,) float
            Each pair's tolerance (its pixel size), positive.
        """
        pairs = np.asarray(pairs)
        if len(pairs) and (pairs.min() < 0 or pairs.max() >= len(self.anchor)):
            raise ValueError(f"pairs name bodies outside 0..{len(self.anchor) - 1}")
        data = np.ascontiguousarray(pairs, np.uint32)
        self.pairs.ensure(max(data.nbytes, 8))
        self.pairs.write(data)
        tol = np.ascontiguousarray(tolerance, np.float32)
        self.tolerance.ensure(max(tol.nbytes, 4))
        self.tolerance.write(tol)

    def encode(self, encoder: wgpu.GPUCommandEncoder, count: int, *,
               pairs: Resource | None = None, tolerance: Resource | None = None) -> None:
        """Record the pass into ``encoder``: the windows of ``count`` pairs into :attr:`buffer`,
        and what pass P2 reads of them into :attr:`atlas` (a :data:`~.atlasplan.WINDOW` each).

        The count is written to the pass's parameters at once (``queue.write_buffer``), so one
        submission holds at most one encode of this pass.

        Parameters
        ----------
        encoder : wgpu.GPUCommandEncoder
        count : int
            Pairs to plan.
        pairs : GrowableBuffer or wgpu.GPUBuffer, optional
            ``count`` pairs as ``vec2u`` (default: this pass's, from :meth:`upload_pairs`).
        tolerance : GrowableBuffer or wgpu.GPUBuffer, optional
            ``count`` tolerances as ``f32`` (default: this pass's).
        """
        count = int(count)
        self.windows.ensure(max(count, 1) * WINDOW.size)
        self.atlas.ensure(max(count, 1) * ATLAS_WINDOW.size)
        if count == 0:
            return
        params = PARAMS.zeros()
        params["count"] = count
        self.gpu.device.queue.write_buffer(self.params, 0, params)
        group = self.stage.group(bodies=self.bodies,
                                 pairs=self.pairs if pairs is None else pairs,
                                 tolerance=self.tolerance if tolerance is None else tolerance,
                                 windows=self.windows, params=(self.params, 0, 16),
                                 faces=self.faces, atlas=self.atlas)
        cpass = encoder.begin_compute_pass(label=self.INFO.title)
        dispatch(cpass, self.stage, group, -(-count // self.workgroup))
        cpass.end()

    def windows_of(self, pairs: np.ndarray, tolerance: np.ndarray) -> np.ndarray:
        """Plan the windows of ``pairs`` of the bodies uploaded last, and read them back raw.

        Parameters
        ----------
        pairs : (K, 2) int
        tolerance : (K,) float

        Returns
        -------
        (K,) structured array of :data:`WINDOW`
        """
        self.upload_pairs(pairs, tolerance)
        k = len(pairs)
        if k == 0:
            return WINDOW.zeros(0)
        encoder = native.encoder(self.gpu.device, self.INFO.title)
        self.encode(encoder, k)
        nbytes = k * WINDOW.size
        staging = self.readback.ensure(nbytes)
        encoder.copy_buffer_to_buffer(self.windows.buffer, 0, staging, 0, nbytes)
        self.gpu.device.queue.submit([encoder.finish()])
        data = self.readback.read(nbytes, np.uint8, timeout=self.timeout,
                                  waiting_for=f"the windows of {k} pairs")
        return data.view(WINDOW.dtype)

    def to_plan(self, raw: np.ndarray, pairs: np.ndarray, tolerance: np.ndarray, first: int = 0
                ) -> dict | None:
        """The kept windows of ``raw`` as :func:`pycinder.focused.plan.hostwindows._plan_chunk`
        returns them.

        Parameters
        ----------
        raw : (K,) structured array of :data:`WINDOW`
            Windows of ``pairs``, planned against the bodies uploaded last.
        pairs : (K, 2) int
        tolerance : (K,) float
        first : int
            Index of ``pairs[0]`` in the plan.

        Returns
        -------
        dict or None
            ``pair`` (m,) int64, ``bodies`` (m, 2), ``axes`` (m, 3, 3) float64, ``origin``
            (m, 3) float64 (world), ``pixel`` (m,) float64, ``w`` and ``h`` (m,) float64,
            ``slab`` (m, 2) float64 and ``flags`` (m,) int64, for the kept pairs in pair order;
            None when every pair is apart.
        """
        idx = np.flatnonzero(raw["kept"])
        if len(idx) == 0:
            return None
        r = raw[idx]
        origin = self.anchor[r["anchor"]] + r["origin"].astype(np.float64)
        return {
            "pair": idx + first, "bodies": np.take(pairs, idx, axis=0),
            "axes": r["axes"][:, :, :3].astype(np.float64), "origin": origin,
            "pixel": np.take(np.asarray(tolerance, np.float64), idx),
            "w": r["w"].astype(np.float64), "h": r["h"].astype(np.float64),
            "slab": r["slab"].astype(np.float64), "flags": r["flags"].astype(np.int64),
        }

    def run(self, pairs: np.ndarray, tolerance: np.ndarray, local_lo: np.ndarray,
            local_hi: np.ndarray, world_lo: np.ndarray, world_hi: np.ndarray,
            transforms: np.ndarray, open_bodies: np.ndarray | None = None) -> dict | None:
        """The windows of ``pairs``, as :func:`pycinder.focused.plan.hostwindows._plan_chunk`
        returns them (one upload, one submission, one readback).

        Parameters
        ----------
        pairs : (K, 2) int
            Candidate pairs.
        tolerance : (K,) float
            Each pair's tolerance (its pixel size).
        local_lo, local_hi : (N, 3) float
            Body-space bounding boxes.
        world_lo, world_hi : (N, 3) float
            World bounding boxes.
        transforms : (N, 4, 4) float
            World-from-body matrices.
        open_bodies : (N,) bool, optional
            Bodies that are not solids.

        Returns
        -------
        dict or None
            See :meth:`to_plan`.
        """
        self.upload_bodies(local_lo, local_hi, world_lo, world_hi, transforms, open_bodies)
        return self.to_plan(self.windows_of(pairs, tolerance), pairs, tolerance)


__all__ = ["ANCHOR_BITS", "BODY", "PARAMS", "WINDOW", "GpuWindows", "anchor_parts", "anchors",
           "plan_bodies"]

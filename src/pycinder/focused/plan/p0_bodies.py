"""Pass P0 of the GPU tile planner, bodies: every body's bounds as pass P1 reads them
(:data:`BODY`), computed on the GPU from the body's pose and boxes (``plan_bodies.wgsl``).

The host uploads, per body, what only float64 can give (O(N) NumPy, no decomposition):

- its *pose* (:data:`POSE`): the linear part ``R`` rounded to float32, its anchor as ``hi + lo``
  (see below) and its translation less its anchor, ``t - A``, computed in float64 and rounded once
  (pass P3 reads the same buffer);
- its *extent* (:data:`EXTENT`): the oriented box's centre and the world box's centre less the
  anchor (float64, rounded once), the world box's and the body-space box's half extents, and
  whether the body is open and whether its transform mirrors it (the sign of the float64
  determinant: in float32 a body flattened or scaled far down would lose it).

One invocation per body then finds what :func:`plan_bodies` (its float64 reference) finds: the
oriented box's half axes ``R[:, c] * half[c]``, the body's frame, where both boxes hold along the
world's axes and along the frame's, the size that picks a pair's anchor body, and the mirror and
open flags.

The frame is the Q of the QR decomposition of ``R`` as NumPy's ``qr`` makes it with the LAPACK
of NumPy's wheels (reference LAPACK's Householder reflections, ``dgeqr2`` and ``dorg2r``, as
OpenBLAS ships them; another LAPACK may choose other signs), its last axis negated where Q is not
proper: :func:`pycinder.focused.plan.plan_numpy_windows._qr_frames`. The shader follows those steps
with their sign conventions: a column whose part below the diagonal is exactly zero is not
reflected, however small the rest; norms are scaled first, so that elements far below 1 (a quarter
turn's ``6e-17``, and its products) neither underflow nor vanish; a zero diagonal element reflects
as a positive one. The host's reference makes every ``-0.0``, and every element below float32's
smallest normal number, ``+0.0`` before decomposing, and the shader takes those elements as
zeros too, so the two planners look along the same axes, not along axes that differ in sign:
bodies turned by quarter and half turns built from ``np.pi`` included. A sign is decided
differently only where the reflected second column's diagonal element, or an element below it,
rounds to zero or to either sign in one precision only: then the two planners' frames differ in
an axis's sign, each a valid frame of the body.

Anchors
-------
WGSL has no float64, and a scene may lie far from the world's origin, or hold a tiny body inside
a huge one. So nothing is measured from the world's origin on the GPU: every body is measured from
its *anchor*, its oriented box's centre rounded to a multiple of ``2**(e - 46)`` (where ``max |c|
< 2**e``), so that the anchor is exactly ``hi + lo`` of two float32 vectors (:func:`anchors`).
The centres uploaded are measured from it in float64 from the inputs themselves (the translation
less the anchor, plus the linear part's share; the world box's bounds less the anchor), so that
they do not round at the anchor's distance from the world's origin. Pass P1 moves a pair's second
body by the offset between the two anchors (:mod:`pycinder.focused.plan.p1_windows`).

Error bound, against :func:`plan_bodies` (float64, then rounded to float32): the frame's axes
and the half axes within a few ``2**-24`` of their size (``R`` rounded once, then a few products
and sums per element, and the reflections' square roots); the intervals within a few ``2**-24``
of the body's own extent from its anchor. Measured in ``tests/focused/plan/test_p0_bodies.py``.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import wgpu

from ...gpu.bindings import Resource, Stage, dispatch
from ...gpu import native
from ...gpu.buffers import DEFAULT_TIMEOUT, GrowableBuffer, Readback
from ...gpu.device import Gpu, get_gpu
from ...gpu.layout import FLAG_MIRROR, FLAG_OPEN, ROW, WORKGROUP
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from ...util.arrays import sum3
from .plan_numpy_windows import TINY, BodyBounds, interval_meet, mirrors

POSE = Struct("BodyPose", [
    ("rows", "array<vec4f, 3>", "world-from-body rows: R's row i (xyz), (t - anchor)_i (w)"),
    ("hi", "vec3f", "the body's anchor, high part: f32(anchor)"),
    ("pad0", "u32", ""),
    ("lo", "vec3f", "the anchor's low part: anchor - hi (exact)"),
    ("pad1", "u32", ""),
], doc="One body's transform, its translation relative to its anchor (passes P0 and P3, "
       "pycinder/focused/plan/p0_bodies.py).")

EXTENT_OPEN, EXTENT_MIRRORED = 1, 2
"""Bits of :data:`EXTENT`'s ``flags``: the body is not a solid; its transform mirrors it (the
sign of its float64 determinant, :func:`~pycinder.focused.plan.plan_numpy_windows.mirrors`: float32
would lose it for a body flattened or scaled far down)."""

EXTENT = Struct("BodyExtent", [
    ("centre", "vec3f", "the oriented box's centre - anchor (float64 on the host)"),
    ("flags", "u32", "EXTENT_OPEN | EXTENT_MIRRORED bits"),
    ("aabb_centre", "vec3f", "the world box's centre - anchor (float64 on the host)"),
    ("pad0", "u32", ""),
    ("aabb_half", "vec3f", "the world box's half extents"),
    ("pad1", "u32", ""),
    ("half", "vec3f", "the body-space box's half extents"),
    ("pad2", "u32", ""),
], doc="One body's boxes, relative to its anchor, for pass P0 (focused/plan/p0_bodies.py).")

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
], doc="One body's bounds for pass P1, relative to the body's anchor, written by pass P0 "
       "(pycinder/focused/plan/p0_bodies.py).")

PARAMS = Struct("PlanParams", [
    ("count", "u32", "candidate pairs of pass P1's dispatch"),
    ("bodies", "u32", "bodies of pass P0's dispatch"),
], uniform=True, doc="The parameters passes P0 and P1 share (one write a plan).")

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
    size = np.abs(centres)
    _, e = np.frexp(np.maximum(np.maximum(size[:, 0], size[:, 1]), size[:, 2]))
    step = np.ldexp(1.0, np.maximum(e, -80) - ANCHOR_BITS)[:, None]
    return np.round(centres / step) * step


def anchor_parts(anchor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Anchors (N, 3) of :func:`anchors` as the GPU takes them: ``hi = float32(anchor)`` and
    ``lo = anchor - hi`` (N, 3) float32, whose sum is the anchor exactly (what passes P1 and P3
    both take the offset between two anchors from)."""
    hi = np.asarray(anchor, np.float64).astype(np.float32)
    return hi, (anchor - hi).astype(np.float32)


def body_poses(transforms: np.ndarray, anchor: np.ndarray) -> np.ndarray:
    """Every body's :data:`POSE`: its linear part, its anchor as ``hi + lo`` and its translation
    less its anchor (float64, rounded to float32 once).

    Parameters
    ----------
    transforms : (N, 4, 4) float
        World-from-body matrices.
    anchor : (N, 3) float64
        Each body's anchor (:func:`anchors`): each exactly the sum of two float32 vectors.

    Returns
    -------
    (N,) structured array of :data:`POSE`
    """
    transforms = np.asarray(transforms, np.float64)
    anchor = np.asarray(anchor, np.float64)
    n = len(transforms)
    if transforms.shape != (n, 4, 4) or anchor.shape != (n, 3):
        raise ValueError(f"transforms {transforms.shape} and anchors {anchor.shape} do not "
                         "match: (N, 4, 4) and (N, 3)")
    return _poses(transforms, transforms[:, :3, 3] - anchor, anchor)


def _poses(transforms: np.ndarray, offset: np.ndarray, anchor: np.ndarray) -> np.ndarray:
    out = POSE.zeros(len(transforms))
    out["rows"][:, :, :3] = transforms[:, :3, :3]
    out["rows"][:, :, 3] = offset
    out["hi"], out["lo"] = anchor_parts(anchor)
    return out


def body_inputs(local_lo: np.ndarray, local_hi: np.ndarray, world_lo: np.ndarray,
                world_hi: np.ndarray, transforms: np.ndarray,
                open_bodies: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the host uploads for pass P0: every body's pose and extent, relative to its anchor
    (see the module's docstring).

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

    Returns
    -------
    poses : (N,) structured array of :data:`POSE`
    extents : (N,) structured array of :data:`EXTENT`
    anchor : (N, 3) float64
        Each body's anchor (what the windows' origins are relative to).
    """
    transforms = np.asarray(transforms, np.float64)
    local_lo = np.asarray(local_lo, np.float64)
    local_hi = np.asarray(local_hi, np.float64)
    world_lo = np.asarray(world_lo, np.float64)
    world_hi = np.asarray(world_hi, np.float64)
    share = np.einsum("nij,nj->ni", transforms[:, :3, :3], 0.5 * (local_lo + local_hi))
    translation = transforms[:, :3, 3]
    anchor = anchors(share + translation)
    offset = translation - anchor
    extents = EXTENT.zeros(len(transforms))
    extents["centre"] = share + offset
    extents["aabb_centre"] = 0.5 * ((world_lo - anchor) + (world_hi - anchor))
    extents["aabb_half"] = 0.5 * (world_hi - world_lo)
    extents["half"] = 0.5 * (local_hi - local_lo)
    flags = np.where(mirrors(transforms[:, :3, :3]), EXTENT_MIRRORED, 0)
    if open_bodies is not None:
        flags |= np.where(np.asarray(open_bodies, bool), EXTENT_OPEN, 0)
    extents["flags"] = flags
    return _poses(transforms, offset, anchor), extents, anchor


def plan_bodies(local_lo: np.ndarray, local_hi: np.ndarray, world_lo: np.ndarray,
                world_hi: np.ndarray, transforms: np.ndarray, bounds: BodyBounds
                ) -> tuple[np.ndarray, np.ndarray]:
    """Every body's :data:`BODY`, relative to its anchor, in float64 on the host: what pass P0
    computes, from :func:`pycinder.focused.plan.plan_numpy_windows.body_bounds` (the tests'
    reference).

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
        Their bounds, from :func:`pycinder.focused.plan.plan_numpy_windows.body_bounds`.

    Returns
    -------
    bodies : (N,) structured array of :data:`BODY`
    anchor : (N, 3) float64
        Each body's anchor (what the windows' origins are relative to).
    """
    # The anchors and the centres measured from them: the very float64 values P0 is given.
    _, extents, anchor = body_inputs(local_lo, local_hi, world_lo, world_hi, transforms)
    centre = extents["centre"].astype(np.float64)
    aabb_centre = extents["aabb_centre"].astype(np.float64)
    out = BODY.zeros(len(anchor))
    out["hi"], out["lo"] = anchor_parts(anchor)
    out["size"] = bounds.aabb_half.sum(axis=1)
    out["flags_a"] = bounds.flags[0]
    out["flags_b"] = bounds.flags[1]
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


class GpuBodies:
    """P0: one invocation per body, the body's :data:`BODY` from its pose and extent.

    The pipeline and buffers are made once; buffers grow when an upload needs more and are
    reused.

    Parameters
    ----------
    gpu : Gpu, optional
        The device (default: pycinder's).
    timeout : float
        Seconds a readback (:meth:`read`) may wait for the GPU.
    workgroup : int
        Invocations (bodies) per workgroup.
    """

    INFO: ClassVar[PassInfo] = PassInfo(
        "P0", "bodies", "each body's bounds relative to its anchor: its oriented box's half "
        "axes, its frame (the Q of its linear part), where its boxes hold along the world's axes "
        "and its own", when="when tiles are planned on the GPU")
    SHADER, ENTRY = "plan_bodies", "plan_bodies"

    def __init__(self, gpu: Gpu | None = None, timeout: float = DEFAULT_TIMEOUT, *,
                 workgroup: int = WORKGROUP) -> None:
        self.gpu = gpu = gpu or get_gpu()
        self.timeout = float(timeout)
        self.workgroup = int(workgroup)
        consts = {"WORKGROUP": self.workgroup, "ROW": ROW,
                  "FLAG_MIRROR_A": FLAG_MIRROR[0], "FLAG_MIRROR_B": FLAG_MIRROR[1],
                  "FLAG_OPEN_A": FLAG_OPEN[0], "FLAG_OPEN_B": FLAG_OPEN[1],
                  "EXTENT_OPEN": EXTENT_OPEN, "EXTENT_MIRRORED": EXTENT_MIRRORED,
                  "MIN_NORMAL": TINY}
        self.stage = Stage(gpu, self.SHADER, self.ENTRY, label=self.INFO.title,
                           structs=(POSE, EXTENT, BODY, PARAMS), consts=consts)
        device = gpu.device

        def grow(label: str, usage: int = _U.STORAGE | _U.COPY_DST) -> GrowableBuffer:
            return GrowableBuffer(device, f"{self.INFO.name} {label}", usage)

        self.poses = grow("poses")
        """The bodies' :data:`POSE` records (pass P3 reads them too)."""
        self.extents = grow("extents")
        self.bodies = grow("bodies", _U.STORAGE | _U.COPY_SRC)
        """The bodies' :data:`BODY` records, written by :meth:`encode` (bind after encoding)."""
        self.params = device.create_buffer(label=f"{self.INFO.name} parameters", size=16,
                                           usage=_U.UNIFORM | _U.COPY_DST)
        """The pass's own :data:`PARAMS`, for :meth:`read` (pass P1 binds its own block, which
        it writes with its pairs)."""
        self.readback = Readback(device, f"{self.INFO.name} readback")
        self.anchor = np.zeros((0, 3))
        """(N, 3) float64: the anchors of the bodies uploaded last."""

    @property
    def count(self) -> int:
        """Bodies uploaded last."""
        return len(self.anchor)

    def upload(self, local_lo: np.ndarray, local_hi: np.ndarray, world_lo: np.ndarray,
               world_hi: np.ndarray, transforms: np.ndarray,
               open_bodies: np.ndarray | None = None) -> np.ndarray:
        """Upload every body's pose and extent (:func:`body_inputs`).

        Parameters
        ----------
        local_lo, local_hi, world_lo, world_hi : (N, 3) float
        transforms : (N, 4, 4) float
        open_bodies : (N,) bool, optional

        Returns
        -------
        (N, 3) float64
            The bodies' anchors (also :attr:`anchor`).
        """
        poses, extents, self.anchor = body_inputs(local_lo, local_hi, world_lo, world_hi,
                                                  transforms, open_bodies)
        n = len(poses)
        self.poses.ensure(max(poses.nbytes, POSE.size))
        self.poses.write(poses)
        self.extents.ensure(max(extents.nbytes, EXTENT.size))
        self.extents.write(extents)
        self.bodies.ensure(max(n, 1) * BODY.size)
        return self.anchor

    def encode(self, encoder: wgpu.GPUCommandEncoder, params: Resource) -> None:
        """Record the pass into ``encoder``: the :data:`BODY` of every body uploaded last into
        :attr:`bodies` (nothing when none was).

        Parameters
        ----------
        encoder : wgpu.GPUCommandEncoder
        params : wgpu.GPUBuffer or (buffer, offset, size)
            A :data:`PARAMS` block whose ``bodies`` is :attr:`count` by the time the encoder's
            commands run (pass P1's, written with its pairs).
        """
        n = self.count
        if n == 0:
            return
        group = self.stage.group(poses=self.poses, extents=self.extents, bodies=self.bodies,
                                 params=params)
        cpass = encoder.begin_compute_pass(label=self.INFO.title)
        dispatch(cpass, self.stage, group, -(-n // self.workgroup))
        cpass.end()

    def read(self) -> np.ndarray:
        """Run the pass over the bodies uploaded last and read their records back (one
        submission, one map).

        Returns
        -------
        (N,) structured array of :data:`BODY`
        """
        n = self.count
        if n == 0:
            return BODY.zeros(0)
        nbytes = n * BODY.size
        staging = self.readback.ensure(nbytes)
        params = PARAMS.zeros()
        params["bodies"] = n
        self.gpu.device.queue.write_buffer(self.params, 0, params)
        encoder = native.encoder(self.gpu.device, self.INFO.title)
        self.encode(encoder, (self.params, 0, 16))
        encoder.copy_buffer_to_buffer(self.bodies.buffer, 0, staging, 0, nbytes)
        self.gpu.device.queue.submit([encoder.finish()])
        data = self.readback.read(nbytes, np.uint8, timeout=self.timeout,
                                  waiting_for=f"the bounds of {n} bodies")
        return data.view(BODY.dtype)


__all__ = ["ANCHOR_BITS", "BODY", "EXTENT", "PARAMS", "POSE", "GpuBodies", "anchor_parts",
           "anchors", "body_inputs", "body_poses", "plan_bodies"]

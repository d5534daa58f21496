"""Pass P1 of the GPU tile planner, windows: each candidate pair's window, as
:func:`pycinder.focused.plan.plan_numpy_windows._plan_chunk` plans it, in single precision
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

- Every body's bounds come from pass P0 (:mod:`pycinder.focused.plan.p0_bodies`), relative to the
  body's own *anchor* (a point at its oriented box's centre, exactly ``hi + lo`` of two float32
  vectors): its boxes' centres (computed on the host in float64 and rounded once), its intervals
  along the world's axes and its own frame's, its half axes and frame (:data:`BODY`).
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
origin (1e-3 at 1e13). Measured against it (``tests/focused/plan/test_p1_windows.py``), the origin
and slab are within 1e-4 pixel and the axes within 1e-7 where its choices are clear. Where the
float64 and the float32 planner round a close decision differently (a frame's area, the order of
equal extents, a pair whose boxes just touch, an extent of almost a whole number of pixels, the
count side of a pair as deep in front as behind), the two plans differ there, each a valid window of
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
from .p2_atlas import WINDOW as ATLAS_WINDOW
from .p0_bodies import ANCHOR_BITS, BODY, PARAMS, GpuBodies, anchor_parts, anchors
from .plan_numpy_windows import MARGIN_PX, TILT
from .plan_numpy import PROBE_FACES

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


_U = wgpu.BufferUsage


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

        self.p0 = GpuBodies(gpu, timeout, workgroup=workgroup)
        """Pass P0, whose bodies this pass reads (encoded before it by :meth:`encode`)."""
        self.pairs, self.pair_tolerances = grow("pairs"), grow("tolerances")
        self.windows = grow("windows", _U.STORAGE | _U.COPY_SRC)
        self.faces = grow("faces")
        self.atlas = grow("atlas windows", _U.STORAGE)
        self.params = device.create_buffer(label=f"{self.INFO.name} parameters", size=16,
                                           usage=_U.UNIFORM | _U.COPY_DST)
        self.readback = Readback(device, f"{self.INFO.name} readback")

    @property
    def anchor(self) -> np.ndarray:
        """(N, 3) float64: the anchors of the bodies uploaded last (pass P0's,
        :func:`~pycinder.focused.plan.p0_bodies.anchors`)."""
        return self.p0.anchor

    @property
    def poses(self) -> GrowableBuffer:
        """The :data:`~pycinder.focused.plan.p0_bodies.POSE` of every body uploaded last (what
        pass P3 reads)."""
        return self.p0.poses

    @property
    def buffer(self) -> GrowableBuffer:
        """The windows, one :data:`WINDOW` per pair of the last :meth:`encode` (the buffer may
        be replaced when an encode needs more room: bind it after encoding)."""
        return self.windows

    def upload_bodies(self, local_lo: np.ndarray, local_hi: np.ndarray, world_lo: np.ndarray,
                      world_hi: np.ndarray, transforms: np.ndarray,
                      open_bodies: np.ndarray | None = None, *,
                      faces: np.ndarray | None = None) -> np.ndarray:
        """Upload every body's pose and boxes for pass P0 (which :meth:`encode` runs before this
        pass), relative to its anchor, and its faces.

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
        faces : (N,) int, optional
            Faces of each body: a pair is dense (its large window is probed in a plan of any size)
            when its bodies have :data:`~pycinder.focused.plan.plan_numpy.PROBE_FACES` or more
            together. Default: none is (pass P2 is then told that every pair is).

        Returns
        -------
        (N, 3) float64
            The bodies' anchors (:attr:`anchor`).
        """
        anchor = self.p0.upload(local_lo, local_hi, world_lo, world_hi, transforms, open_bodies)
        counts = np.zeros(len(anchor), np.uint32) if faces is None else \
            np.minimum(np.asarray(faces), PROBE_FACES).astype(np.uint32)
        self.faces.ensure(max(counts.nbytes, 4))
        self.faces.write(counts)
        return anchor

    def upload_pairs(self, pairs: np.ndarray, pair_tolerances: np.ndarray) -> None:
        """Upload candidate pairs and their tolerances to this pass's own buffers.

        Parameters
        ----------
        pairs : (K, 2) int
            Bodies of each pair, indices into the bodies uploaded last.
        pair_tolerances : (K,) float
            Each pair's tolerance (its pixel size), positive.
        """
        pairs = np.asarray(pairs)
        if len(pairs) and (pairs.min() < 0 or pairs.max() >= len(self.anchor)):
            raise ValueError(f"pairs name bodies outside 0..{len(self.anchor) - 1}")
        data = np.ascontiguousarray(pairs, np.uint32)
        self.pairs.ensure(max(data.nbytes, 8))
        self.pairs.write(data)
        tol = np.ascontiguousarray(pair_tolerances, np.float32)
        self.pair_tolerances.ensure(max(tol.nbytes, 4))
        self.pair_tolerances.write(tol)

    def encode(self, encoder: wgpu.GPUCommandEncoder, count: int, *,
               pairs: Resource | None = None, pair_tolerances: Resource | None = None) -> None:
        """Record pass P0 over the bodies uploaded last (:meth:`upload_bodies`), then this pass
        into ``encoder``: the windows of ``count`` pairs into :attr:`buffer`, and what pass P2
        reads of them into :attr:`atlas` (a :data:`~.atlasplan.WINDOW` each).

        The count is written to the pass's parameters at once (``queue.write_buffer``), so one
        submission holds at most one encode of this pass.

        Parameters
        ----------
        encoder : wgpu.GPUCommandEncoder
        count : int
            Pairs to plan.
        pairs : GrowableBuffer or wgpu.GPUBuffer, optional
            ``count`` pairs as ``vec2u`` (default: this pass's, from :meth:`upload_pairs`).
        pair_tolerances : GrowableBuffer or wgpu.GPUBuffer, optional
            ``count`` pair tolerances as ``f32`` (default: this pass's).
        """
        count = int(count)
        self.windows.ensure(max(count, 1) * WINDOW.size)
        self.atlas.ensure(max(count, 1) * ATLAS_WINDOW.size)
        if count == 0:
            return
        params = PARAMS.zeros()
        params["count"] = count
        params["bodies"] = self.p0.count
        self.gpu.device.queue.write_buffer(self.params, 0, params)
        self.p0.encode(encoder, (self.params, 0, 16))
        group = self.stage.group(bodies=self.p0.bodies,
                                 pairs=self.pairs if pairs is None else pairs,
                                 pair_tolerances=(self.pair_tolerances if pair_tolerances is None
                                                  else pair_tolerances),
                                 windows=self.windows, params=(self.params, 0, 16),
                                 faces=self.faces, atlas=self.atlas)
        cpass = encoder.begin_compute_pass(label=self.INFO.title)
        dispatch(cpass, self.stage, group, -(-count // self.workgroup))
        cpass.end()

    def windows_of(self, pairs: np.ndarray, pair_tolerances: np.ndarray) -> np.ndarray:
        """Plan the windows of ``pairs`` of the bodies uploaded last, and read them back raw.

        Parameters
        ----------
        pairs : (K, 2) int
        pair_tolerances : (K,) float

        Returns
        -------
        (K,) structured array of :data:`WINDOW`
        """
        self.upload_pairs(pairs, pair_tolerances)
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

    def to_plan(self, raw: np.ndarray, pairs: np.ndarray, pair_tolerances: np.ndarray,
                first: int = 0) -> dict | None:
        """The kept windows of ``raw`` as
        :func:`pycinder.focused.plan.plan_numpy_windows._plan_chunk` returns them.

        Parameters
        ----------
        raw : (K,) structured array of :data:`WINDOW`
            Windows of ``pairs``, planned against the bodies uploaded last.
        pairs : (K, 2) int
        pair_tolerances : (K,) float
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
            "pixel": np.take(np.asarray(pair_tolerances, np.float64), idx),
            "w": r["w"].astype(np.float64), "h": r["h"].astype(np.float64),
            "slab": r["slab"].astype(np.float64), "flags": r["flags"].astype(np.int64),
        }

    def run(self, pairs: np.ndarray, pair_tolerances: np.ndarray, local_lo: np.ndarray,
            local_hi: np.ndarray, world_lo: np.ndarray, world_hi: np.ndarray,
            transforms: np.ndarray, open_bodies: np.ndarray | None = None) -> dict | None:
        """The windows of ``pairs``, as :func:`pycinder.focused.plan.plan_numpy_windows._plan_chunk`
        returns them (one upload, one submission, one readback).

        Parameters
        ----------
        pairs : (K, 2) int
            Candidate pairs.
        pair_tolerances : (K,) float
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
        return self.to_plan(self.windows_of(pairs, pair_tolerances), pairs, pair_tolerances)


__all__ = ["ANCHOR_BITS", "BODY", "PARAMS", "WINDOW", "GpuWindows", "anchor_parts", "anchors"]

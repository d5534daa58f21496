"""Pass P3 of the GPU tile planner, tile words: every tile of the plan as the frame's passes read
it (:data:`pycinder.gpu.layout.TILE`), written on the GPU right after passes P1 and P2, in the same
submission (``plan_tile_words.wgsl``).

One invocation per tile record of pass P2 (:attr:`AtlasPlanner.tiles
<pycinder.focused.plan.p2_atlas.AtlasPlanner>`, dispatched over its ``capacity``; those past the
summary's ``tiles`` return at once) reads the tile's record, pass P1's window of its pair
(:data:`~pycinder.focused.plan.p1_windows.WINDOW`), the pair's bodies and each body's :data:`BODY`,
and writes what the host otherwise writes with ``tile_words(plan,
plan.tile_from_body(transforms))`` (:func:`pycinder.focused.frame.frameio.tile_words`,
:meth:`pycinder.focused.plan.plan_numpy.TilePlan.tile_from_body`):

- ``window``: the tile's (P2); ``slab``: its window's (P1), ``zw = 0``; ``bodies``: its pair's;
  ``flags``: the window's and the tile's; ``pair``: its candidate pair;
- ``m0``, ``m1``: body a's and body b's tile-from-body (3, 4) rows. With ``axes`` and ``pixel`` the
  window's, its origin ``o`` relative to the pair's anchor (the anchor of body ``window.anchor``,
  :mod:`pycinder.focused.plan.p0_bodies`), and the tile ``u``, ``v`` pixels from the
  window's corner (``u = (moved ? u0 : 0) + shift``, ``v = moved ? v0 : 0``, as
  :meth:`pycinder.focused.plan.plan_gpu.GpuPlanner._tiles` moves the origin), row ``i`` of a side
  with world-from-body ``(R, t)`` is ``axes[i] . R / pixel`` and, in its last column, ``axes[i] . (t
  - anchor - o) / pixel - u axes[i] . axes[0] - v axes[i] . axes[1]``.

Precision
---------
WGSL has no float64, and the tiles of a pair 1e13 from the world's origin must keep the
precision of the pair's own size. So nothing is measured from the world's origin on the GPU:

- The host (float64, O(N)) uploads each body's linear part ``R`` rounded to float32, its anchor
  (pass P0's: exactly ``hi + lo`` of two float32 vectors; the planner binds P0's poses, and a
  caller of this pass alone gives them to :meth:`TileWords.upload_bodies`), and its translation
  *less its anchor*, ``t - A``, computed in float64 (an exact
  difference wherever ``t`` is within a factor two of ``A``) and rounded to float32 once: an
  error of ``2**-24 |t - A|``, relative to how far the body's origin lies from its oriented box's
  centre, not from the world's.
- Per tile and side, the shader takes the side's origin from the pair's anchor as
  ``((hi_s - hi_p) + (lo_s - lo_p)) + (t - A_s)``: the anchors' offset ``d`` as pass P1 takes
  it (0 for the anchor body itself; the low parts' difference is exact for anchors whose largest
  coordinates are within a factor four of each other, both on grids of ``2**(e - 46)``; the high
  parts' difference is exact for coordinates within a factor two of each other and otherwise
  rounded relative to ``|d|``; so ``d`` is within a few ``2**-24 |d|``), then less the window's
  origin ``o`` (P1's float32, relative to the same anchor, the very value the host adds to its
  float64 anchor).
- The tile's place is subtracted in pixels: ``u axes[i] . axes[0] + v axes[i] . axes[1]``
  (``u``, ``v`` exact in float32), so ``u pixel`` is never formed in world units.

Error bound, against the float64 composition of the same window (its float32 ``axes``, ``o`` and
``pixel`` taken as exact), with ``eps = 2**-24``: the rotation rows are within about
``6 eps`` of their size ``|R| / pixel`` (``R`` and ``pixel`` rounded to float32 once, the
products, sums and the division once each); the last column, in pixels, within about
``5 eps (|d| + |t - A| + |o|) / pixel + 5 eps (u + v) + eps |m|``, where ``u``, ``v`` are the
tile's place in its window and ``m`` the value itself. Every term is the pair's own
extent (its anchors' offset, a body origin's offset from its box, the window's place and size)
in pixels, never its distance from the world's origin. The tolerance policy keeps those under
:data:`~pycinder.tolerance.MAX_PIXELS_ACROSS` (``2**20``) pixels, where the words' own float32
rounding is a sixteenth of a pixel; in ordinary scenes (windows up to a few thousand pixels) the
error is 1e-5 to 2e-4 pixel. The float64 host composition rounds at ``2**-53`` of the distance
from the origin instead (``TilePlan.origin`` is absolute): 1e-3 world units at 1e13, 2e-2 pixel
for pixels of 0.1 there.

Measured on lavapipe (``tests/focused/plan/test_p3_tile_words.py``: rotated, scaled, sheared and
mirrored bodies at 1e-3, 1 and 1e3 across, near the origin, at 1e7 and at 1e13): rotation rows
within 2.2e-7 of their size; the last column and the error at each tile's window's corners within
2e-5 pixel for windows of about a hundred pixels and 1.8e-4 pixel for windows of thousands, against
the float64 composition relative to each pair's anchor.

A plain ``hi + lo`` split of the translation itself would not do: two float32 hold 48 bits, so
``t`` would be off by up to ``2**-48 |t|`` and the difference of the two low parts rounded at
``2**-48`` of the distance from the origin: 0.08 pixel for bodies 10 across at 1e13 (pixels of
0.1), and a pixel or more where the tolerance policy lets a pixel be ``2**-48`` of that distance
(:data:`~pycinder.tolerance.MAX_PIXELS_FROM_ORIGIN`).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import wgpu

from ...gpu.bindings import Resource, Stage, dispatch
from ...gpu.buffers import DEFAULT_TIMEOUT, GrowableBuffer, Readback
from ...gpu import native
from ...gpu.device import Gpu, get_gpu
from ...gpu.layout import ROW, TILE, WORKGROUP
from ...gpu.table import PassInfo
from .p2_atlas import SUMMARY
from .p2_atlas import TILE as ATLAS_TILE
from .p0_bodies import POSE, body_poses
from .p1_windows import WINDOW

BODY = POSE
"""One body's transform for this pass, its translation relative to its anchor (pass P0's
:data:`~pycinder.focused.plan.p0_bodies.POSE`: the planner binds P0's buffer; this pass's own,
from :meth:`TileWords.upload_bodies`, serves a caller running it alone)."""

_U = wgpu.BufferUsage


tile_bodies = body_poses
"""Every body's :data:`BODY` (:func:`pycinder.focused.plan.p0_bodies.body_poses`)."""


class TileWords:
    """P3: one invocation per tile of pass P2's plan, its :data:`~pycinder.gpu.layout.TILE`.

    The pipeline and buffers are made once; buffers grow when a call needs more and are reused.
    Chain it after P1 and P2 in one encoder::

        p1.encode(encoder, k)
        p2.encode(encoder, p1.atlas, k, budget_pixels=...)
        p3.encode(encoder, windows=p1.buffer, pairs=p1.pairs, atlas_tiles=p2.tiles,
                  summary=p2.summary, capacity=p2.capacity, bodies=p1.poses)

    with the poses pass P0 uploaded with P1's bodies (or after :meth:`upload_bodies` with the
    transforms and P1's anchors).

    Parameters
    ----------
    gpu : Gpu, optional
        The device (default: pycinder's).
    timeout : float
        Seconds a readback (:meth:`read`) may wait for the GPU.
    workgroup : int
        Invocations (tiles) per workgroup.
    """

    INFO: ClassVar[PassInfo] = PassInfo(
        "P3", "tile words", "each planned tile as the frame's passes read it: its window, slab, "
        "flags and both bodies' tile-from-body matrices, relative to the pair's anchor",
        when="when tiles are planned on the GPU")
    SHADER, ENTRY = "plan_tile_words", "tile_words"

    def __init__(self, gpu: Gpu | None = None, timeout: float = DEFAULT_TIMEOUT, *,
                 workgroup: int = WORKGROUP) -> None:
        self.gpu = gpu = gpu or get_gpu()
        self.timeout = float(timeout)
        self.workgroup = int(workgroup)
        self.stage = Stage(gpu, self.SHADER, self.ENTRY, label=self.INFO.title,
                           structs=(POSE, WINDOW, ATLAS_TILE, SUMMARY, TILE),
                           consts={"WORKGROUP": self.workgroup, "ROW": ROW})
        device = gpu.device
        self.bodies = GrowableBuffer(device, f"{self.INFO.name} bodies", _U.STORAGE | _U.COPY_DST)
        self._tiles = GrowableBuffer(device, f"{self.INFO.name} tiles", _U.STORAGE | _U.COPY_SRC)
        self.readback = Readback(device, f"{self.INFO.name} readback")
        self.count = 0
        """Bodies uploaded last."""

    @property
    def tiles(self) -> GrowableBuffer:
        """The tiles, ``capacity`` :data:`~pycinder.gpu.layout.TILE` records of the last
        :meth:`encode`, the first ``summary.tiles`` of them valid (usage STORAGE | COPY_SRC; the
        buffer may be replaced when an encode needs more room: bind or copy it after
        encoding)."""
        return self._tiles

    def upload_bodies(self, transforms: np.ndarray, anchor: np.ndarray) -> None:
        """Upload every body's :data:`BODY` (:func:`tile_bodies`).

        Parameters
        ----------
        transforms : (N, 4, 4) float64
            World-from-body matrices, those pass P1 planned with.
        anchor : (N, 3) float64
            The anchors pass P1 uploaded with them (:attr:`GpuWindows.anchor
            <pycinder.focused.plan.p1_windows.GpuWindows>`), which its windows' origins are relative
            to.
        """
        bodies = tile_bodies(transforms, anchor)
        self.bodies.ensure(max(bodies.nbytes, BODY.size))
        self.bodies.write(bodies)
        self.count = len(bodies)

    def encode(self, encoder: wgpu.GPUCommandEncoder, *, windows: Resource, pairs: Resource,
               atlas_tiles: Resource, summary: Resource, capacity: int,
               bodies: Resource | None = None) -> None:
        """Record the pass into ``encoder`` (after passes P1 and P2 in the same encoder, or with
        their buffers written earlier): the tiles of P2's plan into :attr:`tiles`.

        Nothing is written to the queue: the pass may be encoded any number of times in one
        submission.

        Parameters
        ----------
        encoder : wgpu.GPUCommandEncoder
        windows : GrowableBuffer or wgpu.GPUBuffer
            Pass P1's windows (:attr:`GpuWindows.buffer
            <pycinder.focused.plan.p1_windows.GpuWindows>`), one
            :data:`~pycinder.focused.plan.p1_windows.WINDOW` per candidate pair.
        pairs : GrowableBuffer or wgpu.GPUBuffer
            The candidate pairs P1 planned, ``vec2u`` (:attr:`GpuWindows.pairs`), indices into
            the bodies of :meth:`upload_bodies`.
        atlas_tiles : GrowableBuffer or wgpu.GPUBuffer
            Pass P2's tile records (:attr:`AtlasPlanner.tiles
            <pycinder.focused.plan.p2_atlas.AtlasPlanner>`, :data:`~.atlasplan.TILE`).
        summary : GrowableBuffer or wgpu.GPUBuffer
            Pass P2's summary (:attr:`AtlasPlanner.summary`): its ``tiles`` records are written
            (none when its ``fits`` is 0).
        capacity : int
            Tile records P2's buffer holds (:attr:`AtlasPlanner.capacity`): the invocations
            dispatched, and the records :attr:`tiles` holds.
        bodies : GrowableBuffer or wgpu.GPUBuffer, optional
            The bodies' :data:`BODY` records, those P1's windows are relative to (pass P0's
            :attr:`GpuWindows.poses <pycinder.focused.plan.p1_windows.GpuWindows>`); default: this
            pass's own, from :meth:`upload_bodies`.
        """
        capacity = int(capacity)
        self._tiles.ensure(max(capacity, 1) * TILE.size)
        if capacity <= 0:
            return
        if bodies is None and self.count == 0:
            raise RuntimeError(f"{self.INFO.title}: upload_bodies before encode")
        if isinstance(summary, GrowableBuffer):
            summary = summary.buffer
        if not isinstance(summary, tuple):
            summary = (summary, 0, SUMMARY.size)
        group = self.stage.group(bodies=self.bodies if bodies is None else bodies,
                                 windows=windows, pairs=pairs, atlas=atlas_tiles, summary=summary,
                                 tiles=self._tiles)
        cpass = encoder.begin_compute_pass(label=self.INFO.title)
        dispatch(cpass, self.stage, group, -(-capacity // self.workgroup))
        cpass.end()

    def copy_into(self, encoder: wgpu.GPUCommandEncoder, staging: wgpu.GPUBuffer, offset: int,
                  count: int) -> int:
        """Encode the copy of the first ``count`` records of :attr:`tiles` into ``staging`` at
        ``offset`` (after :meth:`encode`); returns the bytes copied."""
        nbytes = int(count) * TILE.size
        if nbytes:
            encoder.copy_buffer_to_buffer(self._tiles.buffer, 0, staging, offset, nbytes)
        return nbytes

    def read(self, count: int) -> np.ndarray:
        """Read back the first ``count`` records of :attr:`tiles` (one submission, one map; waits
        for what was submitted before).

        Returns
        -------
        (count,) structured array of :data:`~pycinder.gpu.layout.TILE`
        """
        count = int(count)
        if count <= 0:
            return TILE.zeros(0)
        nbytes = count * TILE.size
        staging = self.readback.ensure(nbytes)
        encoder = native.encoder(self.gpu.device, f"{self.INFO.title} readback")
        self.copy_into(encoder, staging, 0, count)
        self.gpu.device.queue.submit([encoder.finish()])
        data = self.readback.read(nbytes, np.uint8, timeout=self.timeout,
                                  waiting_for=f"the {count} tile words of {self.INFO.title}")
        return data.view(TILE.dtype)


__all__ = ["BODY", "TileWords", "tile_bodies"]

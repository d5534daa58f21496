"""Pass C1, distance: the distance between two bodies' surfaces, per candidate pair, exactly (in
single precision), cluster pair by cluster pair (``distance.wgsl``). The clearance query's one
pass; what it is given and what its figures promise is in :mod:`pycinder.clearance`."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import wgpu

from ..gpu.buffers import DEFAULT_TIMEOUT, GrowableBuffer, Readback
from ..gpu.device import Gpu
from ..gpu.structs import Struct
from .bindings import Stage, dispatch
from .table import PassInfo

ITEM = Struct("DistanceItem", [
    ("pair", "u32", "the candidate pair (its frame and its figure)"),
    ("a_start", "u32", "first face of body a's cluster (packed)"),
    ("a_count", "u32", "faces in it (at most CLUSTER_FACES)"),
    ("b_start", "u32", "first face of body b's cluster"),
    ("b_count", "u32", "faces in it"),
], doc="A cluster of body a and a cluster of body b whose boxes are within the clearance.")

FRAME = Struct("PairFrame", [
    ("m0", "array<vec4f, 3>", "pair-from-body rows of body a (origin at the pair's box)"),
    ("m1", "array<vec4f, 3>", "pair-from-body rows of body b"),
], doc="A candidate pair's own frame, centred on where its bodies can be within the clearance.")

PARAMS = Struct("DistanceParams", [("items", "u32", "items of the dispatch")], uniform=True)

_U = wgpu.BufferUsage
FAR = np.float32(np.inf).view(np.uint32)
"""The figure of a pair no item measured (its bits: +inf)."""


class Distance:
    """C1: one workgroup per item; per pair the smallest distance found (atomicMin).

    Parameters
    ----------
    gpu : Gpu
    timeout : float
        Seconds the readback may wait for the GPU.
    """

    INFO: ClassVar[PassInfo] = PassInfo(
        "C1", "distance", "distance between the surfaces of each candidate pair, cluster pair "
        "by cluster pair", when="clearance queries")

    def __init__(self, gpu: Gpu, timeout: float = DEFAULT_TIMEOUT) -> None:
        self.gpu = gpu
        self.timeout = timeout
        self.stage = Stage(gpu, "distance", "distance", label=self.INFO.title,
                           structs=(ITEM, FRAME, PARAMS))
        device = gpu.device

        def grow(label: str, usage: int = _U.STORAGE | _U.COPY_DST) -> GrowableBuffer:
            return GrowableBuffer(device, label, usage)

        self.items, self.frames = grow("distance items"), grow("pair frames")
        self.best = grow("pair distances", _U.STORAGE | _U.COPY_DST | _U.COPY_SRC)
        self.params = device.create_buffer(label="distance parameters", size=16,
                                           usage=_U.UNIFORM | _U.COPY_DST)
        self.readback = Readback(device, "pair distances")

    def run(self, positions: GrowableBuffer, faces: GrowableBuffer, items: np.ndarray,
            frames: np.ndarray) -> np.ndarray:
        """Measure.

        Parameters
        ----------
        positions, faces : GrowableBuffer
            The packed shapes as the focused passes hold them (their current vertices: see
            :meth:`~pycinder.passes.atlas.AtlasBuffers.upload`).
        items : (I,) structured array of :data:`ITEM`
        frames : (K,) structured array of :data:`FRAME`

        Returns
        -------
        (K,) float32
            Per pair the smallest distance between its surfaces found in its items (+inf for a
            pair with no item).
        """
        k = len(frames)
        if k == 0:
            return np.zeros(0, np.float32)
        self.items.ensure(max(items.nbytes, ITEM.size))
        if len(items):
            self.items.write(items)
        self.frames.ensure(frames.nbytes)
        self.frames.write(frames)
        self.best.ensure(4 * k)
        self.best.write(np.full(k, FAR, np.uint32))
        params = PARAMS.zeros()
        params["items"] = len(items)
        self.gpu.device.queue.write_buffer(self.params, 0, params)
        encoder = self.gpu.device.create_command_encoder()
        if len(items):
            cpass = encoder.begin_compute_pass(label=self.INFO.title)
            dispatch(cpass, self.stage, self.stage.group(
                positions=positions, faces=faces, items=self.items, frames=self.frames,
                best=self.best, params=(self.params, 0, 16)), len(items))
            cpass.end()
        staging = self.readback.ensure(4 * k)
        encoder.copy_buffer_to_buffer(self.best.buffer, 0, staging, 0, 4 * k)
        self.gpu.device.queue.submit([encoder.finish()])
        words = self.readback.read(4 * k, timeout=self.timeout,
                                   waiting_for=f"the distances of {k} pairs")
        return np.ascontiguousarray(words[:k]).view(np.float32).copy()


__all__ = ["FRAME", "ITEM", "PARAMS", "Distance"]

"""Passes that reduce work over cluster pairs to a few figures per candidate pair: pass C1
(:mod:`~pycinder.focused.measure.c1_distance`, clearance) and H1
(:mod:`~pycinder.focused.measure.h1_depth`, hard clashes).

Each item is a cluster of body a and a cluster of body b (at most
:data:`~pycinder.gpu.layout.CLUSTER_FACES` faces each) of one candidate pair; one workgroup takes
one item, with the b cluster's faces in workgroup memory and a face of the a cluster per thread.
Each pair is measured in a frame of its own (:data:`FRAME`), centred where its bodies meet, so that
single precision is spent on the pair's own extent; its figures are kept with atomicMax or
atomicMin on order-preserving bits, in ``words`` words per pair, and read back once.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np
import wgpu

from ...gpu.bindings import Stage, dispatch
from ...gpu.buffers import DEFAULT_TIMEOUT, GrowableBuffer, Readback
from ...gpu import native
from ...gpu.device import Gpu
from ...gpu.structs import Struct
from ...gpu.table import PassInfo

if TYPE_CHECKING:
    from ...scene import Scene

ITEM = Struct("PairItem", [
    ("pair", "u32", "the candidate pair (its frame and its figures)"),
    ("a_start", "u32", "first face of body a's cluster (packed)"),
    ("a_count", "u32", "faces in it"),
    ("b_start", "u32", "first face of body b's cluster"),
    ("b_count", "u32", "faces in it"),
    ("whole", "u32", ("pass H1's bits: the pair's bodies whole (its only item), flipped, the "
                      "lines the item skips")),
], doc="Faces of body a and faces of body b of one candidate pair: a cluster of each (at most "
       "CLUSTER_FACES faces), or for pass H1 the bodies whole.")

FRAME = Struct("PairFrame", [
    ("m0", "array<vec4f, 3>", "pair-from-body rows of body a (origin where the pair meets)"),
    ("m1", "array<vec4f, 3>", "pair-from-body rows of body b"),
    ("touch", "f32", ("pass H1, a pair of solids: two faces whose projections overlap by no "
                      "more than this width (pair units) only touch there, within rounding (see "
                      "measure_depth.wgsl); 0 for a pair with an open body")),
    ("cap", "f32", ("pass H1: a line stops once both its figures reach this (pair units), for a "
                    "pair whose figure matters only up to it; 0: no cap")),
], doc="A candidate pair's own frame, centred where its bodies meet.")

PARAMS = Struct("PairParams", [
    ("items", "u32", "items of the pass"),
    ("split", "u32", "items the first entry point takes (the others take the rest)"),
], uniform=True)

_U = wgpu.BufferUsage


def spread(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every element of rows holding ``counts`` (K,) elements each: its row and its index in
    the row, rows in order.

    Returns
    -------
    row, within : (sum(counts),) int64
    """
    counts = np.asarray(counts, np.int64)
    row = np.repeat(np.arange(len(counts)), counts)
    within = np.arange(len(row)) - np.repeat(np.cumsum(counts) - counts, counts)
    return row, within


def check_rounding(scene: Scene, pairs: np.ndarray, error: np.ndarray, option: str,
                   value: float, figure: str) -> None:
    """A ValueError naming the pair whose rounding bound ``error`` (K,) is over ``value / 16``:
    what the contracts of the clearance (``option`` "clearance", ``figure`` "distance") and
    hard-clash ("min_depth", "depth") queries need of single precision."""
    too_fine = np.flatnonzero(error > value / 16)
    if len(too_fine) == 0:
        return
    k = too_fine[np.argmax(error[too_fine])]
    a, b = pairs[k]
    raise ValueError(
        f"{option} {value:g} is too small for {scene.label(int(a))} and {scene.label(int(b))} "
        f"in single precision: their {figure} is measured within {error[k]:.3g}, and the "
        f"contract needs at most {option} / 16; use a {option} of at least "
        f"{16 * error[k]:.3g}, or query those bodies at their own scale")


TOUCH = 2.0**-20
"""The width, per unit of a frame's reach, under which pass H1 takes two faces' overlapping
projections as faces that only touch (:data:`FRAME`'s ``touch``): 16 times the single-precision
rounding of a vertex in the frame, so that faces meeting along an edge, or lying face on face,
never overlap by more once rounded."""


def pair_frames(transforms: np.ndarray, pairs: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                centre_lo: np.ndarray, centre_hi: np.ndarray, solid: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Each pair's own frame, centred on a box, and how far its bodies reach from that centre.

    Parameters
    ----------
    transforms : (N, 4, 4) float
        World-from-body matrices.
    pairs : (K, 2) int
    lo, hi : (N, 3) float
        World boxes of the bodies.
    centre_lo, centre_hi : (K, 3) float
        The box each pair's frame is centred on (where its bodies meet).
    solid : (N,) bool, optional
        Which bodies are solids: a pair of two gets its touch width (:data:`TOUCH`), the others
        0 (without it, every pair gets 0).

    Returns
    -------
    frames : (K,) structured array of :data:`FRAME`
    reach : (K,) float64
        The farthest either body's world box reaches from the frame's centre (what the
        rounding of a figure measured in the frame is proportional to).
    """
    origin = 0.5 * (np.asarray(centre_lo, np.float64) + np.asarray(centre_hi, np.float64))
    frames = FRAME.zeros(len(pairs))
    for side, field in enumerate(("m0", "m1")):
        m = np.array(transforms[pairs[:, side], :3], np.float64)
        m[:, :, 3] -= origin
        frames[field] = m
    a, b = pairs[:, 0], pairs[:, 1]
    corners = np.abs(np.stack([lo[a], hi[a], lo[b], hi[b]]) - origin)  # (4, K, 3)
    reach = np.sqrt((corners.max(axis=0) ** 2).sum(axis=1))
    if solid is not None:
        both = np.asarray(solid, bool)[a] & np.asarray(solid, bool)[b]
        frames["touch"] = np.where(both, TOUCH * reach, 0.0)
    return frames, reach


class ClusterPairPass:
    """One compute pass over items, reduced to ``WORDS`` 32-bit words per pair.

    Subclasses name their shader (``SHADER``, entry point ``ENTRY``), their pass (``INFO``),
    the words per pair (``WORDS``), each word's value before the pass (``START``) and the
    constants generated into the shader (``CONSTS``). A pass with a second entry point
    (``SECOND``) runs the items :meth:`second` picks with it, in a second dispatch after the
    first's: item ``params.split + i`` is its workgroup ``i``'s.

    Parameters
    ----------
    gpu : Gpu
    timeout : float
        Seconds the readback may wait for the GPU.
    """

    INFO: ClassVar[PassInfo]
    SHADER: ClassVar[str]
    ENTRY: ClassVar[str]
    WORDS: ClassVar[int]
    START: ClassVar[int]
    CONSTS: ClassVar[dict[str, int | float]] = {}
    SECOND: ClassVar[str | None] = None

    def __init__(self, gpu: Gpu, timeout: float = DEFAULT_TIMEOUT) -> None:
        self.gpu = gpu
        self.timeout = timeout
        self.stages = [Stage(gpu, self.SHADER, entry, label=self.INFO.title,
                             structs=(ITEM, FRAME, PARAMS), consts=self.CONSTS)
                       for entry in (self.ENTRY, self.SECOND) if entry is not None]
        device = gpu.device

        def grow(label: str, usage: int = _U.STORAGE | _U.COPY_DST) -> GrowableBuffer:
            return GrowableBuffer(device, f"{self.INFO.name} {label}", usage)

        self.items, self.frames = grow("items"), grow("pair frames")
        self.best = grow("figures", _U.STORAGE | _U.COPY_DST | _U.COPY_SRC)
        self.params = device.create_buffer(label=f"{self.INFO.name} parameters", size=16,
                                           usage=_U.UNIFORM | _U.COPY_DST)
        self.readback = Readback(device, f"{self.INFO.name} figures")

    def second(self, items: np.ndarray) -> np.ndarray:
        """Which of ``items`` (I,) the second entry point takes: (I,) bool (none here)."""
        return np.zeros(len(items), bool)

    def words(self, positions: GrowableBuffer, faces: GrowableBuffer, items: np.ndarray,
              frames: np.ndarray) -> np.ndarray:
        """Run the pass and read its words back.

        Parameters
        ----------
        positions, faces : GrowableBuffer
            The packed shapes as the focused passes hold them (their current vertices: see
            :meth:`~pycinder.focused.frame.atlas_buffers.AtlasBuffers.upload`).
        items : (I,) structured array of :data:`ITEM`
        frames : (K,) structured array of :data:`FRAME`

        Returns
        -------
        (K, WORDS) uint32
            Each pair's words (``START`` for a pair no item reached).
        """
        k = len(frames)
        if k == 0:
            return np.zeros((0, self.WORDS), np.uint32)
        nbytes = 4 * self.WORDS * k
        later = self.second(items) if len(self.stages) > 1 else np.zeros(len(items), bool)
        split = len(items) - int(np.count_nonzero(later))
        if split < len(items):
            items = np.concatenate([items[~later], items[later]])
        self.items.ensure(max(items.nbytes, ITEM.size))
        if len(items):
            self.items.write(items)
        self.frames.ensure(frames.nbytes)
        self.frames.write(frames)
        self.best.ensure(nbytes)
        self.best.write(np.full(self.WORDS * k, self.START, np.uint32))
        params = PARAMS.zeros()
        params["items"], params["split"] = len(items), split
        self.gpu.device.queue.write_buffer(self.params, 0, params)
        encoder = native.encoder(self.gpu.device, self.INFO.title)
        if len(items):
            cpass = encoder.begin_compute_pass(label=self.INFO.title)
            for stage, count in zip(self.stages, (split, len(items) - split)):
                if count:
                    dispatch(cpass, stage, stage.group(
                        positions=positions, faces=faces, items=self.items,
                        frames=self.frames, best=self.best, params=(self.params, 0, 16)), count)
            cpass.end()
        staging = self.readback.ensure(nbytes)
        encoder.copy_buffer_to_buffer(self.best.buffer, 0, staging, 0, nbytes)
        self.gpu.device.queue.submit([encoder.finish()])
        words = self.readback.read(nbytes, timeout=self.timeout,
                                   waiting_for=f"the {self.INFO.name} figures of {k} pairs")
        return np.ascontiguousarray(words[:self.WORDS * k]).reshape(k, self.WORDS).copy()


__all__ = ["FRAME", "ITEM", "PARAMS", "TOUCH", "ClusterPairPass", "check_rounding", "pair_frames",
           "spread"]

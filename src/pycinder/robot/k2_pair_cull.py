"""A robot check's fixed pair list culled by world boxes on the GPU (pass K2,
``robot_cull.wgsl``), after the forward kinematics (pass K1, :mod:`pycinder.robot.k1_kinematics`),
in one submission with one map::

    joint values (C, J) -> K1 kinematics: the robot's body poses and world boxes (C, B)
                        -> K2 cull: per configuration, a bit per checked pair whose bodies'
                           world boxes overlap (or lie within a padded check's clearance)
    -> the poses, the boxes, and the surviving pairs (configuration, i, j), sorted

The check's bodies (robot, attached, environment: those some checked pair names) and its pairs
are uploaded once per check plan. A box is conservative: K1's holds its body placed by K1's pose
(its own arithmetic's rounding included), and K2 grows it by twice the kinematics' error
estimate; an environment body's box is made on the host in float64, grown as K1 grows its own,
and rounded outwards. So no pair whose bodies overlap in float64 is culled, as far as the
estimate holds (measured at most a quarter of it); the query itself tests the bodies at K1's
poses, whose boxes hold their vertices as stored.
A pair whose boxes overlap only by those margins is kept: the planner finds it apart
(``stats.separated``). The query's scene takes K1's boxes as its world boxes
(``PreparedBodies.copies(boxes=)``): the host measures none.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import wgpu

from ..gpu import native
from ..gpu.bindings import Stage, dispatch
from ..gpu.buffers import GrowableBuffer, Readback
from ..gpu.layout import ROW, WORKGROUP
from ..gpu.structs import Struct
from ..gpu.table import PassInfo
from ..util.text import plural
from .k1_kinematics import ROUNDING, GpuKinematics

FIXED = 0xFFFF_FFFF
"""A :data:`BODY`'s ``source`` where its box is its own (an environment body)."""

BODY = Struct("CullBody", [
    ("lo", "vec3f", "a fixed body's world box minimum (rounded down)"),
    ("source", "u32", "its index among K1's bodies, or FIXED"),
    ("hi", "vec3f", "a fixed body's world box maximum (rounded up)"),
    ("pad", "f32", "how far K1's box is grown: twice K1's error estimate (0 for a fixed body)"),
], doc="One body of a robot check for pass K2 (pycinder/robot/k2_pair_cull.py).")

PARAMS = Struct("CullParams", [
    ("configurations", "u32", "configurations of the dispatch"),
    ("pairs", "u32", "checked pairs per configuration"),
    ("words", "u32", "words of bits per configuration: ceil(pairs / 32)"),
    ("moving", "u32", "K1's bodies per configuration"),
    ("grow", "f32", "world units every box is grown by (a padded check's clearance)"),
    ("pad0", "u32", ""),
    ("pad1", "u32", ""),
    ("pad2", "u32", ""),
], uniform=True, doc="Pass K2's sizes (pycinder/robot/k2_pair_cull.py).")


def fixed_boxes(poses: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(U, 2, 3) float64 world boxes of body-space boxes ``lo``, ``hi`` (U, 3) placed by
    ``poses`` (U, 4, 4): the oriented box's own, grown as K1 grows its boxes (by
    :data:`~pycinder.robot.k1_kinematics.ROUNDING` of their terms' magnitudes), so that they hold
    the bodies' vertices as stored in float32 too."""
    poses = np.asarray(poses, np.float64)
    linear, middle = np.abs(poses[:, :3, :3]), 0.5 * (lo + hi)
    centre = np.einsum("nij,nj->ni", poses[:, :3, :3], middle) + poses[:, :3, 3]
    half = np.einsum("nij,nj->ni", linear, 0.5 * (hi - lo))
    size = np.einsum("nij,nj->ni", linear, np.abs(middle)) + np.abs(poses[:, :3, 3]) + half
    half += ROUNDING * size
    return np.stack([centre - half, centre + half], axis=1)


def outwards(boxes: np.ndarray) -> np.ndarray:
    """(U, 2, 3) float32 boxes holding float64 ``boxes`` (U, 2, 3): minima rounded down,
    maxima up."""
    out = boxes.astype(np.float32)
    lo, hi = out[:, 0], out[:, 1]
    lo[...] = np.where(lo > boxes[:, 0], np.nextafter(lo, np.float32(-np.inf)), lo)
    hi[...] = np.where(hi < boxes[:, 1], np.nextafter(hi, np.float32(np.inf)), hi)
    return out


_U = wgpu.BufferUsage


class GpuPairCull:
    """K2 over the pairs of one check plan, after K1 (``kinematics``).

    Parameters
    ----------
    kinematics : GpuKinematics
        The robot's pass K1 (its device is this pass's).
    sources : (U,) int
        Per body of the check, its index among K1's bodies, or -1 for a fixed body.
    poses : (U, 4, 4) float
        World from body of the fixed bodies (those of the others are not read).
    lo, hi : (U, 3) float
        Each body's box, in its own coordinates.
    pairs : (P, 2) int
        The checked pairs, as indices into the check's bodies, ``i < j``, sorted.
    """

    INFO: ClassVar[PassInfo] = PassInfo(
        "K2", "cull", "a robot check's pair list culled by world boxes: a bit per configuration "
        "and pair whose boxes overlap", when="per batch of a robot's check, after K1")
    SHADER, ENTRY = "robot_cull", "cull_pairs"

    def __init__(self, kinematics: GpuKinematics, sources: np.ndarray, poses: np.ndarray,
                 lo: np.ndarray, hi: np.ndarray, pairs: np.ndarray) -> None:
        self.kinematics = kinematics
        self.gpu = gpu = kinematics.gpu
        consts = {"WORKGROUP": WORKGROUP, "ROW": ROW, "FIXED": FIXED}
        self.stage = Stage(gpu, self.SHADER, self.ENTRY, label=self.INFO.title,
                           structs=(BODY, PARAMS), consts=consts)
        sources = np.asarray(sources, np.int64)
        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        table = BODY.zeros(len(sources))
        moving = sources >= 0
        self.fixed = fixed_boxes(poses, lo, hi)
        """(U, 2, 3) float64: the fixed bodies' world boxes (rows of the others unused)."""
        box = outwards(self.fixed)
        table["lo"], table["hi"] = box[:, 0], box[:, 1]
        table["source"] = np.where(moving, sources, FIXED)
        self.error = kinematics.errors_of(sources)
        """(U,) each body's K1 error estimate (0 for a fixed body)."""
        table["pad"] = 2.0 * self.error
        self._local = (lo, hi)
        self._placed = np.asarray(poses, np.float64).copy()
        self.pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
        self.words = -(-len(self.pairs) // 32)
        device = gpu.device

        def store(label: str, data: np.ndarray) -> wgpu.GPUBuffer:
            data = data if data.size else np.zeros(2, np.uint32)
            return device.create_buffer_with_data(label=f"{self.INFO.name} {label}",
                                                  data=np.ascontiguousarray(data).tobytes(),
                                                  usage=_U.STORAGE)

        self.table = table
        self.bodies = device.create_buffer_with_data(label=f"{self.INFO.name} bodies",
                                                     data=table.tobytes(),
                                                     usage=_U.STORAGE | _U.COPY_DST)
        self.pair_buffer = store("pairs", self.pairs.astype(np.uint32))
        self.bits = GrowableBuffer(device, f"{self.INFO.name} bits", _U.STORAGE | _U.COPY_SRC)
        self.params = device.create_buffer(label=f"{self.INFO.name} parameters",
                                           size=PARAMS.size, usage=_U.UNIFORM | _U.COPY_DST)
        self.readback = Readback(device, f"{self.INFO.name} readback")

    def place(self, poses: np.ndarray) -> None:
        """Place the fixed bodies at ``poses`` (U, 4, 4) (those of the others are not read): an
        environment of the same meshes moved. Nothing is written when none moved."""
        poses = np.asarray(poses, np.float64)
        if np.array_equal(poses, self._placed):
            return
        fixed = fixed_boxes(poses, *self._local)
        table = self.table.copy()
        box = outwards(fixed)
        table["lo"], table["hi"] = box[:, 0], box[:, 1]
        self.gpu.device.queue.write_buffer(self.bodies, 0, table)
        self.table, self.fixed, self._placed = table, fixed, poses.copy()  # once written

    def run(self, q: np.ndarray, grow: float = 0.0
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """K1 and K2 over configurations ``q``: one submission, one map.

        Parameters
        ----------
        q : (C, J) float
            Joint values, checked by the caller.
        grow : float
            World units every box is grown by (a padded check's clearance).

        Returns
        -------
        rows : (C, B, 3, 4) float32
            K1's poses: world from body, its top three rows (:meth:`GpuKinematics.read`).
        boxes : (C, B, 2, 4) float32
            K1's world boxes: minimum and maximum (xyz; w unused), each holding its body
            placed by ``rows``.
        survivors : (S, 3) int64
            The pairs kept: configuration (index into ``q``), and the pair's bodies (indices
            into the check's bodies), sorted by configuration, then as the pair list.
        """
        k1 = self.kinematics
        c = len(q)
        if not len(self.pairs):
            raise ValueError("pass K2 of a check with no pair to check: nothing to run")
        if c == 0:
            return (np.zeros((0, k1.bodies, 3, 4), np.float32),
                    np.zeros((0, k1.bodies, 2, 4), np.float32), np.zeros((0, 3), np.int64))
        k1.upload(q)
        words = c * self.words
        self.bits.ensure(4 * words)
        params = PARAMS.zeros()
        params["configurations"], params["pairs"], params["words"] = c, len(self.pairs), \
            self.words
        params["moving"], params["grow"] = k1.bodies, grow
        device = self.gpu.device
        device.queue.write_buffer(self.params, 0, params)
        pose_bytes, box_bytes = c * k1.bodies * 48, c * k1.bodies * 32
        nbytes = pose_bytes + box_bytes + 4 * words
        staging = self.readback.ensure(nbytes)
        encoder = native.encoder(device, self.INFO.title)
        k1.encode(encoder)
        group = self.stage.group(boxes=k1.boxes, bodies=self.bodies, pairs=self.pair_buffer,
                                 words=self.bits, params=self.params)
        cpass = encoder.begin_compute_pass(label=self.INFO.title)
        dispatch(cpass, self.stage, group, -(-words // WORKGROUP))
        cpass.end()
        if pose_bytes:
            encoder.copy_buffer_to_buffer(k1.poses.buffer, 0, staging, 0, pose_bytes)
            encoder.copy_buffer_to_buffer(k1.boxes.buffer, 0, staging, pose_bytes, box_bytes)
        encoder.copy_buffer_to_buffer(self.bits.buffer, 0, staging, pose_bytes + box_bytes,
                                      4 * words)
        device.queue.submit([encoder.finish()])
        data = self.readback.read(
            nbytes, np.uint8, timeout=k1.timeout,
            waiting_for=f"{k1.name}'s poses and pairs in {plural(c, 'configuration')}")
        rows = data[:pose_bytes].view(np.float32).reshape(c, k1.bodies, 3, 4)
        boxes = data[pose_bytes:pose_bytes + box_bytes].view(np.float32).reshape(
            c, k1.bodies, 2, 4)
        # Bits past a configuration's pairs are 0: the words are searched whole.
        kept = np.flatnonzero(np.unpackbits(data[pose_bytes + box_bytes:], bitorder="little"))
        config, pair = np.divmod(kept, 32 * self.words)
        survivors = np.empty((len(config), 3), np.int64)
        survivors[:, 0] = config
        survivors[:, 1:] = self.pairs.take(pair, axis=0)
        return rows, boxes, survivors


PASSES = (GpuKinematics, GpuPairCull)
"""A robot check's passes on the GPU, in the order they run (the docs' pass table)."""

__all__ = ["BODY", "FIXED", "PARAMS", "PASSES", "GpuPairCull", "fixed_boxes", "outwards"]

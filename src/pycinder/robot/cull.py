"""A robot check's fixed pair list culled by world boxes on the GPU (pass K2,
``robot_cull.wgsl``), after the forward kinematics (pass K1, :mod:`pycinder.robot.kinematics`),
in one submission with one map::

    joint values (C, J) -> K1 kinematics: the robot's body poses (C, B)
                        -> K2 cull: per configuration, a bit per checked pair whose bodies'
                           world boxes overlap (or lie within a padded check's clearance)
    -> the poses, and the surviving pairs (configuration, i, j), sorted

The check's bodies (robot, attached, environment: those some checked pair names) and its pairs
are uploaded once per check plan. A box is conservative: grown by twice the kinematics' error
estimate for a body that moves with the robot, and by its own arithmetic's rounding, so no pair
whose bodies overlap in float64 is culled. A pair whose boxes overlap only by those margins is
kept: the planner finds it apart (``stats.separated``).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import wgpu

from ..gpu import native
from ..gpu.bindings import Stage, dispatch
from ..gpu.buffers import GrowableBuffer, Readback
from ..gpu.layout import WORKGROUP
from ..gpu.structs import Struct
from ..gpu.table import PassInfo
from ..util.text import plural
from .kinematics import GpuKinematics

FIXED = 0xFFFF_FFFF
"""A :data:`BODY`'s ``source`` where its pose is its own (an environment body)."""

ROUNDING = 2.0**-20
"""Bound on the relative rounding of a box's coordinates in the pass (a few products and sums in
float32, each within ``2**-24``), as a fraction of the sum of their terms' magnitudes."""

BODY = Struct("CullBody", [
    ("pose", "array<vec4f, 3>", "world-from-body rows of a fixed body (source FIXED)"),
    ("centre", "vec3f", "the body-space box's centre"),
    ("source", "u32", "its index among K1's bodies, or FIXED"),
    ("half", "vec3f", "the body-space box's half extents"),
    ("pad", "f32", "how far its world box is grown: twice K1's error estimate, or 0"),
], doc="One body of a robot check for pass K2 (pycinder/robot/cull.py).")

PARAMS = Struct("CullParams", [
    ("configurations", "u32", "configurations of the dispatch"),
    ("pairs", "u32", "checked pairs per configuration"),
    ("words", "u32", "words of bits per configuration: ceil(pairs / 32)"),
    ("moving", "u32", "K1's bodies per configuration"),
    ("grow", "f32", "world units every box is grown by (a padded check's clearance)"),
    ("pad0", "u32", ""),
    ("pad1", "u32", ""),
    ("pad2", "u32", ""),
], uniform=True, doc="Pass K2's sizes (pycinder/robot/cull.py).")

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
        World from body of the fixed bodies (rows of the others are not read).
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
        consts = {"WORKGROUP": WORKGROUP, "FIXED": FIXED, "ROUNDING": ROUNDING}
        self.stage = Stage(gpu, self.SHADER, self.ENTRY, label=self.INFO.title,
                           structs=(BODY, PARAMS), consts=consts)
        sources = np.asarray(sources, np.int64)
        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        table = BODY.zeros(len(sources))
        table["pose"] = np.asarray(poses, np.float64)[:, :3, :]
        table["centre"], table["half"] = 0.5 * (lo + hi), 0.5 * (hi - lo)
        moving = sources >= 0
        table["source"] = np.where(moving, sources, FIXED)
        table["pad"] = np.where(moving, 2.0 * kinematics.error_estimate()[
            np.maximum(sources, 0)], 0.0)
        self.pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
        self.words = -(-len(self.pairs) // 32)
        device = gpu.device

        def store(label: str, data: np.ndarray) -> wgpu.GPUBuffer:
            data = data if data.size else np.zeros(2, np.uint32)
            return device.create_buffer_with_data(label=f"{self.INFO.name} {label}",
                                                  data=np.ascontiguousarray(data).tobytes(),
                                                  usage=_U.STORAGE)

        self.bodies = store("bodies", table)
        self.pair_buffer = store("pairs", self.pairs.astype(np.uint32))
        self.bits = GrowableBuffer(device, f"{self.INFO.name} bits", _U.STORAGE | _U.COPY_SRC)
        self.params = device.create_buffer(label=f"{self.INFO.name} parameters",
                                           size=PARAMS.size, usage=_U.UNIFORM | _U.COPY_DST)
        self.readback = Readback(device, f"{self.INFO.name} readback")

    def run(self, q: np.ndarray, grow: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
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
        survivors : (S, 3) int64
            The pairs kept: configuration (index into ``q``), and the pair's bodies (indices
            into the check's bodies), sorted by configuration, then as the pair list.
        """
        k1 = self.kinematics
        c = len(q)
        if c == 0 or not len(self.pairs):
            return k1.read(q)[..., :3, :].astype(np.float32), np.zeros((0, 3), np.int64)
        k1.upload(q)
        words = c * self.words
        self.bits.ensure(4 * words)
        params = PARAMS.zeros()
        params["configurations"], params["pairs"], params["words"] = c, len(self.pairs), \
            self.words
        params["moving"], params["grow"] = k1.bodies, grow
        device = self.gpu.device
        device.queue.write_buffer(self.params, 0, params)
        pose_bytes = c * k1.bodies * 48
        nbytes = pose_bytes + 4 * words
        staging = self.readback.ensure(nbytes)
        encoder = native.encoder(device, self.INFO.title)
        k1.encode(encoder)
        group = self.stage.group(poses=k1.poses, bodies=self.bodies, pairs=self.pair_buffer,
                                 words=self.bits, params=self.params)
        cpass = encoder.begin_compute_pass(label=self.INFO.title)
        dispatch(cpass, self.stage, group, -(-words // WORKGROUP))
        cpass.end()
        if pose_bytes:
            encoder.copy_buffer_to_buffer(k1.poses.buffer, 0, staging, 0, pose_bytes)
        encoder.copy_buffer_to_buffer(self.bits.buffer, 0, staging, pose_bytes, 4 * words)
        device.queue.submit([encoder.finish()])
        data = self.readback.read(
            nbytes, np.uint8, timeout=k1.timeout,
            waiting_for=f"{k1.name}'s poses and pairs in {plural(c, 'configuration')}")
        rows = data[:pose_bytes].view(np.float32).reshape(c, k1.bodies, 3, 4)
        # Bits past a configuration's pairs are 0: the words are searched whole.
        kept = np.flatnonzero(np.unpackbits(data[pose_bytes:], bitorder="little"))
        config, pair = np.divmod(kept, 32 * self.words)
        survivors = np.empty((len(config), 3), np.int64)
        survivors[:, 0] = config
        survivors[:, 1:] = self.pairs.take(pair, axis=0)
        return rows, survivors


PASSES = (GpuKinematics, GpuPairCull)
"""A robot check's passes on the GPU, in the order they run (the docs' pass table)."""

__all__ = ["BODY", "FIXED", "PARAMS", "PASSES", "ROUNDING", "GpuPairCull"]

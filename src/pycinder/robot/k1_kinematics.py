"""Forward kinematics on the GPU: every collision body's pose in every configuration, from joint
values, in one compute pass (``robot_kinematics.wgsl``), the first stage of a robot query that
lives on the GPU::

    joint values (C, J)       -> motions (C, M): each moving joint's sine and versine, or offset
                                 (host, float64, rounded once; O(C x M) NumPy)
    K1 kinematics             -> link poses (C, L), body poses (C, B) and the bodies' world
                                 boxes (C, B), one invocation per configuration walking the
                                 joints in tree order (compute)

The kinematic tree is uploaded once: each joint's origin, axis, kind, parent and child link, and
each body's link, origin and body-space box (:data:`JOINT`, :data:`BODY`). A world box holds the
body's vertices placed by its pose as written (grown by :data:`ROUNDING` of its own
arithmetic). Mimic joints take their motion from
their own column of the motions (the host applies the multiplier and offset in float64).

Precision
---------
The passes run in single precision. A body's pose then differs from the float64 poses of
:meth:`~pycinder.robot.model.RobotModel.poses` by a few units in the last place of each product
along its chain: :meth:`GpuKinematics.error_estimate` gives, per body, an estimate of how far any
point of the body may move, ``2**-24 * 2 * (products + 1) * (reach + radius)`` (``products``: the
affine products along its chain; ``reach``: the lengths of the joints' origins and prismatic
travel along it, by its limits; ``radius``: the farthest vertex from the body's origin). It is
an estimate, not a proven bound: the tests measure every vertex of the four benchmark robots at
random configurations against it (at most 0.24 of it). A check uses these poses only where, for
every pair it checks, both bodies' estimates added are at most :data:`POSE_MARGIN` of the pair's
tolerance (a sixteenth of a pixel, the margin single-precision tile coordinates are given), and
where its prismatic joints keep within their limits (:meth:`GpuKinematics.reaches`); the host's
float64 poses otherwise.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import wgpu

from ..gpu import native
from ..gpu.bindings import Stage, dispatch
from ..gpu.buffers import DEFAULT_TIMEOUT, GrowableBuffer, Readback
from ..gpu.device import Gpu, get_gpu
from ..gpu.layout import ROW, WORKGROUP
from ..gpu.structs import Struct
from ..gpu.table import PassInfo
from ..util.text import plural

if TYPE_CHECKING:
    from .model import RobotModel

JOINT_FIXED, JOINT_REVOLUTE, JOINT_PRISMATIC = 0, 1, 2
"""A joint's ``kind`` in :data:`JOINT` (continuous joints are revolute)."""

JOINT = Struct("KinJoint", [
    ("origin", "array<vec4f, 3>", "parent-from-joint rows: R's row i (xyz), t_i (w)"),
    ("axis", "vec3f", "the joint's unit axis, in its own frame"),
    ("kind", "u32", "JOINT_FIXED, JOINT_REVOLUTE or JOINT_PRISMATIC"),
    ("parent", "u32", "the parent link's index"),
    ("child", "u32", "the child link's index"),
    ("motion", "u32", "the joint's column of the motions (moving joints)"),
    ("pad0", "u32", ""),
], doc="One joint of the kinematic tree, in tree order (pycinder/robot/k1_kinematics.py).")

BODY = Struct("KinBody", [
    ("origin", "array<vec4f, 3>", "link-from-body rows: R's row i (xyz), t_i (w)"),
    ("centre", "vec3f", "the body-space box's centre"),
    ("link", "u32", "the link the body moves with"),
    ("half", "vec3f", "the body-space box's half extents"),
    ("pad0", "u32", ""),
], doc="One collision body (or attached object) of the robot (pycinder/robot/k1_kinematics.py).")

ROUNDING = 2.0**-20
"""Bound on the relative rounding of a world box's coordinates in the pass (a few products and
sums in float32, each within ``2**-24``), as a fraction of the sum of their terms'
magnitudes."""

PARAMS = Struct("KinParams", [
    ("configurations", "u32", "configurations of the dispatch"),
    ("links", "u32", "links per configuration"),
    ("joints", "u32", "joints, in tree order"),
    ("motions", "u32", "moving joints: motions per configuration"),
    ("bodies", "u32", "bodies per configuration"),
    ("pad0", "u32", ""),
    ("pad1", "u32", ""),
    ("pad2", "u32", ""),
], uniform=True, doc="The kinematics pass's sizes (pycinder/robot/k1_kinematics.py).")

POSE_MARGIN = 1 / 16
"""Largest sum of a checked pair's two :meth:`GpuKinematics.error_estimate`, as a fraction of
the pair's tolerance, at which a check takes its poses from the GPU."""

_U = wgpu.BufferUsage


def _rows(m: np.ndarray) -> np.ndarray:
    """(..., 3, 4) the affine rows of (..., 4, 4) matrices."""
    return np.asarray(m, np.float64)[..., :3, :]


class GpuKinematics:
    """K1: the poses of a robot's bodies (its collision bodies, then its attached objects, as
    :meth:`~pycinder.robot.model.RobotModel.poses` orders them) in each configuration, on the
    GPU. The tree is uploaded once; the pipeline and buffers are made once and reused (grown
    when a batch needs more).

    Parameters
    ----------
    model : RobotModel
        The robot, with the objects attached to it now (a model whose attached objects change
        needs a new one).
    gpu : Gpu, optional
        The device (default: pycinder's).
    timeout : float
        Seconds a readback may wait for the GPU.
    """

    INFO: ClassVar[PassInfo] = PassInfo(
        "K1", "kinematics", "every body's pose in every configuration: one invocation per "
        "configuration walks the joints in tree order", when="per batch of a robot's check")
    SHADER, ENTRY = "robot_kinematics", "forward_kinematics"

    def __init__(self, model: RobotModel, gpu: Gpu | None = None,
                 timeout: float = DEFAULT_TIMEOUT) -> None:
        self.gpu = gpu = gpu or get_gpu()
        self.timeout = float(timeout)
        self.name = model.name
        consts = {"WORKGROUP": WORKGROUP, "ROW": ROW, "JOINT_REVOLUTE": JOINT_REVOLUTE,
                  "JOINT_PRISMATIC": JOINT_PRISMATIC, "ROUNDING": ROUNDING}
        self.stage = Stage(gpu, self.SHADER, self.ENTRY, label=self.INFO.title,
                           structs=(JOINT, BODY, PARAMS), consts=consts)
        joints, bodies, self._motion = _tables(model)
        self.attached = tuple(id(a.body) for a in model._attached.values())
        """The objects attached to the model when this was made (by identity)."""
        self._travel = np.array([_travel(model.joints[k]) for k in
                                 np.flatnonzero(joints["kind"] != JOINT_FIXED)])
        self.links = len(model.links)
        self.bodies = len(bodies)
        self.products = _products(model, joints)
        self._estimate = _error_estimate(model, joints, bodies, self.products)
        device = gpu.device

        def store(label: str, data: np.ndarray) -> wgpu.GPUBuffer:
            data = data if len(data) else np.zeros(1, data.dtype)
            return device.create_buffer_with_data(label=f"{self.INFO.name} {label}",
                                                  data=data.tobytes(), usage=_U.STORAGE)

        self.joint_count = len(joints)
        self.tree = store("joints", joints)
        self.body_table = store("bodies", bodies)
        self.motions = GrowableBuffer(device, f"{self.INFO.name} motions",
                                      _U.STORAGE | _U.COPY_DST)
        self.link_poses = GrowableBuffer(device, f"{self.INFO.name} links", _U.STORAGE)
        self.poses = GrowableBuffer(device, f"{self.INFO.name} poses",
                                    _U.STORAGE | _U.COPY_SRC)
        """The body poses of the last batch: (C, B, 3) rows of vec4f (bind after encoding)."""
        self.boxes = GrowableBuffer(device, f"{self.INFO.name} boxes",
                                    _U.STORAGE | _U.COPY_SRC)
        """The bodies' world boxes of the last batch: (C, B, 2) vec4f, minimum and maximum
        (xyz), each holding the body's vertices placed by its pose as written."""
        self.params = device.create_buffer(label=f"{self.INFO.name} parameters",
                                           size=PARAMS.size, usage=_U.UNIFORM | _U.COPY_DST)
        self.readback = Readback(device, f"{self.INFO.name} readback")
        self.count = 0
        """Configurations uploaded last."""

    def reaches(self, q: np.ndarray) -> bool:
        """Whether every moving joint's value in configurations ``q`` (C, J) is finite and every
        prismatic joint's offset lies within the travel :meth:`error_estimate` assumes (its
        limits; a check's configurations need not keep them): if not, the estimate does not
        hold for them (a mimic's multiplier may also overflow a finite value)."""
        return bool(self.reaches_each(q).all())

    def reaches_each(self, q: np.ndarray) -> np.ndarray:
        """(C,) bool: :meth:`reaches` of each configuration of ``q`` (C, J) alone."""
        value = self._values(q)
        # inf travel for a joint that turns: any finite angle
        return np.all(np.isfinite(value) & (np.abs(value) <= self._travel), axis=1)

    def error_estimate(self) -> np.ndarray:
        """(B,) how far, at most by estimate, any point of each body lies from where float64
        kinematics puts it (see the module's docstring), in world units."""
        return self._estimate

    def errors_of(self, sources: np.ndarray) -> np.ndarray:
        """(U,) :meth:`error_estimate` of bodies ``sources`` (U,) (indices among this pass's
        bodies), 0 where a source is -1 (a body that does not move with the robot)."""
        sources = np.asarray(sources, np.int64)
        return np.where(sources >= 0, self._estimate[np.maximum(sources, 0)], 0.0)

    def _values(self, q: np.ndarray) -> np.ndarray:
        """(C, M) float64 each moving joint's value (angle or offset) in configurations ``q``
        (C, J): its column times its multiplier plus its offset."""
        col, mult, off, _ = self._motion  # a column of -1 (none) has multiplier 0
        q = np.asarray(q, np.float64)
        value = q.take(col, axis=1) if q.shape[1] else np.zeros((len(q), len(col)))
        value *= mult
        value += off
        return value

    def motions_of(self, q: np.ndarray) -> np.ndarray:
        """(C, M, 2) float32: each moving joint's motion in each configuration ``q`` (C, J):
        a revolute joint's sine and versine (``1 - cos``, as ``2 sin^2(a / 2)``), a prismatic
        joint's offset and 0; computed in float64 and rounded once."""
        revolute = self._motion[3]
        value = self._values(q)
        out = np.zeros((len(value), len(revolute), 2), np.float32)
        turn = value[:, revolute]
        out[:, revolute, 0] = np.sin(turn)
        half = np.sin(0.5 * turn)
        out[:, revolute, 1] = 2.0 * half * half
        out[:, ~revolute, 0] = value[:, ~revolute]
        return out

    def upload(self, q: np.ndarray) -> None:
        """Upload configurations ``q`` (C, J) float, checked by the caller, for :meth:`encode`."""
        motions = self.motions_of(q)
        c = len(q)
        self.count = c
        self.motions.ensure(max(motions.nbytes, 8))
        self.motions.write(motions)
        self.link_poses.ensure(max(c * self.links * 48, 48))
        self.poses.ensure(max(c * self.bodies * 48, 48))
        self.boxes.ensure(max(c * self.bodies * 32, 32))
        params = PARAMS.zeros()
        params["configurations"], params["links"], params["joints"] = c, self.links, \
            self.joint_count
        params["motions"], params["bodies"] = max(motions.shape[1], 1), self.bodies
        self.gpu.device.queue.write_buffer(self.params, 0, params)

    def encode(self, encoder: wgpu.GPUCommandEncoder) -> None:
        """Record the pass: the poses of the configurations uploaded last into :attr:`poses`."""
        if self.count == 0:
            return
        group = self.stage.group(joints=self.tree, bodies=self.body_table,
                                 motions=self.motions, links=self.link_poses, poses=self.poses,
                                 boxes=self.boxes, params=self.params)
        cpass = encoder.begin_compute_pass(label=self.INFO.title)
        dispatch(cpass, self.stage, group, -(-self.count // WORKGROUP))
        cpass.end()

    def read(self, q: np.ndarray) -> np.ndarray:
        """Run the pass over configurations ``q`` and read every body's pose back (one
        submission, one map; a check runs it with pass K2, :mod:`pycinder.robot.k2_pair_cull`).

        Parameters
        ----------
        q : (C, J) float
            Joint values, checked by the caller (finite, J columns).

        Returns
        -------
        (C, B, 4, 4) float64
            World from body, as :meth:`~pycinder.robot.model.RobotModel.poses` orders the
            bodies; computed in float32.
        """
        c = len(q)
        if c == 0 or self.bodies == 0:
            return pose_matrices(np.zeros(c * self.bodies * 12, np.float32), c, self.bodies)
        self.upload(q)
        nbytes = c * self.bodies * 48
        staging = self.readback.ensure(nbytes)
        encoder = native.encoder(self.gpu.device, self.INFO.title)
        self.encode(encoder)
        encoder.copy_buffer_to_buffer(self.poses.buffer, 0, staging, 0, nbytes)
        self.gpu.device.queue.submit([encoder.finish()])
        rows = self.readback.read(
            nbytes, np.float32, timeout=self.timeout,
            waiting_for=f"{self.name}'s poses in {plural(c, 'configuration')}")
        return pose_matrices(rows, c, self.bodies)


def pose_matrices(rows: np.ndarray, configurations: int, bodies: int) -> np.ndarray:
    """(C, B, 4, 4) float64 world-from-body matrices of :attr:`GpuKinematics.poses`' rows
    (C * B * 12,) float32 as read back."""
    out = np.zeros((configurations, bodies, 4, 4))
    out[..., 3, 3] = 1.0
    out[..., :3, :] = rows.reshape(configurations, bodies, 3, 4)
    return out


def _tables(model: RobotModel) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The tree's :data:`JOINT` and :data:`BODY` records, and the host's share of the motions:
    per moving joint its configuration column, multiplier (0 for a joint that follows no
    column: a mimic of a joint that is not actuated), offset and whether it turns."""
    joints = JOINT.zeros(len(model.joints))
    col, mult, off, revolute = [], [], [], []
    for k, (j, (parent, child, c, m, o)) in enumerate(zip(model.joints, model._kin)):
        rec = joints[k]
        rec["origin"] = _rows(j.origin)
        rec["axis"] = j.axis
        rec["parent"], rec["child"] = parent, child
        kind = {"revolute": JOINT_REVOLUTE, "continuous": JOINT_REVOLUTE,
                "prismatic": JOINT_PRISMATIC}.get(j.type, JOINT_FIXED)
        rec["kind"] = kind
        if kind != JOINT_FIXED:
            rec["motion"] = len(col)
            col.append(c)
            mult.append(m)
            off.append(o)
            revolute.append(kind == JOINT_REVOLUTE)
    links, origins = model._body_links()
    bodies = BODY.zeros(len(links))
    bodies["link"] = links
    bodies["origin"] = _rows(origins)
    bounds = np.array([m.bounds for m in _meshes(model)], np.float64).reshape(-1, 2, 3)
    bodies["centre"] = 0.5 * (bounds[:, 0] + bounds[:, 1])
    bodies["half"] = 0.5 * (bounds[:, 1] - bounds[:, 0])
    col, mult = np.array(col, np.int64), np.array(mult, np.float64)
    motion = (np.maximum(col, 0), np.where(col >= 0, mult, 0.0), np.array(off, np.float64),
              np.array(revolute, bool))
    return joints, bodies, motion


def _meshes(model: RobotModel) -> list:
    """Each body's mesh: the collision bodies', then the attached objects'."""
    return [b.mesh for b in model.bodies] + [a.body.mesh for a in model._attached.values()]


def _chains(model: RobotModel) -> list[list[int]]:
    """Per link, the joints from the root to it (indices into ``model.joints``)."""
    chains: list[list[int]] = [[] for _ in model.links]
    for k, (parent, child, *_rest) in enumerate(model._kin):
        chains[child] = chains[parent] + [k]
    return chains


def _products(model: RobotModel, joints: np.ndarray) -> np.ndarray:
    """(L,) the affine products the pass makes along each link's chain."""
    chains = _chains(model)
    moving = joints["kind"] == JOINT_REVOLUTE
    return np.array([sum(1 + int(moving[k]) for k in chain) for chain in chains], np.int64)


def _travel(joint: Any) -> float:
    """How far a prismatic joint slides at most, by its limits (inf for a joint that turns:
    any angle)."""
    return max(abs(joint.lower), abs(joint.upper)) if joint.type == "prismatic" else np.inf


def _error_estimate(model: RobotModel, joints: np.ndarray, bodies: np.ndarray,
                    products: np.ndarray) -> np.ndarray:
    """(B,) :meth:`GpuKinematics.error_estimate`."""
    chains = _chains(model)
    travel = np.array([_travel(j) if j.type == "prismatic" else 0.0 for j in model.joints])
    step = np.linalg.norm(joints["origin"][:, :, 3].astype(np.float64), axis=1) + travel
    reach = np.array([step[chain].sum() for chain in chains])
    origin = bodies["origin"][:, :, 3].astype(np.float64)
    radius = np.array([np.linalg.norm(np.asarray(m.vertices, np.float64), axis=1).max()
                       if len(m.vertices) else 0.0 for m in _meshes(model)]) + \
        np.linalg.norm(origin, axis=1)
    link = bodies["link"].astype(np.int64)
    return 2.0**-24 * 2 * (products[link] + 1) * (reach[link] + radius)


__all__ = ["BODY", "JOINT", "JOINT_FIXED", "JOINT_PRISMATIC", "JOINT_REVOLUTE", "PARAMS",
           "POSE_MARGIN", "ROUNDING", "GpuKinematics", "pose_matrices"]

"""Checks of a robot's configurations: self-collision, attached objects and a fixed
environment, many configurations per batched query (:class:`Robot`)."""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import wgpu

from ..focused.broad.broad_numpy import PairList
from ..tolerance import DEFAULT_RELATIVE_TOLERANCE, body_sizes
from .acm import (ALWAYS_FRACTION, ALWAYS_SAMPLES, AllowedCollisionMatrix, AlwaysCollidingWarning,
                  always_colliding, matrix_from_samples)
from .model import Body, Environment, RobotModel

if TYPE_CHECKING:
    from ..detector import Detector
    from ..scene import PreparedBodies
    from .k2_pair_cull import GpuPairCull

DEFAULT_BODIES_PER_QUERY = 12_000
"""Most bodies one batched query holds by default on a CPU adapter (configurations per query:
this divided by the bodies one configuration holds)."""

GPU_BODIES_PER_QUERY = 200_000
"""Most bodies one batched query holds by default on a GPU: 11,764 Panda configurations with
its table and tray. On an NVIDIA H200 a Panda query checks 71,070 configurations a second in
queries of 1,024, 124,714 in queries of 4,096 and 154,791 in queries of 16,384
(``benchmarks/results/robots.md``); a query the device cannot hold is split."""

QUERY_SECONDS = 2.0
"""Wall seconds a batched query of :meth:`Robot.check` aims at when no ``batch`` is given:
batches start at :data:`FIRST_BATCH` configurations and grow (at most doubling) while queries
take less, up to :data:`GPU_BODIES_PER_QUERY` bodies on a GPU and
:data:`DEFAULT_BODIES_PER_QUERY` on a CPU adapter, so that a slow adapter (a CPU driver) gets
small batches, far from the GPU timeout, and a fast GPU large ones."""

FIRST_BATCH = 8
"""Configurations of the first batched query of a check (see :data:`QUERY_SECONDS`)."""

GPU_FRONT_FROM = 1
"""Fewest configurations of a batch whose poses and pair cull run on the GPU (passes K1 and K2)
where the device runs them: every batch, so that a configuration's poses, and so its pairs
within the tolerance's band, never depend on the batch it is checked in (K1's single precision
and the host's double place a body apart by up to K1's error estimate). A batch of a few
configurations spends more host CPU on the passes' own submission and map than the host's
kinematics would: on lavapipe 1.3-1.5 times the host path's in queries of one; from 32 a query
K1/K2 take less (115 against 128 us a Panda configuration), and on an NVIDIA H200 they check
more configurations a second from 32 for the Panda and from 16 for the Unitree A1
(``benchmarks.batch.run_front_sweep`` in the checkout, ``benchmarks/results/robots.md``). The
benchmarks set it above a batch's size to time the host's path."""

CHECK_OPTIONS = {"records": "none", "broad_phase": "numpy"}
"""The options of a robot's detectors (a batch's candidates are its pair list, culled by world
boxes: no sweep runs, and no records are read)."""

PLANS_KEPT = 8
"""Check plans kept (one per environment, self-collision choice and matrix), each with its
bodies prepared once it has run; the oldest is dropped first."""


@dataclass
class _Plan:
    """The pairs of one configuration a check tests, and the bodies they name (indices into the
    bodies of a check: robot, attached, environment)."""

    used: np.ndarray
    """(U,) int64: the bodies some checked pair names, in order: a configuration's copies."""
    pairs: np.ndarray
    """(P, 2) int64: the pairs checked, as positions in :attr:`used`, ``i < j``, sorted."""
    prepared: PreparedBodies | None = None
    """The check's bodies, prepared once (made by the first batch)."""
    front: GpuPairCull | None = None
    """Its passes K1 and K2 on the GPU (made by the first batch that takes its poses there)."""
    bounds: np.ndarray | None = None
    """(U, 2, 3) float64: the bounds of the meshes of :attr:`used`, read once (a plan is kept by
    its bodies' meshes)."""

    @classmethod
    def of(cls, pairs: list[tuple[int, int]]) -> _Plan:
        """The plan of the checked pairs ``pairs`` (of the check's bodies)."""
        flat = np.array(pairs, dtype=np.int64).reshape(-1, 2)
        used, at = np.unique(flat, return_inverse=True)
        return cls(used, at.reshape(-1, 2))

    @property
    def bodies(self) -> int:
        """Copies of one configuration's bodies in a query."""
        return len(self.used)

    def batch(self, count: int) -> PairList:
        """The pairs of ``count`` configurations whose bodies are copied in order, a
        configuration's copies after the last's."""
        offsets = np.arange(count, dtype=np.int64)[:, None, None] * self.bodies
        return PairList((offsets + self.pairs[None]).reshape(-1, 2))


@dataclass
class _Poses:
    """Every body's pose of a check's batch: the robot's and attached objects' rows, and the
    environment's bodies' fixed poses."""

    rows: np.ndarray
    """(C, R, 3, 4) float: per configuration, world from body of the robot's bodies and attached
    objects (their top three rows; pass K1's float32, or the host's float64)."""
    fixed: np.ndarray
    """(E, 4, 4) float64: world from body of the environment's bodies."""
    boxes: np.ndarray | None = None
    """(C, R, 2, 4) float32: world boxes of the robot's bodies (pass K1's), or None (measured
    by the query's scene)."""
    fixed_boxes: np.ndarray | None = None
    """(B, 2, 3) float64: world boxes of the environment's bodies (rows of the check's bodies;
    with :attr:`boxes`)."""

    def __len__(self) -> int:
        return len(self.rows)

    def take_boxes(self, config: np.ndarray, body: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray] | None:
        """World box minima and maxima (M, 3) float64 of bodies ``body`` (M,) in configurations
        ``config`` (M,); None without :attr:`boxes`."""
        if self.boxes is None:
            return None
        at, fixed = self._at(config, body)
        out = np.empty((len(body), 2, 3))
        out[:] = self.boxes.reshape(-1, 2, 4).take(at, axis=0)[:, :, :3]
        out[fixed] = self.fixed_boxes[body[fixed]]
        return out[:, 0], out[:, 1]

    def _at(self, config: np.ndarray, body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each (config, body)'s row among the robot's (C * R) rows (0 for a fixed body), and
        which are fixed bodies."""
        moving = self.rows.shape[1]
        fixed = body >= moving
        at = config * moving + body
        at[fixed] = 0
        return at, fixed

    def take(self, config: np.ndarray, body: np.ndarray) -> np.ndarray:
        """(M, 4, 4) float64 poses of bodies ``body`` (M,) (of the check) in configurations
        ``config`` (M,)."""
        at, fixed = self._at(config, body)
        out = np.empty((len(body), 4, 4))
        out[:, :3] = self.rows.reshape(-1, 3, 4).take(at, axis=0)
        out[:, 3] = (0.0, 0.0, 0.0, 1.0)
        out[fixed] = self.fixed[body[fixed] - self.rows.shape[1]]
        return out


class _CopyNames(Sequence):
    """The names of a batch's copies of the bodies, made when read (a message names one):
    ``configuration C: body``."""

    def __init__(self, bodies: list[Body], body: np.ndarray, config: np.ndarray, first: int
                 ) -> None:
        self.bodies, self.body, self.config, self.first = bodies, body, config, first

    def __len__(self) -> int:
        return len(self.body)

    def __getitem__(self, i: Any) -> Any:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        i = int(i)
        if not -len(self) <= i < len(self):
            raise IndexError(f"copy {i} of {len(self)}")
        return (f"configuration {self.first + int(self.config[i])}: "
                f"{self.bodies[int(self.body[i])].name}")


class Robot(RobotModel):
    """A robot's links, joints and collision bodies, and checks of its configurations.

    Made by :meth:`from_urdf`. Configurations are (C, J) joint values in the order of
    :attr:`joint_names` (the actuated joints: not fixed, not mimicking another).

    Attributes
    ----------
    name : str
    root : str
        The root link.
    links : list of str
        Every link, in tree order.
    bodies : list of Body
        Collision bodies of the links.
    joint_names : list of str
        The actuated joints, in tree order: a configuration's columns.
    limits : (J, 2) float
        Lower and upper limits (continuous joints: -pi, pi).
    allowed : AllowedCollisionMatrix
        Pairs never checked (see :meth:`compute_allowed_collisions`).
    tolerance : float or None
        World units of the tolerance contract (see :mod:`pycinder.request`); None: 1% of the
        smaller body's size, per pair.
    source : str
        The URDF file's name, for messages.
    """
    # -- pairs ----------------------------------------------------------------------------

    def _all_bodies(self, environment: Environment | None) -> list[Body]:
        return self.bodies + [a.body for a in self._attached.values()] + \
            (environment.bodies if environment is not None else [])

    def checked_pairs(self, environment: Environment | None = None, *,
                      self_collision: bool = True) -> list[tuple[str, str]]:
        """The pairs of names a check tests: bodies on different links, not allowed by
        :attr:`allowed`, robot against environment; sorted."""
        bodies = self._all_bodies(environment)
        return sorted({tuple(sorted((_owner(bodies[i]), _owner(bodies[j]))))
                       for i, j in self._pair_list(environment, self_collision)})

    def _pair_list(self, environment: Environment | None, self_collision: bool
                   ) -> list[tuple[int, int]]:
        bodies = self._all_bodies(environment)
        nr = len(self.bodies)
        na = len(self._attached)
        touch = [a.touch for a in self._attached.values()]
        kind = ["robot"] * nr + ["attached"] * na + ["env"] * (len(bodies) - nr - na)
        allowed = self.allowed
        out = []
        for i in range(len(bodies)):
            for j in range(i + 1, len(bodies)):
                ki, kj = kind[i], kind[j]
                if ki == "env" and kj == "env":
                    continue
                if not self_collision and ki != "env" and kj != "env":
                    continue
                a, b = _owner(bodies[i]), _owner(bodies[j])
                if a == b or allowed.allowed(a, b):
                    continue
                if ki == "robot" and kj == "attached" and bodies[i].link in touch[j - nr]:
                    continue
                out.append((i, j))
        return out

    def _plan(self, environment: Environment | None, self_collision: bool
              ) -> tuple[_Plan, list[Body]]:
        bodies = self._all_bodies(environment)
        # The bodies by name and mesh (a plan holds their meshes, prepared, once it has run:
        # an environment whose bodies changed gets a plan of its own).
        key = (tuple((b.name, id(b.mesh)) for b in bodies), self_collision, len(self.allowed),
               hash(tuple(self.allowed.pairs())))
        plan = self._plans.get(key)
        if plan is None:
            if len(self._plans) >= PLANS_KEPT:
                self._plans.pop(next(iter(self._plans)))  # the oldest, and its prepared meshes
            plan = self._plans[key] = _Plan.of(self._pair_list(environment, self_collision))
        return plan, bodies

    # -- checks ---------------------------------------------------------------------------

    @property
    def detector(self) -> Detector:
        """The detector of the checks (made on first use: ``records="none"``, and the broad
        phase in NumPy: a batch's candidates are its pair list, culled by world boxes)."""
        if self._detector is None:
            from ..detector import Detector

            self._detector = Detector(**CHECK_OPTIONS)
        return self._detector

    def in_collision(self, q: Any, *, environment: Environment | None = None,
                     self_collision: bool = True) -> bool:
        """Whether configuration ``q`` (J,) collides (see :meth:`check`)."""
        q = np.asarray(q, np.float64)
        if q.ndim != 1:
            raise ValueError(f"{self.name}: in_collision takes one configuration ({self.dof} "
                             f"joint values), got shape {q.shape}; use check for many")
        return bool(self.check(q[None], environment=environment,
                               self_collision=self_collision)[0])

    def check(self, qs: Any, *, environment: Environment | None = None,
              self_collision: bool = True, return_pairs: bool = False,
              batch: int | None = None, padding: Any = None, pad_self_collision: bool = False
              ) -> np.ndarray | tuple[np.ndarray, list[list[tuple[str, str]]]]:
        """Which configurations collide: with themselves (pairs of links on different links,
        less :attr:`allowed`), with attached objects, and with the environment.

        Parameters
        ----------
        qs : (C, J) float
            Configurations, columns in :attr:`joint_names` order.
        environment : Environment, optional
            Fixed bodies to check the robot and its attached objects against.
        self_collision : bool
            Check the robot's own pairs (False: only against the environment).
        return_pairs : bool
            Also return, per configuration, the colliding pairs of names (link, attached object
            or environment body names), each pair sorted, the list sorted.
        batch : int, optional
            Configurations per query. Default: paced, from :data:`FIRST_BATCH` configurations
            growing while queries take less than :data:`QUERY_SECONDS`, up to
            :data:`GPU_BODIES_PER_QUERY` bodies per query on a GPU
            (:data:`DEFAULT_BODIES_PER_QUERY` on a CPU adapter). A batch too large for the
            device's pixel budget or memory is split.
        padding : float or dict of str to float, optional
            MoveIt's padding, in world units: one for every link, or per link or attached
            object name (names left out: 0). It applies against the environment: a link and an
            environment body collide when their surfaces are closer than the link's padding;
            self-collision is checked unpadded, as MoveIt checks it (see the module's
            docstring), unless ``pad_self_collision``.
        pad_self_collision : bool
            Pad the robot's own pairs too: two links (or attached objects) collide when their
            surfaces are closer than the sum of their paddings.

        Returns
        -------
        collides : (C,) bool
        pairs : list of list of (str, str)
            Only with ``return_pairs``.
        """
        if not all(isinstance(x, bool) for x in (self_collision, return_pairs,
                                                 pad_self_collision)):
            raise ValueError("self_collision, return_pairs and pad_self_collision must be True "
                             "or False")
        if environment is not None and not isinstance(environment, Environment):
            raise TypeError(f"environment must be a pycinder.robot.Environment, got "
                            f"{type(environment).__name__}")
        qs = self._configurations(qs)
        plan, bodies = self._plan(environment, self_collision)
        pads = self._paddings(padding, bodies)
        collides = np.zeros(len(qs), dtype=bool)
        pairs: list[list[tuple[str, str]]] = [[] for _ in range(len(qs))]
        # How many configurations each pair of bodies collides in, where there are enough of
        # them to tell a pair that always touches (see _warn_always).
        counts = np.zeros((len(bodies),) * 2, np.int64) if len(qs) >= ALWAYS_SAMPLES else None
        for start, stop in self._batches(len(qs), batch, plan):
            self._check_batch(qs[start:stop], start, plan, bodies, collides,
                              pairs if return_pairs else None, pads, counts,
                              pad_self=pad_self_collision)
        if counts is not None:
            self._warn_always(counts, len(qs), bodies)
        return (collides, pairs) if return_pairs else collides

    def _warn_always(self, counts: np.ndarray, checked: int, bodies: list[Body]) -> None:
        """Warn, once per pair, of the robot's own pairs (links, attached objects) in collision
        in nearly all of ``checked`` configurations (:func:`~.acm.always_colliding`);
        ``counts`` (B, B): configurations each pair of ``bodies`` collided in."""
        robot = len(self.bodies) + len(self._attached)
        owners = [_owner(b) for b in bodies[:robot]]
        names = sorted(set(always_colliding(counts[:robot, :robot], checked, owners))
                       - self._warned_always)
        if names:
            from ..errors import warn_at_caller

            self._warned_always.update(names)
            warn_at_caller(AlwaysCollidingWarning.of(self.name, names, checked))

    def _gpu_front(self, plan: _Plan, bodies: list[Body], clearance: float | None
                   ) -> GpuPairCull | None:
        """Passes K1 and K2 of a check: the robot's poses and the plan's pairs culled by world
        boxes, on the GPU (:mod:`pycinder.robot.k2_pair_cull`; made once per plan, and again when
        the objects attached or the device changed; the environment's poses placed anew). None
        where the plan checks no pair, and where, for some checked pair, K1's poses of its
        bodies may lie farther from float64's than
        :data:`~pycinder.robot.k1_kinematics.POSE_MARGIN` of the tolerance the query gives the
        pair (:meth:`GpuKinematics.error_estimate`, both bodies' added): the host's
        :meth:`poses` and box test then. ``clearance``: a padded check's (its queries test
        at most a quarter of it finely)."""
        from .k2_pair_cull import GpuPairCull
        from .k1_kinematics import POSE_MARGIN, GpuKinematics

        if not len(plan.pairs):
            return None
        gpu = self.detector.gpu
        attached = tuple(id(a.body) for a in self._attached.values())
        kinematics = self._kinematics
        if kinematics is None or kinematics.gpu is not gpu or kinematics.attached != attached:
            with self.detector._device_lock():
                kinematics = self._kinematics = GpuKinematics(self, gpu,
                                                              self.detector.request.timeout)
        robot = len(self.bodies) + len(self._attached)
        sources = np.where(plan.used < robot, plan.used, -1)
        used = [bodies[i] for i in plan.used]
        origins = np.array([b.origin for b in used]).reshape(-1, 4, 4)
        if plan.bounds is None:
            plan.bounds = np.array([b.mesh.bounds for b in used], np.float64).reshape(-1, 2, 3)
        bounds = plan.bounds
        # Per checked pair, both bodies' estimates against the tolerance its query gives it.
        error = kinematics.errors_of(sources)
        a, b = plan.pairs[:, 0], plan.pairs[:, 1]
        given = self.tolerance if self.tolerance is not None else \
            self.detector.request.tolerance
        if given is not None:
            pair_tolerances = np.full(len(a), float(given))
        elif clearance is not None:
            pair_tolerances = np.full(len(a), np.inf)
        else:  # the default: of the smaller body's size, placed by its origin
            size = body_sizes(bounds[:, 0], bounds[:, 1], origins)
            pair_tolerances = DEFAULT_RELATIVE_TOLERANCE * np.minimum(size[a], size[b])
        if clearance is not None:  # a padded check tests within a quarter of its clearance
            pair_tolerances = np.minimum(pair_tolerances, clearance / 4)
        if not (error[a] + error[b] <= POSE_MARGIN * pair_tolerances).all():
            return None
        fixed = np.where((sources < 0)[:, None, None], origins, np.eye(4))
        if plan.front is None or plan.front.kinematics is not kinematics:
            with self.detector._device_lock():
                plan.front = GpuPairCull(kinematics, sources, fixed, bounds[:, 0],
                                         bounds[:, 1], plan.pairs)
        else:  # an environment of the same meshes may have moved them
            with self.detector._device_lock():
                plan.front.place(fixed)
        return plan.front

    def _reach_runs(self, qs: np.ndarray, plan: _Plan, bodies: list[Body],
                    clearance: float | None) -> list[tuple[int, int]]:
        """The runs of consecutive configurations of ``qs`` that take one path, K1's or the
        host's (:meth:`_gpu_batch`), decided for each configuration alone: a configuration
        whose joint values K1's estimate does not hold for takes the host's poses in any batch,
        and the others K1's. One run where every configuration takes the same path."""
        from ..errors import GpuError

        if len(qs) < GPU_FRONT_FROM:
            return [(0, len(qs))]
        try:
            front = self._gpu_front(plan, bodies, clearance)
        except GpuError:  # its buffers or pipelines could not be made: the next check anew
            self._forget_fronts()
            raise
        if front is None:
            return [(0, len(qs))]
        inside = front.kinematics.reaches_each(qs)
        cuts = np.flatnonzero(inside[1:] != inside[:-1]) + 1
        edges = [0, *cuts.tolist(), len(qs)]
        return list(zip(edges[:-1], edges[1:]))

    def _gpu_batch(self, qs: np.ndarray, plan: _Plan, bodies: list[Body],
                   clearance: float | None) -> GpuPairCull | None:
        """Passes K1 and K2 for a batch of configurations ``qs``, or None where the host makes
        its poses and box test: fewer than :data:`GPU_FRONT_FROM` configurations, a
        :meth:`_gpu_front` of None, or joint values outside what K1's estimate holds for."""
        from ..errors import GpuError

        if len(qs) < GPU_FRONT_FROM:
            return None
        try:
            front = self._gpu_front(plan, bodies, clearance)
        except GpuError:  # its buffers or pipelines could not be made: the next check anew
            self._forget_fronts()
            raise
        return front if front is not None and front.kinematics.reaches(qs) else None

    def _forget_fronts(self) -> None:
        """Drop passes K1 and K2, and the padded checks' detectors (after a GPU error: the next
        check makes them anew, on the detector's device)."""
        self._kinematics = None
        self._padded.clear()
        for plan in self._plans.values():
            plan.front = None

    def _batches(self, count: int, batch: int | None, plan: _Plan) -> Iterator[tuple[int, int]]:
        """``(start, stop)`` of each query's configurations: ``batch`` at a time when given;
        else paced (see :data:`QUERY_SECONDS`), the time between one range and the next being
        the caller's query. None for a check with nothing to query (its cap asks the
        detector's device, which such a check need not start)."""
        given = None if batch is None else self._batch_size(batch, plan)  # checked always
        if count == 0 or not len(plan.pairs):
            return
        most = self._batch_size(None, plan) if given is None else given
        size = most if batch is not None else min(FIRST_BATCH, most)
        start = 0
        while start < count:
            t0 = time.perf_counter()
            yield start, min(start + size, count)
            start += size
            if batch is None:
                pace = QUERY_SECONDS / max(time.perf_counter() - t0, 1e-3)
                size = max(1, min(most, int(size * min(pace, 2.0))))

    def _paddings(self, padding: Any, bodies: list[Body]) -> np.ndarray | None:
        """(B,) the padding of each body of a check (None without padding)."""
        if padding is None:
            return None
        robot = len(self.bodies) + len(self._attached)
        links = len(self.bodies)
        if isinstance(padding, dict):
            known = set(self.links) | set(self._attached)
            unknown = sorted(set(padding) - known)
            if unknown:
                raise ValueError(f"{self.name}: padding names {unknown[:3]}, which are neither "
                                 "links nor attached objects")
            values = [padding.get(_owner(b), 0.0) if k < robot else 0.0
                      for k, b in enumerate(bodies)]
        else:  # the links' padding (attached objects are padded only by name)
            values = [padding if k < links else 0.0 for k in range(len(bodies))]
        pads = np.array([float(v) if isinstance(v, (int, float, np.floating))
                         and not isinstance(v, bool) else np.nan for v in values])
        if not np.isfinite(pads).all() or (pads < 0).any():
            raise ValueError(f"{self.name}: padding must be non-negative world units, got "
                             f"{padding!r}")
        return pads if pads.any() else None

    def _padded_detector(self, clearance: float) -> Detector:
        """The detector of padded checks whose largest padding sum is ``clearance``."""
        from ..detector import Detector

        cache = self._padded
        if clearance not in cache:
            while len(cache) >= 2:  # a check's host batches' and GPU batches' (see _query)
                cache.pop(next(iter(cache)))
            cache[clearance] = Detector(**CHECK_OPTIONS, clearance=clearance,
                                        strict=self.detector.request.strict)
        return cache[clearance]

    def _batch_size(self, batch: int | None, plan: _Plan) -> int:
        if batch is None:
            most = DEFAULT_BODIES_PER_QUERY if self.detector.gpu.cpu_adapter \
                else GPU_BODIES_PER_QUERY
            return max(1, most // max(plan.bodies, 1))
        if isinstance(batch, bool) or not isinstance(batch, (int, np.integer)) or batch < 1:
            raise ValueError(f"batch must be a positive whole number of configurations, got "
                             f"{batch!r}")
        return int(batch)

    def _check_poses(self, qs: np.ndarray, environment: Environment | None) -> np.ndarray:
        """(C, B, 4, 4): every body's pose of a check (robot, attached, then environment, as
        :meth:`_all_bodies` orders them) in each configuration ``qs`` (C, J)."""
        poses = self.poses(qs)
        if environment is None or not len(environment):
            return poses
        env = np.array([b.origin for b in environment.bodies])
        return np.concatenate([poses, np.broadcast_to(env, (len(poses), *env.shape))], axis=1)

    def _check_batch(self, qs: np.ndarray, start: int, plan: _Plan, bodies: list[Body],
                     collides: np.ndarray, pairs: list[list[tuple[str, str]]] | None,
                     pads: np.ndarray | None = None, counts: np.ndarray | None = None, *,
                     pad_self: bool = False) -> None:
        from ..errors import GpuError, GpuMemoryError

        if not len(plan.pairs) or not len(qs):
            return
        clearance = None if pads is None else max(
            float(pads.max()) if not pad_self else float(pads[plan.used][plan.pairs].sum(1).max()),
            1e-12)
        runs = self._reach_runs(qs, plan, bodies, clearance)
        if len(runs) > 1:  # K1 takes some configurations, the host the others: each alone
            for first, end in runs:
                self._check_batch(qs[first:end], start + first, plan, bodies, collides, pairs,
                                  pads, counts, pad_self=pad_self)
            return
        try:
            survivors = boxes = fixed_boxes = slack = None
            front = self._gpu_batch(qs, plan, bodies, clearance)
            if front is None:
                rows = self.poses(qs)[..., :3, :]
            else:
                with self.detector._device_lock():
                    try:
                        rows, boxes, survivors = front.run(qs, clearance or 0.0)
                    except GpuMemoryError:
                        raise
                    except (GpuError, wgpu.GPUError) as exc:
                        self._forget_fronts()
                        raise self.detector._recover(exc) from exc
                fixed_boxes = np.zeros((len(bodies), 2, 3))
                fixed_boxes[plan.used] = front.fixed
                slack = np.zeros(len(bodies))
                slack[plan.used] = front.error
            fixed = np.array([b.origin for b in bodies[len(rows[0]):]]).reshape(-1, 4, 4)
            poses = _Poses(rows, fixed, boxes, fixed_boxes)
            config, a, b = self._query(poses, start, plan, bodies, pads, clearance, survivors,
                                       slack, pad_self=pad_self)
        except GpuMemoryError:
            if len(qs) == 1:
                raise
            half = len(qs) // 2
            for first, end in ((0, half), (half, len(qs))):
                self._check_batch(qs[first:end], start + first, plan, bodies, collides, pairs,
                                  pads, counts, pad_self=pad_self)
            return
        collides[start + config] = True
        if counts is not None:
            np.add.at(counts, (a, b), 1)
        if pairs is not None:
            owners = [_owner(body) for body in bodies]
            found: dict[int, set[tuple[str, str]]] = {}
            for c, i, j in zip(config.tolist(), a.tolist(), b.tolist()):
                found.setdefault(c, set()).add(tuple(sorted((owners[i], owners[j]))))
            for c, names in found.items():
                pairs[start + c] = sorted(names)

    def _query(self, poses: _Poses, start: int, plan: _Plan, bodies: list[Body],
               pads: np.ndarray | None, clearance: float | None = None,
               survivors: np.ndarray | None = None, slack: np.ndarray | None = None, *,
               pad_self: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One query of a batch of configurations (``poses``: each body's pose in each):
        copies of the check's bodies, prepared once, in one scene whose only candidates are each
        configuration's checked pairs (a :class:`~pycinder.focused.broad.broad_numpy.PairList`,
        culled by their world boxes). Without ``survivors``, a copy per configuration of every
        body some checked pair names, the pairs culled by the host's boxes; with them (pass K2's
        (S, 3): configuration and positions in ``plan.used``), copies of the bodies of the
        pairs kept alone, and those pairs the candidates, the scene's world boxes K1's; a
        padded check then keeps a pair within its padding plus both bodies' K1 error estimates
        (``slack`` (B,), per body of the check). Returns the pairs found: each one's
        configuration (index into the batch) and bodies ``a``, ``b`` (indices into
        ``bodies``), (P,) each; with padding, each pair kept by its own padding (environment
        pairs by the robot body's, the robot's own pairs by none, MoveIt's, or with
        ``pad_self`` by the sum of both bodies')."""
        used = plan.used
        if plan.prepared is None:
            plan.prepared = self.detector.prepare([bodies[i].mesh for i in used],
                                                  names=[bodies[i].name for i in used])
        per, count = plan.bodies, len(poses)
        if survivors is None:
            copy = np.arange(per * count)  # configuration * per + position in used
            candidates = plan.batch(count)
        else:
            first, second = survivors[:, 0] * per + survivors[:, 1], \
                survivors[:, 0] * per + survivors[:, 2]
            kept = np.zeros(per * count, dtype=bool)
            kept[first] = kept[second] = True
            copy = np.flatnonzero(kept)
            slot = np.cumsum(kept) - 1  # a kept copy's index among the copies
            candidates = PairList(np.stack([slot[first], slot[second]], axis=1), culled=True)
        config, body = copy // per, copy % per
        names = _CopyNames(bodies, used[body], config, start)
        transforms = poses.take(config, used[body])
        if poses.boxes is None:  # the host's float64 poses: checked like any query's
            scene = plan.prepared.copies(body, transforms, names)
        else:  # pass K1's: finite and proper, with their world boxes
            scene = plan.prepared._copies(body, transforms, names,
                                          poses.take_boxes(config, used[body]))
        body_tolerances = np.full(len(copy), self._tolerance_value)
        if pads is None:
            result = self.detector._find_within(scene, candidates, body_tolerances)
        else:
            # At K1's poses each body may lie its error estimate (``slack``) off float64's:
            # pairs that close to their padding are measured and kept.
            reach = clearance if slack is None else clearance + 2.0 * float(slack.max())
            result = self._padded_detector(reach)._find_within(scene, candidates,
                                                               body_tolerances)
        found = result.pairs
        config, a, b = config[found[:, 0]], used[body[found[:, 0]]], used[body[found[:, 1]]]
        if pads is None:
            return config, a, b
        robot = len(self.bodies) + len(self._attached)
        limit = pads[a] + pads[b] if pad_self else \
            np.where((a >= robot) | (b >= robot), pads[a] + pads[b], 0.0)
        if slack is not None:
            limit = np.where(limit > 0, limit + slack[a] + slack[b], 0.0)
        keep = result.distances < limit + result.distance_errors
        return config[keep], a[keep], b[keep]

    @property
    def _tolerance_value(self) -> float:
        """The checks' tolerance in world units; NaN for the detector's own (per pair)."""
        from ..joined_scenes import scene_tolerances

        return float(scene_tolerances(self.tolerance, 1, [self.name])[0])

    def interpolate(self, qs: Any, resolution: float) -> np.ndarray:
        """A path through waypoints ``qs`` (W, J), linearly interpolated so that no joint moves
        more than ``resolution`` between consecutive configurations (radians or metres).

        Returns
        -------
        (M, J) float64
            Starts with the first waypoint and ends with the last; every waypoint is on it.
        """
        qs = self._configurations(qs)
        if isinstance(resolution, bool) or not isinstance(resolution, (int, float)) or \
                not math.isfinite(resolution) or resolution <= 0:
            raise ValueError(f"resolution must be a positive number, got {resolution!r}")
        parts = [qs[:1]]
        for a, b in zip(qs[:-1], qs[1:]):
            steps = max(1, int(math.ceil(np.abs(b - a).max() / resolution - 1e-12)))
            s = np.arange(1, steps + 1)[:, None] / steps
            parts.append(a + s * (b - a))
        return np.concatenate(parts)

    def check_path(self, qs: Any, resolution: float = 0.01, *,
                   environment: Environment | None = None, self_collision: bool = True,
                   batch: int | None = None, padding: Any = None,
                   pad_self_collision: bool = False) -> int | None:
        """The first colliding configuration of a path, densely interpolated.

        Parameters
        ----------
        qs : (W, J) float
            Waypoints.
        resolution : float
            Most a joint moves between checked configurations (see :meth:`interpolate`).
        environment, self_collision, batch, padding, pad_self_collision
            As :meth:`check`; batches are checked in order and the check stops at the first
            batch with a collision.

        Returns
        -------
        int or None
            Index into ``robot.interpolate(qs, resolution)`` of the first configuration that
            collides; None when none does.
        """
        path = self.interpolate(qs, resolution)
        plan, _ = self._plan(environment, self_collision)
        for start, stop in self._batches(len(path), batch, plan):
            hit = self.check(path[start:stop], environment=environment,
                             self_collision=self_collision, batch=stop - start,
                             padding=padding, pad_self_collision=pad_self_collision)
            if hit.any():
                return start + int(np.flatnonzero(hit)[0])
        return None

    # -- the allowed-collision matrix -----------------------------------------------------

    def adjacent_links(self) -> list[tuple[str, str]]:
        """Pairs of links with collision geometry that MoveIt's Setup Assistant calls adjacent:
        joined by a joint, or through links without collision geometry (sorted pairs)."""
        geometric = {b.link for b in self.bodies}
        neighbours: dict[str, set[str]] = {n: set() for n in self.links}
        for j in self.joints:
            neighbours[j.parent].add(j.child)
            neighbours[j.child].add(j.parent)
        out = set()
        for start in geometric:
            seen, todo = {start}, [start]
            while todo:
                n = todo.pop()
                for m in neighbours[n]:
                    if m in seen:
                        continue
                    seen.add(m)
                    if m in geometric:
                        out.add(tuple(sorted((start, m))))
                    else:
                        todo.append(m)
        return sorted(out)

    def compute_allowed_collisions(self, samples: int = 10_000, *, seed: int = 0,
                                   always_fraction: float = ALWAYS_FRACTION,
                                   always_samples: int = ALWAYS_SAMPLES,
                                   batch: int | None = None) -> AllowedCollisionMatrix:
        """An allowed-collision matrix made by MoveIt Setup Assistant's rules, in its order
        (a pair takes the first reason that applies):

        1. ``Adjacent``: :meth:`adjacent_links`;
        2. ``Default``: pairs in collision in :meth:`default_configuration`;
        3. ``Always``: pairs in collision in at least ``always_fraction`` of the first
           ``always_samples`` random configurations;
        4. ``Never``: pairs in collision in none of ``samples`` random configurations.

        Random configurations are uniform within the joint limits, from ``seed``; the checks are
        :meth:`check`'s, without :attr:`allowed` and without attached objects.

        Returns
        -------
        AllowedCollisionMatrix
            A new matrix (assign it to :attr:`allowed`, or write it with
            :meth:`AllowedCollisionMatrix.write_srdf`).
        """
        if not isinstance(samples, (int, np.integer)) or samples < 1:
            raise ValueError(f"samples must be a positive whole number, got {samples!r}")
        if not 0 < always_fraction <= 1:
            raise ValueError(f"always_fraction must be in (0, 1], got {always_fraction!r}")
        saved, attached, warned = self.allowed, self._attached, set(self._warned_always)
        try:
            self.allowed, self._attached = AllowedCollisionMatrix(), {}
            self._plans.clear()
            _, default = self.check(self.default_configuration()[None], return_pairs=True)
            qs = self.random_configurations(max(samples, always_samples), seed)
            with warnings.catch_warnings():  # its "Always" pairs are what it is looking for
                warnings.simplefilter("ignore", AlwaysCollidingWarning)
                _, found = self.check(qs, return_pairs=True, batch=batch)
        finally:
            self.allowed, self._attached, self._warned_always = saved, attached, warned
            self._plans.clear()
        return matrix_from_samples(self.adjacent_links(), default[0], found,
                                   sorted({b.link for b in self.bodies}), samples=samples,
                                   always_samples=always_samples,
                                   always_fraction=always_fraction)

    def write_srdf(self, path: str | Path) -> None:
        """Write :attr:`allowed` as an SRDF file."""
        self.allowed.write_srdf(path, self.name)


def _owner(body: Body) -> str:
    """The name a body's collisions are reported under: its link (robot), its own name
    (attached object, environment body)."""
    return body.name if body.source == "attached" else body.link


# ---------------------------------------------------------------------------------------------
# URDF pieces

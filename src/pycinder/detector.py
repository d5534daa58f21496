"""The Detector: a request, the GPU resources that serve it, and one query after another.

    request (checked once) + bodies + transforms
      -> scene (validated shapes, cached by content)
      -> strategy: focused (broad phase -> tiles -> passes F0-F8 -> readback)
                   or scene (views -> passes 1-7 -> filter -> readback mode)
      -> CollisionResult
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import wgpu

from .joined_scenes import join_scenes, split
from .errors import GpuError, GpuTimeoutError, with_message
from .focused.broad.broad_numpy import PairList
from .focused.focused_strategy import FocusedStrategy
from .gpu.device import (check_not_forked, device_lost, fork_generation, get_gpu,
                         keep_from_parent, renew_gpu)
from .request import CollisionRequest
from .result import CollisionResult, Stats
from .scene import PreparedBodies, Scene, ShapeCache, prepare_scene
from .scene.prepared import check_body_count
from .strategy import Pending, Query, Strategy, refuse
from .view import View
from .wholescene.scene_strategy import WholeSceneStrategy

STRATEGIES: dict[str, type[Strategy]] = {"focused": FocusedStrategy, "scene": WholeSceneStrategy}
"""The strategies by the name a request gives (``CollisionRequest.strategy``)."""


class Detector:
    """Collision detection with GPU pipelines and buffers kept between calls.

    Parameters
    ----------
    request : CollisionRequest, optional
        Every option at once; keywords below build one (or change the given one).
    **options
        Options of :class:`~pycinder.CollisionRequest`: ``tolerance``, ``strategy``,
        ``resolution``, ``self_interference``, ``readback``, ``encode``, ``strict``,
        ``contacts`` (every query keeps what ``result.contacts()`` needs), ...

    Examples
    --------
    A ball moving along a box, one query per frame on one detector:

    >>> import numpy as np, trimesh, pycinder
    >>> meshes = [trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)]
    >>> frames = np.tile(np.eye(4), (3, 2, 1, 1))     # (frames, N, 4, 4) world from body
    >>> frames[:, 1, 0, 3] = [0.6, 1.0, 2.0]           # the ball's x in each frame
    >>> det = pycinder.Detector(tolerance=1e-3)
    >>> for transforms in frames:
    ...     print(det.find_collisions(meshes, transforms).pairs.tolist())
    [[0, 1]]
    []
    []

    Meshes that only move can be checked once (:meth:`prepare`):

    >>> bodies = det.prepare(meshes, names=["box", "ball"])
    >>> [det.find_collisions(bodies, transforms).pair_names() for transforms in frames]
    [{('ball', 'box')}, set(), set()]
    """

    def __init__(self, request: CollisionRequest | None = None, /, **options: Any) -> None:
        if request is not None and not isinstance(request, CollisionRequest):
            raise TypeError(
                f"Detector's first argument is a CollisionRequest, got {request!r}; pass options "
                "by name (for the paper's whole-scene image: strategy='scene', resolution=1024)")
        if request is None:
            request = CollisionRequest(**options)
        elif options:
            request = request.replace(**options)
        self.request = request
        self.gpu = get_gpu()
        self.shapes = ShapeCache()
        self._generation = fork_generation()
        self._lock = self.gpu.lock  # one query at a time on the device, from any thread
        with self._lock:  # pipelines and buffers are made on the device too
            self.strategy: Strategy = self._make_strategy()

    @property
    def in_this_process(self) -> bool:
        """Whether this detector's GPU device belongs to this process: False in a process forked
        after the detector was made, where using it raises
        :class:`~pycinder.ForkedProcessError` (make a new detector there)."""
        return self._generation == fork_generation()

    def _device_lock(self) -> threading.RLock:
        """The lock that gives one query at a time the device, once this detector is known to
        belong to this process (checked before taking it: a lock held by a parent's thread at a
        fork is never released in the child)."""
        check_not_forked(self._generation, "this Detector")
        return self._lock

    def _make_strategy(self) -> Strategy:
        return STRATEGIES[self.request.strategy](self.gpu, self.request)

    def _recover(self, exc: Exception) -> GpuError:
        """After a GPU error: rebuild the strategy's pipelines and buffers (on a new device
        where the device was lost), so that the next query starts clean, and say so in the
        error."""
        lost = device_lost(self.gpu, exc)
        try:
            if lost is not None:
                self.gpu = renew_gpu(self.gpu)
            self.strategy = self._make_strategy()
        except Exception as again:  # the device itself is gone
            return with_message(exc, f"{exc}; the GPU device could not be used again "
                                     f"({again}): recreate the Detector in a new process",
                                lost=lost is not None)
        return with_message(exc, f"{exc} (the device was lost: the detector made a new device "
                                 "and can be used again)" if lost is not None else
                            f"{exc} (the detector was reset and can be used again)",
                            lost=lost is not None)

    def prepare(self, bodies: Sequence[Any], names: Sequence[str | None] | None = None
                ) -> PreparedBodies:
        """Check and measure meshes once, for queries that change only their transforms.

        Parameters
        ----------
        bodies : sequence of trimesh.Trimesh or (vertices (V, 3), faces (F, 3)) pairs
        names : sequence of str, optional
            Body names for error messages and results.

        Returns
        -------
        PreparedBodies
            Pass it to :meth:`find_collisions` or :meth:`submit` in place of the bodies: a query
            then checks only the transforms. The meshes are taken as they are now; tell
            vertices that change with :meth:`PreparedBodies.update`.

        Raises
        ------
        ValueError
            Bad bodies, as :meth:`find_collisions` raises them.
        """
        with self._device_lock():
            return PreparedBodies(bodies, names, cache=self.shapes, strict=self.request.strict,
                                  max_bodies=self.request.max_bodies, lock=self._lock)

    def find_collisions(self, bodies: Sequence[Any], transforms: Any = None, *,
                        names: Sequence[str | None] | None = None,
                        groups: Any = None,
                        view: View | Sequence[View] | None = None,
                        records: str | None = None, contacts: bool | None = None,
                        pairs: Any = None) -> CollisionResult:
        """Find every pair of interfering bodies.

        Parameters
        ----------
        bodies : sequence of trimesh.Trimesh or (vertices (V, 3), faces (F, 3)) pairs
            Meshes in body coordinates (closed ones are solids), or :class:`PreparedBodies`:
            meshes checked once by :meth:`prepare`.
        transforms : (N, 4, 4) float, optional
            World-from-body matrices (default: identity).
        names : sequence of str, optional
            Body names for error messages (prepared bodies have theirs).
        groups : (N,) int, optional
            Only pairs of bodies in different groups are tested (one probe against many
            bodies, or two sets against each other); default: every pair.
        view : View or sequence of View, optional
            Scene strategy only: the views to render through (default: one fitted view).
        records : {"found", "all", "none"}, optional
            Focused strategy: the request's ``records`` for this call only, on the same
            pipelines and cached shapes.
        contacts : bool, optional
            Focused strategy: True keeps what contacts are reduced from (every record, as
            ``records="all"``), so that ``result.contacts()`` answers from the result alone;
            False needs none. Default: the request's ``contacts``. A physics step asks for
            both every frame: ``Detector(contacts=True)``, or this per call.
        pairs : (K, 2) int, optional
            Focused strategy: the only pairs that may be tested and reported, an allowed list
            (each ``(i, j)`` once, either way round; a pair whose boxes do not meet is still left
            out, and so is one within a group where ``groups`` is given). Clash rules give one
            (:mod:`pycinder.bim.rules`). Default: every pair.

        Returns
        -------
        CollisionResult
            ``pairs`` is (K, 2) int64 with ``i < j``. Plain data: no detector or GPU handle.

        Raises
        ------
        ValueError
            Bad bodies or options; ``contacts=True`` with ``records`` other than ``"all"``, or
            with the scene strategy.

        Examples
        --------
        Pairs and contacts of one step, together:

        >>> import trimesh, pycinder
        >>> box = trimesh.creation.box((1, 1, 1))
        >>> ball = trimesh.creation.icosphere(radius=0.4).apply_translation((0.6, 0, 0))
        >>> det = pycinder.Detector(tolerance=0.005)
        >>> result = det.find_collisions([box, ball], names=["box", "ball"], contacts=True)
        >>> [(c.pair, c.normal.round(1).tolist()) for c in result.contacts()]
        [(('box', 'ball'), [1.0, 0.0, 0.0])]
        """
        return self.submit(bodies, transforms, names=names, groups=groups, view=view,
                           records=records, contacts=contacts, pairs=pairs).result()

    def submit(self, bodies: Sequence[Any], transforms: Any = None, *,
               names: Sequence[str | None] | None = None, groups: Any = None,
               view: View | Sequence[View] | None = None, records: str | None = None,
               contacts: bool | None = None, pairs: Any = None) -> PendingQuery:
        """:meth:`find_collisions` without waiting for the GPU: the host checks the bodies,
        plans the tiles and submits the frame, and returns at once. Prepare the next frame, then
        call ``.result()`` on the handle. Two queries can be in flight; a third waits for the
        oldest's GPU work. Arguments as :meth:`find_collisions`.

        Returns
        -------
        PendingQuery
            ``.result()`` gives the :class:`CollisionResult`; ``.ready`` says whether the GPU
            has finished.

        Examples
        --------
        >>> import numpy as np, trimesh, pycinder
        >>> meshes = [trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)]
        >>> frames = np.tile(np.eye(4), (3, 2, 1, 1))
        >>> frames[:, 1, 0, 3] = [0.6, 1.0, 2.0]
        >>> det = pycinder.Detector(tolerance=1e-3)
        >>> pending = det.submit(meshes, frames[0])
        >>> for transforms in frames[1:]:
        ...     following = det.submit(meshes, transforms)  # the GPU may still run the last one
        ...     print(len(pending.result().pairs))
        ...     pending = following
        1
        0
        >>> len(pending.result().pairs)
        0
        """
        return self._pending(bodies, transforms, names, groups, view,
                             self.request.call_records(records, contacts), pairs=pairs)

    def in_collision(self, bodies: Sequence[Any], transforms: Any = None, *,
                     names: Sequence[str | None] | None = None, groups: Any = None,
                     pairs: Any = None) -> bool:
        """Whether any two bodies interfere, as :meth:`find_collisions` would answer, for less:
        the pairs likeliest to collide (:func:`~pycinder.focused.plan.plan_numpy.likely_pairs`) run
        first, and the GPU skips every tile that has not started once any pair is found (the
        focused strategy; the scene strategy runs its whole query). Arguments as
        :meth:`find_collisions`.

        Returns
        -------
        bool
            Whether a pair was found, each tile tested as :meth:`find_collisions` tests it: the
            contract's promises hold for the answer (see :mod:`pycinder.request`).
        """
        pending = self._pending(bodies, transforms, names, groups, None, "none",
                                stop_at_first=True, pairs=pairs)
        return bool(len(pending.result().pairs))

    def _pending(self, bodies: Sequence[Any], transforms: Any,
                 names: Sequence[str | None] | None, groups: Any,
                 view: View | Sequence[View] | None, records: str | None,
                 stop_at_first: bool = False, pairs: Any = None) -> PendingQuery:
        """Validate a query's input and submit it; ``records``: the mode it keeps, resolved by
        :meth:`CollisionRequest.call_records` (None for the scene strategy)."""
        if not isinstance(bodies, Sequence):
            bodies = list(bodies)
        if isinstance(bodies, PreparedBodies) and names is not None:
            raise ValueError("prepared bodies have their names (given to Detector.prepare); "
                             "pass names=None")
        if view is not None:
            refuse(self.strategy, "view")
        with self._device_lock():  # one query at a time: the GPU buffers are the detector's own
            t0 = time.perf_counter()
            scene = self._scene(bodies, transforms, names)
            groups = _checked_groups(groups, len(scene))
            within = None
            if pairs is not None:
                refuse(self.strategy, "pairs")
                within, groups = allowed_pairs(pairs, len(scene), groups), None
            query = Query(groups=groups, records=records, within=within,
                          stop_at_first=stop_at_first, view=view)
            return PendingQuery(self, self._submit(scene, t0, query), t0)

    def find_collisions_batch(self, scenes: Sequence[Any], *, tolerance: Any = None,
                              labels: Sequence[Any] | None = None, records: str | None = None,
                              contacts: bool | None = None) -> list[CollisionResult]:
        """Many small scenes in one query, pairs only within a scene; one result per scene,
        as :meth:`find_collisions` gives it (with ``contacts=True``, each result's contacts).
        See :func:`pycinder.batch.find_collisions_batch`."""
        request = self.request
        refuse(self.strategy, "batch")
        records = request.call_records(records, contacts)
        with self._device_lock():  # one query at a time: the GPU buffers are the detector's own
            t0 = time.perf_counter()
            joined = join_scenes(scenes, labels, tolerance, strict=request.strict,
                                 cache=self.shapes, max_bodies=request.max_bodies)
            pending = self._submit(joined.scene, t0, Query(records=records, within=joined.key,
                                                           body_tolerances=joined.body_tolerances))
            result = self._finish(pending, t0)
        return split(result, joined)

    def _find_within(self, scene: Scene, within: np.ndarray | PairList,
                     body_tolerances: np.ndarray | None) -> CollisionResult:
        """One query of a validated scene holding many small ones (``within`` (N,): each body's
        scene; pairs only inside one; or a :class:`~pycinder.focused.broad.broad_numpy.PairList` of
        the only pairs to test), each body's scene's tolerance in ``body_tolerances`` (N,), NaN for
        the request's: :meth:`find_collisions_batch` without joining and splitting scenes (for
        callers that make the scene themselves, from :meth:`PreparedBodies.copies`, and read
        its pairs with the bodies' global indices)."""
        refuse(self.strategy, "scenes")
        check_body_count(len(scene), self.request.max_bodies)
        records = self.request.call_records(None, None)
        with self._device_lock():
            t0 = time.perf_counter()
            pending = self._submit(scene, t0, Query(records=records, within=within,
                                                    body_tolerances=body_tolerances))
            return self._finish(pending, t0)

    def _scene(self, bodies: Sequence[Any], transforms: Any,
               names: Sequence[str | None] | None) -> Scene:
        """The validated scene of bodies (or prepared bodies) and their transforms."""
        if isinstance(bodies, PreparedBodies):
            # Bodies prepared by a detector that holds more are checked against this one.
            check_body_count(len(bodies), self.request.max_bodies)
            return bodies.scene(transforms)
        return prepare_scene(bodies, transforms, names=names, strict=self.request.strict,
                             cache=self.shapes, max_bodies=self.request.max_bodies)

    def _submit(self, scene: Scene, t0: float, query: Query) -> Pending:
        """Submit a validated scene to the strategy (the one path of single and batched
        queries; the caller holds the device lock); :meth:`_finish` completes it.

        Parameters
        ----------
        scene : Scene
        t0 : float
            ``time.perf_counter()`` at the query's start (validation is timed from it).
        query : Query
            What the call asks (checked groups, records, pairs, tolerances per body, view).

        Returns
        -------
        Pending
            ``.result()`` gives the strategy's :class:`CollisionResult`.

        Raises
        ------
        GpuError
            After a GPU error, with the detector reset (see :meth:`_recover`).
        """
        stats = Stats(strategy=self.request.strategy, adapter=self.gpu.description,
                      bodies=len(scene))
        stats.add_ms("validate", (time.perf_counter() - t0) * 1e3)
        try:
            return self.strategy.submit(scene, stats, query)
        except (GpuTimeoutError, wgpu.GPUError) as exc:
            raise self._recover(exc) from exc

    def _finish(self, pending: Pending, t0: float) -> CollisionResult:
        """The result of a query :meth:`_submit` submitted, waiting for the GPU, with its total
        time written in."""
        with self._lock:
            try:
                result = pending.result()
            except (GpuTimeoutError, wgpu.GPUError) as exc:
                raise self._recover(exc) from exc
            result.stats.wall_ms["total"] = (time.perf_counter() - t0) * 1e3
            return result


def allowed_pairs(pairs: Any, n: int, groups: np.ndarray | None = None) -> PairList:
    """The pairs a query may test, as a :class:`~pycinder.focused.broad.broad_numpy.PairList`: each
    ``(i, j)`` with ``i < j``, once, sorted, and only across ``groups`` where given.

    Parameters
    ----------
    pairs : (K, 2) int
    n : int
        Bodies of the query.
    groups : (n,) int, optional

    Raises
    ------
    ValueError
        Pairs that are not (K, 2) whole numbers, that name a body past ``n``, or a body with
        itself.
    """
    table = np.asarray(pairs)
    if table.size == 0:
        table = table.reshape(0, 2)
    if table.ndim != 2 or table.shape[1] != 2 or not (
            np.issubdtype(table.dtype, np.integer) or table.size == 0):
        raise ValueError(f"pairs must be (K, 2) whole numbers, body indices; got shape "
                         f"{table.shape} of {table.dtype}")
    table = np.sort(table.astype(np.int64), axis=1)
    if len(table) and (table[:, 0].min() < 0 or table[:, 1].max() >= n):
        raise ValueError(f"pairs name bodies from {int(table.min())} to {int(table.max())}; the "
                         f"query has {n} (0 to {n - 1})")
    if len(table) and np.any(table[:, 0] == table[:, 1]):
        k = int(np.flatnonzero(table[:, 0] == table[:, 1])[0])
        raise ValueError(f"pairs name body {int(table[k, 0])} with itself (row {k})")
    table = np.unique(table, axis=0)
    if groups is not None and len(table):
        table = table[groups[table[:, 0]] != groups[table[:, 1]]]
    return PairList(table)


def _checked_groups(groups: Any, n: int) -> np.ndarray | None:
    """``groups`` as an (n,) integer array, or None; a ValueError for any other shape."""
    if groups is None:
        return None
    groups = np.asarray(groups)
    if groups.shape != (n,) or not np.issubdtype(groups.dtype, np.integer):
        raise ValueError(f"groups must be {n} whole numbers, one per body; "
                         f"got shape {groups.shape} of {groups.dtype}")
    return groups


class PendingQuery:
    """A query submitted with :meth:`Detector.submit`; :meth:`result` waits for it."""

    def __init__(self, detector: Detector, pending: Pending, t0: float) -> None:
        self._detector, self._pending, self._t0 = detector, pending, t0
        self._result: CollisionResult | None = None

    @property
    def ready(self) -> bool:
        """Whether the GPU has finished the query's first frame (``result()`` will not wait for
        it; retries of undecided tiles, if any, still run then)."""
        return self._result is not None or self._pending.ready

    def result(self) -> CollisionResult:
        """The query's result, waiting for the GPU if it has not finished (at most the request's
        ``timeout`` per wait)."""
        if self._result is None:
            self._result = self._detector._finish(self._pending, self._t0)
        return self._result


_DETECTORS: dict[CollisionRequest, Detector] = {}
_DETECTORS_LOCK = threading.Lock()


def shared_detector(request: CollisionRequest) -> Detector:
    """A detector per distinct request, kept for reuse (the last few only)."""
    with _DETECTORS_LOCK:
        det = _DETECTORS.get(request)
        if det is not None and not det.in_this_process:  # made by a parent, before a fork
            keep_from_parent(_DETECTORS.pop(request))
            det = None
        if det is None:
            if len(_DETECTORS) >= 4:
                _DETECTORS.pop(next(iter(_DETECTORS)))
            det = _DETECTORS[request] = Detector(request)
        return det


def find_collisions(bodies: Sequence[Any], transforms: Any = None, *,
                    tolerance: float | None = None, names: Sequence[str | None] | None = None,
                    groups: Any = None, view: View | Sequence[View] | None = None,
                    **options: Any) -> CollisionResult:
    """Find every pair of interfering closed meshes.

    Parameters
    ----------
    bodies : sequence of trimesh.Trimesh or (vertices (V, 3), faces (F, 3)) pairs
    transforms : (N, 4, 4) float, optional
        World-from-body matrices.
    tolerance : float, optional
        World units: pairs at least this far apart are never reported, pairs overlapping by
        twice this are always reported (see :mod:`pycinder.request`). Default: 1% of the smaller
        body's size, per pair.
    names : sequence of str, optional
        Body names for error messages.
    groups : (N,) int, optional
        Only pairs of bodies in different groups are tested; default: every pair.
    view : View or sequence of View, optional
        Scene strategy only.
    **options
        Other options of :class:`~pycinder.CollisionRequest` (``strategy``, ``encode``,
        ``records``, ``contacts``, ...). ``contacts=True`` keeps what contacts are reduced from,
        so that ``result.contacts()`` answers from the result alone.

    Returns
    -------
    CollisionResult
        Plain data (no detector or GPU handle): it pickles.

    Notes
    -----
    For animation loops keep a :class:`Detector`: this function keeps one per distinct request.
    """
    request = CollisionRequest(tolerance=tolerance, **options)
    return shared_detector(request).find_collisions(bodies, transforms, names=names,
                                                    groups=groups, view=view)

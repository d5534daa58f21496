"""The Detector: a request, the GPU resources that serve it, and one query after another.

    request (checked once) + bodies + transforms
      -> scene (validated shapes, cached by content)
      -> strategy: focused (broad phase -> tiles -> passes F0-F5 -> readback)
                   or scene (views -> passes 1-7 -> filter -> readback mode)
      -> CollisionResult
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from .focused import FocusedStrategy
from .gpu.device import get_gpu
from .request import RECORD_MODES, CollisionRequest
from .result import CollisionResult, Stats, remember_query
from .scene import ShapeCache, prepare_scene
from .view import View
from .wholescene import SceneStrategy


class Detector:
    """Collision detection with GPU pipelines and buffers kept between calls.

    Parameters
    ----------
    request : CollisionRequest, optional
        Every option at once; keywords below build one (or change the given one).
    **options
        Options of :class:`~pycinder.CollisionRequest`: ``tolerance``, ``strategy``,
        ``resolution``, ``self_interference``, ``readback``, ``encode``, ``strict``, ...

    Examples
    --------
    >>> det = pycinder.Detector(tolerance=1e-3)
    >>> for frame in frames:
    ...     result = det.find_collisions(meshes, transforms)   # transforms: (N, 4, 4)
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
        self.strategy: FocusedStrategy | SceneStrategy
        if request.strategy == "focused":
            self.strategy = FocusedStrategy(self.gpu, request)
        else:
            self.strategy = SceneStrategy(self.gpu, request)

    def find_collisions(self, bodies: Sequence[Any], transforms: Any = None, *,
                        names: Sequence[str | None] | None = None,
                        groups: Any = None,
                        view: View | Sequence[View] | None = None,
                        records: str | None = None) -> CollisionResult:
        """Find every pair of interfering bodies.

        Parameters
        ----------
        bodies : sequence of trimesh.Trimesh or (vertices (V, 3), faces (F, 3)) pairs
            Closed meshes in body coordinates.
        transforms : (N, 4, 4) float, optional
            World-from-body matrices (default: identity).
        names : sequence of str, optional
            Body names for error messages.
        groups : (N,) int, optional
            Only pairs of bodies in different groups are tested (one probe against many
            bodies, or two sets against each other); default: every pair.
        view : View or sequence of View, optional
            Scene strategy only: the views to render through (default: one fitted view).
        records : {"found", "all", "none"}, optional
            Focused strategy: the request's ``records`` for this call only, on the same
            pipelines and cached shapes (a manager asks for contacts on some calls only).

        Returns
        -------
        CollisionResult
            ``pairs`` is (K, 2) int64 with ``i < j``.
        """
        t0 = time.perf_counter()
        if view is not None and self.request.strategy != "scene":
            raise ValueError("view applies to strategy='scene'; the focused strategy chooses a "
                             "view per candidate pair")
        if records is not None:
            if self.request.strategy != "focused":
                raise ValueError("records per call applies to strategy='focused'")
            if records not in RECORD_MODES:
                raise ValueError(f"records must be one of {RECORD_MODES}, got {records!r}")
        if not isinstance(bodies, Sequence):
            bodies = list(bodies)  # kept on the result, to run it again for contacts
        scene = prepare_scene(bodies, transforms, names=names, strict=self.request.strict,
                              cache=self.shapes, max_bodies=self.request.max_bodies)
        stats = Stats(strategy=self.request.strategy, adapter=self.gpu.description,
                      bodies=len(scene))
        if groups is not None:
            groups = np.asarray(groups)
            if groups.shape != (len(scene),) or not np.issubdtype(groups.dtype, np.integer):
                raise ValueError(f"groups must be {len(scene)} whole numbers, one per body; "
                                 f"got shape {groups.shape} of {groups.dtype}")
        stats.add_ms("validate", (time.perf_counter() - t0) * 1e3)
        if isinstance(self.strategy, SceneStrategy):
            result = self.strategy.run(scene, stats, view)
            if groups is not None:
                result = result.across(groups)
        else:
            result = self.strategy.run(scene, stats, groups, records)
        stats.wall_ms["total"] = (time.perf_counter() - t0) * 1e3
        remember_query(result, self, bodies, transforms, names, groups,
                       records or self.request.records)
        return result


_DETECTORS: dict[CollisionRequest, Detector] = {}


def shared_detector(request: CollisionRequest) -> Detector:
    """A detector per distinct request, kept for reuse (the last few only)."""
    det = _DETECTORS.get(request)
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
        Other options of :class:`~pycinder.CollisionRequest` (``strategy``, ``encode``, ...).

    Returns
    -------
    CollisionResult

    Notes
    -----
    For animation loops keep a :class:`Detector`: this function keeps one per distinct request.
    """
    request = CollisionRequest(tolerance=tolerance, **options)
    return shared_detector(request).find_collisions(bodies, transforms, names=names,
                                                    groups=groups, view=view)

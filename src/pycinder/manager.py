"""A drop-in for ``trimesh.collision.CollisionManager``.

Swap the import and keep the code: the same methods, arguments, return types, name ordering and
errors as trimesh's class (which runs python-fcl). What backs each answer:

* **Collisions** (``in_collision_*``): pycinder's GPU query, one per call (``in_collision_single``
  and ``in_collision_other`` test only the pairs across the two sides), within the tolerance
  contract of :mod:`pycinder.request`. Unlike FCL's surface tests, a body wholly inside another
  is a collision. An object's mesh is copied when it is added (read-only), as trimesh builds
  its BVH then: every method tests the mesh as it was added (edit it, and add it again to have
  the edit seen). Calls over all of the manager's objects check the copies once
  (:meth:`pycinder.Detector.prepare`) until objects are added or removed; the others recognise
  them by trimesh's cached content hash.
* **Contacts** (``return_data=True``): one :class:`ContactData` per contact region of each
  colliding pair, reduced from the GPU's records (:mod:`pycinder.contacts`). ``normal`` follows
  python-fcl: it points from the contact's first object into its second (``ContactData.pair``;
  trimesh's ``names`` is a set), ``depth`` is the penetration along it, ``point`` lies on the
  intersection, ``index(name)`` is a face of that object at the contact (-1 where unknown).
* **Distances** (``min_distance_*``): python-fcl, built as trimesh builds it (``Convex`` for
  convex meshes, ``BVHModel`` otherwise), for exact distances between separated objects. For
  overlapping objects the distance is negative, the penetration depth: python-fcl's EPA where
  both meshes are convex (as trimesh), pycinder's contact depth otherwise (where python-fcl
  reports 0, or nothing for a body inside another). Needs python-fcl: ``pip install
  'pycinder[distance]'``.
* **Query modes**: the options are those of :class:`~pycinder.CollisionRequest`, the mode options
  included. ``CollisionManager(min_depth=d)`` makes ``in_collision_*`` report hard clashes (pairs
  deeper than ``d``, never touching convex pairs; see :mod:`pycinder.focused.modes.hardclash`),
  ``CollisionManager(clearance=c)`` pairs closer than ``c`` (see
  :mod:`pycinder.focused.modes.clearance`); their names and booleans answer that question. Such a
  manager measures no contacts: ``return_data=True``, and ``min_distance_*`` where non-convex
  objects overlap, raise a ``ValueError`` (use a manager without the mode for them).
"""

from __future__ import annotations

import contextlib
import functools
import sys
import threading
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Callable, Literal, TypeVar, Union, cast, overload

import numpy as np

from .contacts import ContactData
from .detector import Detector
from .gpu.device import keep_from_parent
from .request import CollisionRequest
from .result import CollisionResult
from .scene import PreparedBodies
from .scene.bodies import mesh_arrays
from .util.optional import require

EXTERNAL = "__external"
"""The name trimesh gives the probe of ``in_collision_single`` and ``min_distance_single``."""

NamePairs = set[tuple[str, str]]
"""Colliding pairs by name, each sorted (``in_collision_internal``) or (this, other)
(``in_collision_other``)."""
NamePair = Union[tuple[str, str], tuple[None, None]]
"""The two names a distance query reports, or ``(None, None)`` with no pair to measure."""
_N = TypeVar("_N")
CollisionAnswer = Union[bool, tuple[bool, _N], tuple[bool, list[ContactData]],
                        tuple[bool, _N, list[ContactData]]]
"""What ``in_collision_*`` returns, by ``return_names`` and ``return_data``, as trimesh's."""

NO_DISTANCE = sys.float_info.max
"""What trimesh (python-fcl) returns as the distance when there is no pair to measure."""


def _fcl() -> Any:
    return require("fcl", "CollisionManager.min_distance_*", "distance", "python-fcl")


def _as_trimesh(mesh: Any) -> Any:
    import trimesh

    if isinstance(mesh, trimesh.Trimesh):
        return mesh
    vertices, faces = mesh
    return trimesh.Trimesh(np.asarray(vertices, np.float64), np.asarray(faces), process=False)


def _transform(transform: Any) -> np.ndarray:
    t = np.eye(4) if transform is None else np.asarray(transform, dtype=np.float64)
    if t.shape != (4, 4):
        raise ValueError("transform must be (4,4)!")
    return t


class DistanceData:
    """What a distance query found, shaped like trimesh's ``DistanceData``.

    Attributes
    ----------
    names : set of str
    distance : float
        Distance between the objects; negative: they overlap by that much.
    """

    def __init__(self, pair: tuple[str, str], distance: float, points: Sequence[Any],
                 faces: Sequence[int]) -> None:
        self.names = set(pair)
        self.distance = float(distance)
        self._points = {pair[0]: np.asarray(points[0]), pair[1]: np.asarray(points[1])}
        self._inds = {pair[0]: int(faces[0]), pair[1]: int(faces[1])}

    def point(self, name: str) -> np.ndarray:
        """The closest point on object ``name`` (for overlapping objects: its deepest point
        inside the other)."""
        return self._points[name]

    def index(self, name: str) -> int:
        """The closest face of object ``name`` (-1 where unknown)."""
        return self._inds[name]


DistanceAnswer = Union[float, tuple[float, _N], tuple[float, DistanceData | None],
                       tuple[float, _N, DistanceData | None]]
"""What ``min_distance_*`` returns, by ``return_names`` and ``return_data``, as trimesh's."""


@dataclass
class CollisionObject:
    """What :meth:`CollisionManager.add_object` returns (trimesh returns python-fcl's object).

    ``mesh`` is the mesh as given; ``geometry`` what the manager tests: the read-only
    ``(vertices, faces)`` copy of it taken when the object was added (as trimesh builds its BVH
    then), the mesh itself where it is no pair of arrays (the query names the problem), or None
    for a probe, tested as given."""

    name: str
    mesh: Any
    transform: np.ndarray
    geometry: Any = field(default=None, repr=False)
    _fcl: Any = field(default=None, repr=False)
    _trimesh: Any = field(default=None, repr=False)

    @property
    def body(self) -> Any:
        """What a query is given for this object."""
        return self.mesh if self.geometry is None else self.geometry

    @property
    def trimesh(self) -> Any:
        """The tested mesh as a ``trimesh.Trimesh`` (made once)."""
        if self._trimesh is None:
            self._trimesh = _as_trimesh(self.body)
        return self._trimesh

    def world_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(3,), (3,) world box of the object at its transform."""
        corners = self.trimesh.bounding_box.vertices
        w = corners @ self.transform[:3, :3].T + self.transform[:3, 3]
        return w.min(axis=0), w.max(axis=0)


def _answer(hit: bool | float, names: Any, data: Any, return_names: bool, return_data: bool) -> Any:
    if return_names and return_data:
        return hit, names, data
    if return_names:
        return hit, names
    if return_data:
        return hit, data
    return hit


_Method = TypeVar("_Method", bound=Callable[..., Any])


def _serialised(method: _Method) -> _Method:
    """One call of a manager at a time, from any thread: its objects and its detector are
    shared by every call. A call given another manager (``*_other``) holds that one's lock too
    (the two taken in one order, so that crossed calls cannot deadlock)."""

    @functools.wraps(method)
    def call(self: CollisionManager, *args: Any, **kwargs: Any) -> Any:
        other = kwargs.get("other_manager", args[0] if args else None)
        locks = [self._lock]
        if isinstance(other, CollisionManager) and other is not self:
            locks = sorted(locks + [other._lock], key=id)
        with contextlib.ExitStack() as held:
            for lock in locks:
                held.enter_context(lock)
            return method(self, *args, **kwargs)

    return cast(_Method, call)


class CollisionManager:
    """Collision and distance checks among named meshes, with trimesh's method names.

    Parameters
    ----------
    **options
        Options of :class:`~pycinder.CollisionRequest` (``tolerance``, ...) for its detectors.
    """

    def __init__(self, **options: Any) -> None:
        given = [name for name in ("records", "contacts") if name in options]
        if given:
            raise TypeError(f"CollisionManager chooses the records itself (contacts when a call "
                            f"asks for return_data, pairs only otherwise); leave "
                            f"{' and '.join(map(repr, given))} out")
        if options.get("strategy", "focused") != "focused":
            raise ValueError("CollisionManager runs the focused strategy (its contacts and "
                             "distances need tiles per pair); leave 'strategy' out")
        self._request = CollisionRequest(**options)  # options checked now, not at first use
        self._detector_: Detector | None = None
        self._objs: dict[str, CollisionObject] = {}
        self._copies: dict[int, list[Any]] = {}
        """Per mesh given (by id; the mesh is kept, so the id stays its own): the mesh, its
        latest copy (shared by the objects added with it while its content is unchanged) and
        how many objects use the mesh."""
        self._prepared: PreparedBodies | None = None
        """The objects' copies, checked once until objects are added or removed."""
        self._lock = threading.RLock()

    # -- objects --------------------------------------------------------------------------------

    @_serialised
    def add_object(self, name: str, mesh: Any, transform: np.ndarray | None = None
                   ) -> CollisionObject:
        """Add an object, or replace the one of the same name.

        Parameters
        ----------
        name : str
        mesh : trimesh.Trimesh or (vertices, faces)
        transform : (4, 4) float, optional
            World from object (float32 is fine).
        """
        transform = _transform(transform)
        old = self._objs.get(name)  # an unhashable name raises here, before anything is kept
        obj = CollisionObject(name, mesh, transform, self._copy(mesh))
        self._objs[name] = obj  # a replaced object keeps its place, as in trimesh
        if old is not None:
            self._forget(old.mesh)
        self._prepared = None
        return obj

    @_serialised
    def remove_object(self, name: str) -> None:
        if name not in self._objs:
            raise ValueError(f"{name} not in collision manager!")
        self._forget(self._objs.pop(name).mesh)
        self._prepared = None

    @_serialised
    def set_transform(self, name: str, transform: np.ndarray) -> None:
        if name not in self._objs:
            raise ValueError(f"{name} not in collision manager!")
        self._objs[name].transform = _transform(transform)

    # -- collisions -----------------------------------------------------------------------------

    @overload
    def in_collision_internal(self, return_names: Literal[False] = False,
            return_data: Literal[False] = False) -> bool: ...
    @overload
    def in_collision_internal(self, *, return_names: Literal[True],
            return_data: Literal[False] = False) -> tuple[bool, NamePairs]: ...
    @overload
    def in_collision_internal(self, *, return_names: Literal[False] = False,
            return_data: Literal[True]) -> tuple[bool, list[ContactData]]: ...
    @overload
    def in_collision_internal(self, *, return_names: Literal[True],
            return_data: Literal[True]) -> tuple[bool, NamePairs, list[ContactData]]: ...
    @overload
    def in_collision_internal(self, return_names: bool = False,
            return_data: bool = False) -> CollisionAnswer[NamePairs]: ...

    @_serialised
    def in_collision_internal(self, return_names: bool = False, return_data: bool = False
                              ) -> CollisionAnswer[NamePairs]:
        """Whether any two objects collide; optionally the set of sorted name pairs and the
        contacts."""
        names = list(self._objs)
        objs = list(self._objs.values())
        if not return_names and not return_data:
            return self._any(objs, names, None)
        result = self._query(objs, names, None, return_data)
        pairs = {tuple(sorted((names[i], names[j]))) for i, j in result.pairs.tolist()}
        data = self._contacts(result) if return_data else []
        return _answer(bool(pairs), pairs, data, return_names, return_data)

    @overload
    def in_collision_single(self, mesh: Any, transform: np.ndarray | None = None,
            return_names: Literal[False] = False, return_data: Literal[False] = False) -> bool: ...
    @overload
    def in_collision_single(self, mesh: Any, transform: np.ndarray | None = None, *,
            return_names: Literal[True],
            return_data: Literal[False] = False) -> tuple[bool, set[str]]: ...
    @overload
    def in_collision_single(self, mesh: Any, transform: np.ndarray | None = None, *,
            return_names: Literal[False] = False,
            return_data: Literal[True]) -> tuple[bool, list[ContactData]]: ...
    @overload
    def in_collision_single(self, mesh: Any, transform: np.ndarray | None = None, *,
            return_names: Literal[True],
            return_data: Literal[True]) -> tuple[bool, set[str], list[ContactData]]: ...
    @overload
    def in_collision_single(self, mesh: Any, transform: np.ndarray | None = None,
            return_names: bool = False, return_data: bool = False) -> CollisionAnswer[set[str]]: ...

    @_serialised
    def in_collision_single(self, mesh: Any, transform: np.ndarray | None = None,
                            return_names: bool = False, return_data: bool = False) -> CollisionAnswer[set[str]]:
        """Whether ``mesh`` at ``transform`` collides with any object; optionally the set of
        their names and the contacts. One query, whatever the number of objects."""
        names = list(self._objs)
        probe = CollisionObject(EXTERNAL, mesh, _transform(transform))
        groups = np.r_[np.zeros(len(names), np.int64), 1]
        objs, labels = [*self._objs.values(), probe], [*names, EXTERNAL]
        if not return_names and not return_data:
            return self._any(objs, labels, groups)
        result = self._query(objs, labels, groups, return_data)
        found = {names[i] for i, j in result.pairs.tolist()}
        data = self._contacts(result) if return_data else []
        return _answer(bool(found), found, data, return_names, return_data)

    @overload
    def in_collision_other(self, other_manager: CollisionManager,
            return_names: Literal[False] = False, return_data: Literal[False] = False) -> bool: ...
    @overload
    def in_collision_other(self, other_manager: CollisionManager, *, return_names: Literal[True],
            return_data: Literal[False] = False) -> tuple[bool, NamePairs]: ...
    @overload
    def in_collision_other(self, other_manager: CollisionManager, *,
            return_names: Literal[False] = False,
            return_data: Literal[True]) -> tuple[bool, list[ContactData]]: ...
    @overload
    def in_collision_other(self, other_manager: CollisionManager, *, return_names: Literal[True],
            return_data: Literal[True]) -> tuple[bool, NamePairs, list[ContactData]]: ...
    @overload
    def in_collision_other(self, other_manager: CollisionManager, return_names: bool = False,
            return_data: bool = False) -> CollisionAnswer[NamePairs]: ...

    @_serialised
    def in_collision_other(self, other_manager: CollisionManager, return_names: bool = False,
                           return_data: bool = False) -> CollisionAnswer[NamePairs]:
        """Whether any object of this manager collides with any of ``other_manager``; optionally
        the set of (this name, other name) pairs and the contacts."""
        mine, theirs = list(self._objs), list(other_manager._objs)
        objs = [self._objs[n] for n in mine] + [other_manager._objs[n] for n in theirs]
        groups = np.r_[np.zeros(len(mine), np.int64), np.ones(len(theirs), np.int64)]
        if not return_names and not return_data:
            return self._any(objs, mine + theirs, groups)
        result = self._query(objs, mine + theirs, groups, return_data)
        k = len(mine)
        found = {(mine[i], theirs[j - k]) for i, j in result.pairs.tolist()}
        data = self._contacts(result) if return_data else []
        return _answer(bool(found), found, data, return_names, return_data)

    # -- distances ------------------------------------------------------------------------------

    @overload
    def min_distance_internal(self, name: str | None = None, return_names: Literal[False] = False,
            return_data: Literal[False] = False) -> float: ...
    @overload
    def min_distance_internal(self, name: str | None = None, *, return_names: Literal[True],
            return_data: Literal[False] = False) -> tuple[float, NamePair]: ...
    @overload
    def min_distance_internal(self, name: str | None = None, *,
            return_names: Literal[False] = False,
            return_data: Literal[True]) -> tuple[float, DistanceData | None]: ...
    @overload
    def min_distance_internal(self, name: str | None = None, *, return_names: Literal[True],
            return_data: Literal[True]) -> tuple[float, NamePair, DistanceData | None]: ...
    @overload
    def min_distance_internal(self, name: str | None = None, return_names: bool = False,
            return_data: bool = False) -> DistanceAnswer[NamePair]: ...

    @_serialised
    def min_distance_internal(self, name: str | None = None, return_names: bool = False,
                              return_data: bool = False) -> DistanceAnswer[NamePair]:
        """Smallest distance between two objects (from object ``name``, if given); negative when
        objects overlap. Optionally the sorted names and a :class:`DistanceData`."""
        names = list(self._objs)
        if name is not None and name not in self._objs:
            raise ValueError(f"{name} not in collision manager!")
        groups = None
        if name is not None:
            groups = np.array([0 if n == name else 1 for n in names], np.int64)
        objs = [self._objs[n] for n in names]
        distance, pair, data = self._min_distance(objs, names, groups)
        if pair is None:
            return _answer(distance, (None, None), None, return_names, return_data)
        return _answer(distance, tuple(sorted(pair)), data, return_names, return_data)

    @overload
    def min_distance_single(self, mesh: Any, transform: np.ndarray | None = None,
            return_name: Literal[False] = False, return_data: Literal[False] = False) -> float: ...
    @overload
    def min_distance_single(self, mesh: Any, transform: np.ndarray | None = None, *,
            return_name: Literal[True],
            return_data: Literal[False] = False) -> tuple[float, str | None]: ...
    @overload
    def min_distance_single(self, mesh: Any, transform: np.ndarray | None = None, *,
            return_name: Literal[False] = False,
            return_data: Literal[True]) -> tuple[float, DistanceData | None]: ...
    @overload
    def min_distance_single(self, mesh: Any, transform: np.ndarray | None = None, *,
            return_name: Literal[True],
            return_data: Literal[True]) -> tuple[float, str | None, DistanceData | None]: ...
    @overload
    def min_distance_single(self, mesh: Any, transform: np.ndarray | None = None,
            return_name: bool = False, return_data: bool = False) -> DistanceAnswer[str | None]: ...

    @_serialised
    def min_distance_single(self, mesh: Any, transform: np.ndarray | None = None,
                            return_name: bool = False, return_data: bool = False) -> DistanceAnswer[str | None]:
        """Smallest distance between ``mesh`` at ``transform`` and any object; negative when it
        overlaps one. Optionally the closest object's name and a :class:`DistanceData`."""
        names = list(self._objs)
        probe = CollisionObject(EXTERNAL, mesh, _transform(transform))
        groups = np.r_[np.zeros(len(names), np.int64), 1]
        distance, pair, data = self._min_distance([self._objs[n] for n in names] + [probe],
                                                  names + [EXTERNAL], groups)
        closest = None if pair is None else (pair[0] if pair[1] == EXTERNAL else pair[1])
        return _answer(distance, closest, data, return_name, return_data)

    @overload
    def min_distance_other(self, other_manager: CollisionManager,
            return_names: Literal[False] = False, return_data: Literal[False] = False) -> float: ...
    @overload
    def min_distance_other(self, other_manager: CollisionManager, *, return_names: Literal[True],
            return_data: Literal[False] = False) -> tuple[float, NamePair]: ...
    @overload
    def min_distance_other(self, other_manager: CollisionManager, *,
            return_names: Literal[False] = False,
            return_data: Literal[True]) -> tuple[float, DistanceData | None]: ...
    @overload
    def min_distance_other(self, other_manager: CollisionManager, *, return_names: Literal[True],
            return_data: Literal[True]) -> tuple[float, NamePair, DistanceData | None]: ...
    @overload
    def min_distance_other(self, other_manager: CollisionManager, return_names: bool = False,
            return_data: bool = False) -> DistanceAnswer[NamePair]: ...

    @_serialised
    def min_distance_other(self, other_manager: CollisionManager, return_names: bool = False,
                           return_data: bool = False) -> DistanceAnswer[NamePair]:
        """Smallest distance between an object of this manager and one of ``other_manager``;
        optionally the (this name, other name) pair and a :class:`DistanceData`."""
        mine, theirs = list(self._objs), list(other_manager._objs)
        objs = [self._objs[n] for n in mine] + [other_manager._objs[n] for n in theirs]
        groups = np.r_[np.zeros(len(mine), np.int64), np.ones(len(theirs), np.int64)]
        # Other managers' objects keep their own names; label them apart in the query.
        labels = mine + [f"\0{n}" for n in theirs]
        distance, pair, data = self._min_distance(objs, labels, groups)
        if pair is None:
            return _answer(distance, (None, None), None, return_names, return_data)
        first, second = sorted(pair, key=lambda s: s.startswith("\0"))
        names = (first, second[1:])
        if data is not None:
            data = DistanceData(names, data.distance, [data.point(first), data.point(second)],
                                [data.index(first), data.index(second)])
        return _answer(distance, names, data, return_names, return_data)

    # -- inside ---------------------------------------------------------------------------------

    @property
    def _detector(self) -> Detector:
        """One detector, its pipelines and cached shapes shared by every call, made at first
        use (and again in a process forked after it was made)."""
        if self._detector_ is not None and not self._detector_.in_this_process:
            # This process was forked after the detector was made: it needs one of its own.
            keep_from_parent(self._detector_)
            self._detector_, self._prepared = None, None
        if self._detector_ is None:
            self._detector_ = Detector(self._request)
        return self._detector_

    def _copy(self, mesh: Any) -> Any:
        """The ``(vertices, faces)`` copy of a mesh being added: that of an earlier object added
        with the same mesh while its content is unchanged (700 objects of one sphere share one),
        else a new one. Its arrays are read-only and carry trimesh's cached content hash, so a
        query recognises them without hashing their bytes. Input that is no pair of arrays is
        kept as given (the query then says what is wrong with it, naming the object)."""
        try:
            vertices, faces = (np.asarray(a) for a in mesh_arrays(mesh, "mesh"))
        except (TypeError, ValueError):
            return mesh
        known = self._copies.get(id(mesh))
        if known is not None and np.array_equal(known[1][0], vertices) \
                and np.array_equal(known[1][1], faces):
            known[2] += 1
            return known[1]
        from trimesh.caching import tracked_array

        copy = (tracked_array(np.array(vertices)), tracked_array(np.array(faces)))
        for a in copy:
            a.flags.writeable = False
        users = known[2] if known is not None else 0
        self._copies[id(mesh)] = [mesh, copy, users + 1]
        return copy

    def _forget(self, mesh: Any) -> None:
        """One object less uses ``mesh``: drop its copy once none does."""
        known = self._copies.get(id(mesh))
        if known is not None and known[0] is mesh:
            known[2] -= 1
            if known[2] <= 0:
                del self._copies[id(mesh)]

    def _query(self, objs: Sequence[CollisionObject], labels: list[str],
               groups: np.ndarray | None, contacts: bool) -> CollisionResult:
        mode = next((m for m in ("min_depth", "clearance")
                     if getattr(self._request, m) is not None), None)
        if contacts and mode is not None:
            raise ValueError(
                f"this CollisionManager was made with {mode}={getattr(self._request, mode)!r}: "
                f"its queries report that mode's pairs and measure no contacts, which "
                f"return_data=True (and min_distance_* where non-convex objects overlap) "
                f"needs; use a CollisionManager without {mode} for them")
        bodies, transforms, names = self._bodies(objs, labels)
        if contacts:
            return self._detector.find_collisions(bodies, transforms, names=names, groups=groups,
                                                  contacts=True)
        return self._detector.find_collisions(bodies, transforms, names=names, groups=groups,
                                              records="none")

    def _any(self, objs: Sequence[CollisionObject], labels: list[str],
             groups: np.ndarray | None) -> bool:
        """Whether any two of ``objs`` (in different ``groups``) collide: the GPU stops at the
        first pair it finds (:meth:`~pycinder.Detector.in_collision`)."""
        bodies, transforms, names = self._bodies(objs, labels)
        return self._detector.in_collision(bodies, transforms, names=names, groups=groups)

    def _bodies(self, objs: Sequence[CollisionObject], labels: list[str]
                ) -> tuple[Any, np.ndarray, list[str] | None]:
        """What a query of ``objs`` is given: bodies, (N, 4, 4) transforms and names."""
        transforms = np.array([o.transform for o in objs]).reshape(-1, 4, 4)
        if len(objs) == len(self._objs) and labels == list(self._objs) \
                and all(a is b for a, b in zip(objs, self._objs.values())):
            # Every object of this manager: their copies are checked once, until objects are
            # added or removed.
            if self._prepared is None:
                self._prepared = self._detector.prepare([o.body for o in objs], names=labels)
            return self._prepared, transforms, None
        return [o.body for o in objs], transforms, labels

    @staticmethod
    def _contacts(result: CollisionResult) -> list[ContactData]:
        """The contacts of a result asked for with contacts (:meth:`_query`), named by the
        labels the query was given."""
        return list(result.contacts())

    def _min_distance(self, objs: Sequence[CollisionObject], labels: list[str],
                      groups: np.ndarray | None
                      ) -> tuple[float, tuple[str, str] | None, DistanceData | None]:
        """Overlapping pairs first (the most negative signed distance), else python-fcl's exact
        distance over the pairs its broad phase leaves."""
        fcl = _fcl()
        if len(objs) < 2:
            return NO_DISTANCE, None, None
        result = self._query(objs, labels, groups, contacts=False)
        if len(result.pairs):
            return self._deepest(result.pairs, objs, labels, groups)
        request = fcl.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)
        best: tuple[float, Any, int, int] | None = None
        for i, j in _pairs_by_box_distance(objs, groups):
            if best is not None and _box_distance(objs[i], objs[j]) >= best[0]:
                break
            res = fcl.DistanceResult()  # python-fcl objects are built for the pairs visited only
            d = fcl.distance(self._fcl_object(objs[i]), self._fcl_object(objs[j]), request, res)
            if best is None or d < best[0]:
                best = (d, res, i, j)
        if best is None:
            return NO_DISTANCE, None, None
        d, res, i, j = best
        pair = (labels[i], labels[j])
        return d, pair, DistanceData(pair, d, res.nearest_points, (res.b1, res.b2))

    def _deepest(self, pairs: np.ndarray, objs: Sequence[CollisionObject], labels: list[str],
                 groups: np.ndarray | None) -> tuple[float, tuple[str, str], DistanceData]:
        """The most negative signed distance among the colliding ``pairs`` (K, 2): python-fcl's
        EPA where both meshes are convex, else the depth of the GPU contacts, from a second
        query over just the objects of such pairs."""
        convex = np.zeros(len(objs), dtype=bool)  # asked only of objects in colliding pairs
        touching = np.unique(pairs)
        convex[touching] = [objs[i].trimesh.is_convex for i in touching]
        concave = pairs[~(convex[pairs[:, 0]] & convex[pairs[:, 1]])]
        contacts = None
        if len(concave):
            involved = np.unique(concave)
            sub = self._query([objs[i] for i in involved], [labels[i] for i in involved],
                              None if groups is None else groups[involved], contacts=True)
            contacts = sub.contacts()
            contacts.pair = involved[contacts.pair]  # back to indices into objs
        best: tuple[float, tuple[str, str], DistanceData] | None = None
        for a, b in pairs.tolist():
            pair = (labels[a], labels[b])
            oa, ob = objs[a], objs[b]
            mine = np.flatnonzero((contacts.pair == [a, b]).all(axis=1)) \
                if contacts is not None else np.zeros(0, np.int64)
            if (convex[a] and convex[b]) or not len(mine):
                # Convex pairs, and (should records be missing) any pair: python-fcl's signed
                # distance, exact for convex meshes.
                d, data = self._fcl_signed(oa, ob, pair)
            else:
                assert contacts is not None  # mine is not empty
                k = mine[np.argmax(contacts.depth[mine])]
                d = -float(contacts.depth[k])
                points = [np.where(np.isnan(p), contacts.point[k], p) for p in contacts.deepest[k]]
                data = DistanceData(pair, d, points, tuple(contacts.face[k]))
            if best is None or d < best[0]:
                best = (d, pair, data)
        assert best is not None  # result.pairs is not empty
        return best

    def _fcl_signed(self, a: CollisionObject, b: CollisionObject, pair: tuple[str, str]
                    ) -> tuple[float, DistanceData]:
        """python-fcl's signed distance of two objects and its DistanceData."""
        fcl = _fcl()
        res = fcl.DistanceResult()
        d = fcl.distance(self._fcl_object(a), self._fcl_object(b), fcl.DistanceRequest(
            enable_nearest_points=True, enable_signed_distance=True), res)
        return d, DistanceData(pair, d, res.nearest_points, (res.b1, res.b2))

    @staticmethod
    def _fcl_object(obj: CollisionObject) -> Any:
        """python-fcl's object for ``obj``, built once, as trimesh builds it."""
        fcl = _fcl()
        if obj._fcl is None:
            mesh = obj.trimesh
            if mesh.is_convex:
                counts = np.full((len(mesh.faces), 1), 3, dtype=np.int64)
                geom = fcl.Convex(mesh.vertices, len(mesh.faces),
                                  np.hstack([counts, mesh.faces]).ravel())
            else:
                geom = fcl.BVHModel()
                geom.beginModel(len(mesh.vertices), len(mesh.faces))
                geom.addSubModel(mesh.vertices, mesh.faces)
                geom.endModel()
            obj._fcl = fcl.CollisionObject(geom, fcl.Transform())
        t = obj.transform
        obj._fcl.setTransform(fcl.Transform(t[:3, :3], t[:3, 3]))
        return obj._fcl


def _box_distance(a: CollisionObject, b: CollisionObject) -> float:
    (la, ha), (lb, hb) = a.world_box(), b.world_box()
    gap = np.maximum(np.maximum(la - hb, lb - ha), 0.0)
    return float(np.linalg.norm(gap))


def _pairs_by_box_distance(objs: Sequence[CollisionObject], groups: np.ndarray | None
                           ) -> Iterable[tuple[int, int]]:
    """Pairs in order of their boxes' distance, a lower bound of theirs: a search can stop once
    a box distance exceeds the best distance found."""
    boxes = [o.world_box() for o in objs]
    lo = np.array([b[0] for b in boxes])
    hi = np.array([b[1] for b in boxes])
    i, j = np.triu_indices(len(objs), 1)
    if groups is not None:
        keep = groups[i] != groups[j]
        i, j = i[keep], j[keep]
    gap = np.maximum(np.maximum(lo[i] - hi[j], lo[j] - hi[i]), 0.0)
    order = np.argsort(np.linalg.norm(gap, axis=1), kind="stable")
    return zip(i[order].tolist(), j[order].tolist())


def scene_to_collision(scene: Any, **options: Any) -> tuple[CollisionManager, dict[str, Any]]:
    """A :class:`CollisionManager` of a ``trimesh.Scene``'s geometry nodes, as trimesh's
    ``trimesh.collision.scene_to_collision``.

    Returns
    -------
    manager : CollisionManager
    objects : dict of node name to CollisionObject
    """
    manager = CollisionManager(**options)
    objects = {}
    for node in scene.graph.nodes_geometry:
        transform, geometry = scene.graph[node]
        objects[node] = manager.add_object(node, scene.geometry[geometry], transform)
    return manager, objects

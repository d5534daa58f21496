"""A drop-in for ``trimesh.collision.CollisionManager`` backed by CInDeR.

Method names, arguments and return values follow trimesh's class, so code written for it runs
unchanged; ``return_data=True`` gives :class:`ContactData` built from the collision pixels.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from .detector import Detector
from .result import CollisionResult
from .view import View

EXTERNAL = "__external"


class ContactData:
    """One collision pixel, shaped like trimesh's ``ContactData``.

    names : the two object names, penetrating first
    point : (3,) float world-space point on the penetrating edge
    depth : float, always 0.0 (CInDeR does not measure penetration depth)
    """

    def __init__(self, names: tuple[str, str], point: np.ndarray, edge: int) -> None:
        self.names = set(names)
        self._names = names
        self.point = point
        self.depth = 0.0
        self.edge = edge

    def index(self, name: str) -> int:
        """The edge index of the contact on ``name`` (-1 for the penetrated object)."""
        return self.edge if name == self._names[0] else -1

    def __repr__(self) -> str:
        return f"ContactData(names={self._names}, point={self.point.tolist()})"


class CollisionManager:
    """Collision checks among named meshes, with trimesh's method names.

    Keywords (``tolerance``, ``strategy``, ...) configure the :class:`Detector` it owns.
    """

    def __init__(self, *, view: View | list[View] | None = None, **detector_options: Any) -> None:
        self._detector = Detector(**detector_options)
        self._view = view
        self._objs: dict[str, dict[str, Any]] = {}

    # -- trimesh's interface --------------------------------------------------------------------

    def add_object(self, name: str, mesh: Any, transform: np.ndarray | None = None) -> str:
        """Add (or replace) the object ``name`` with ``mesh`` at ``transform`` ((4, 4) float)."""
        transform = np.eye(4) if transform is None else np.asarray(transform, dtype=np.float64)
        if transform.shape != (4, 4):
            raise ValueError("transform must be (4,4)!")
        self._objs[name] = {"mesh": mesh, "transform": transform}
        return name

    def remove_object(self, name: str) -> None:
        if name not in self._objs:
            raise ValueError(f"{name} not in collision manager!")
        del self._objs[name]

    def set_transform(self, name: str, transform: np.ndarray) -> None:
        if name not in self._objs:
            raise ValueError(f"{name} not in collision manager!")
        transform = np.asarray(transform, dtype=np.float64)
        if transform.shape != (4, 4):
            raise ValueError("transform must be (4,4)!")
        self._objs[name]["transform"] = transform

    def in_collision_internal(self, return_names: bool = False, return_data: bool = False):
        """Whether any two managed objects collide.

        Returns ``is_collision``, plus a set of sorted name pairs if ``return_names``, plus a list
        of :class:`ContactData` if ``return_data``.
        """
        names = list(self._objs)
        result = self._query([self._objs[n] for n in names], names)
        pairs = {tuple(sorted((names[i], names[j]))) for i, j in result.pairs.tolist()}
        data = self._contacts(result, names) if return_data else []
        return self._answer(bool(pairs), pairs, data, return_names, return_data)

    def in_collision_single(self, mesh: Any, transform: np.ndarray | None = None,
                            return_names: bool = False, return_data: bool = False):
        """Whether ``mesh`` at ``transform`` collides with any managed object.

        With ``return_names``, also the set of names of the objects it collides with.
        """
        names = list(self._objs)
        t = np.eye(4) if transform is None else np.asarray(transform, dtype=np.float64)
        entries = [self._objs[n] for n in names] + [{"mesh": mesh, "transform": t}]
        result = self._query(entries, names + [EXTERNAL])
        ext = len(names)
        hits = result.pairs[(result.pairs == ext).any(axis=1)]
        colliding = {names[int(i)] for i in hits[hits != ext].tolist()}
        data = []
        if return_data:
            data = [c for c in self._contacts(result, names + [EXTERNAL]) if EXTERNAL in c.names]
        return self._answer(bool(colliding), colliding, data, return_names, return_data)

    def in_collision_other(self, other_manager: CollisionManager, return_names: bool = False,
                           return_data: bool = False):
        """Whether any object of this manager collides with any object of ``other_manager``.

        With ``return_names``, also the set of (this name, other name) pairs.
        """
        mine, theirs = list(self._objs), list(other_manager._objs)
        entries = [self._objs[n] for n in mine] + [other_manager._objs[n] for n in theirs]
        result = self._query(entries, [f"a:{n}" for n in mine] + [f"b:{n}" for n in theirs])
        k = len(mine)
        pairs = result.pairs[(result.pairs[:, 0] < k) & (result.pairs[:, 1] >= k)]
        found = {(mine[i], theirs[j - k]) for i, j in pairs.tolist()}
        data = []
        if return_data:
            everyone = mine + theirs
            data = [c for c in self._contacts(result, everyone)
                    if (everyone.index(c._names[0]) < k) != (everyone.index(c._names[1]) < k)]
        return self._answer(bool(found), found, data, return_names, return_data)

    # -- helpers --------------------------------------------------------------------------------

    def _query(self, entries: Iterable[dict[str, Any]], labels: list[str]) -> CollisionResult:
        entries = list(entries)
        return self._detector.find_collisions(
            [e["mesh"] for e in entries], [e["transform"] for e in entries] or None,
            view=self._view, names=labels)

    @staticmethod
    def _contacts(result: CollisionResult, names: list[str]) -> list[ContactData]:
        points = result.points()
        return [ContactData((names[r["penetrating"]], names[r["penetrated"]]), p, int(r["edge"]))
                for r, p in zip(result.records, points)]

    @staticmethod
    def _answer(hit: bool, names: Any, data: list, return_names: bool, return_data: bool):
        if return_names and return_data:
            return hit, names, data
        if return_names:
            return hit, names
        if return_data:
            return hit, data
        return hit

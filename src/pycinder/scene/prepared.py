"""Bodies checked once, for queries that change only transforms.

:meth:`pycinder.Detector.prepare` checks and measures every mesh once and returns
:class:`PreparedBodies`; a query given them (in place of the list of bodies) checks only its
transforms, so a rigid scene's host work no longer grows with its meshes (1,000 small bodies:
about 10 ms of hashing and checking per query, spared). Bodies that deform are told with
:meth:`PreparedBodies.update`, which checks only their new vertices.

Like trimesh's ``CollisionManager``, which builds its BVHs when objects are added, prepared bodies
are the meshes as they were when prepared: a vertex array edited in place later is not seen until
it is passed to :meth:`~PreparedBodies.update`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .bodies import (Scene, Shape, ShapeCache, _shapes_of, body_label, check_transforms,
                     mesh_arrays)


class PreparedBodies(Sequence):
    """Meshes checked once (see the module's docstring); a sequence of the meshes as given.

    Parameters
    ----------
    bodies : sequence of trimesh.Trimesh or (vertices (V, 3), faces (F, 3)) pairs
    names : sequence of str or None, optional
        Names for messages and results.
    cache : ShapeCache
        Shapes and topologies seen before (the detector's).
    strict : bool
        Raise instead of warning for open, inside-out and zero-area meshes.
    max_bodies : int, optional
        Most bodies one query can hold.
    """

    def __init__(self, bodies: Sequence[Any], names: Sequence[str | None] | None = None, *,
                 cache: ShapeCache, strict: bool = False, max_bodies: int | None = None
                 ) -> None:
        if isinstance(bodies, (str, bytes)) or not isinstance(bodies, Sequence):
            bodies = list(bodies)
        self.names = _checked_names(len(bodies), names, max_bodies)
        self._bodies = list(bodies)
        self._cache, self._strict = cache, strict
        cache.begin_query()
        try:
            shapes, body_shape = _shapes_of(self._bodies, self.names, cache, strict)
        finally:
            cache.end_query()
        self._set(shapes, body_shape)

    def _set(self, shapes: list[Shape], body_shape: np.ndarray) -> None:
        """Keep the shapes some body uses, and each body's offset (see :class:`Scene`)."""
        used, body_shape = np.unique(body_shape, return_inverse=True)
        self.shapes = [shapes[k] for k in used]
        self.body_shape = body_shape.astype(np.int64)
        self._offsets = np.array([s.offset for s in self.shapes]).reshape(-1, 3)[self.body_shape]

    def __len__(self) -> int:
        return len(self._bodies)

    def __getitem__(self, index: Any) -> Any:
        return self._bodies[index]

    def __repr__(self) -> str:
        return (f"PreparedBodies({len(self)} bodies, {len(self.shapes)} distinct meshes, "
                f"{sum(len(s.topology.faces) for s in self.shapes):,} triangles)")

    def update(self, index: int | Sequence[int], vertices: Any) -> None:
        """New vertices for bodies that moved: ``index`` one body or several, ``vertices`` its
        (V, 3) array or one array per body. Each keeps its faces; the vertices are checked now
        (they may differ in count only as far as the faces allow).

        Raises
        ------
        ValueError
            Bad vertices, naming the body; the bodies are then as they were.
        IndexError
            A body that is not among these.
        """
        many = not np.isscalar(index)
        which = [int(i) for i in (index if many else [index])]
        arrays = list(vertices) if many else [vertices]
        if len(arrays) != len(which):
            raise ValueError(f"update got {len(arrays)} vertex arrays for {len(which)} bodies")
        for i in which:
            if not -len(self) <= i < len(self):
                raise IndexError(f"body {i}: there are {len(self)} bodies")
        which = [i % len(self) for i in which]
        meshes = []
        for i, v in zip(which, arrays):
            label = body_label(i, self.names[i])
            meshes.append((v, mesh_arrays(self._bodies[i], label)[1], label))
        self._cache.begin_query()
        try:
            new = self._cache.get_many(meshes, self._strict)
        finally:
            self._cache.end_query()
        shapes, body_shape = list(self.shapes), self.body_shape.copy()
        for (v, faces, _), i, shape in zip(meshes, which, new):
            body_shape[i] = len(shapes)
            shapes.append(shape)
            self._bodies[i] = (v, faces)
        self._set(shapes, body_shape)

    def scene(self, transforms: Any = None) -> Scene:
        """The validated scene of a query at ``transforms`` (N, 4, 4) (None: identities),
        checked like any query's."""
        return self._scene(check_transforms(transforms, len(self), self.names))

    def _scene(self, checked: np.ndarray) -> Scene:
        # The stored vertices are relative to each shape's offset: fold it into the transforms
        # (a copy of the caller's, made by check_transforms).
        checked[:, :3, 3] += np.einsum("nij,nj->ni", checked[:, :3, :3], self._offsets)
        return Scene(self.shapes, self.body_shape, checked, self.names)


def prepare_scene(bodies: Sequence[Any], transforms: Any = None, *,
                  names: Sequence[str | None] | None = None, strict: bool = False,
                  cache: ShapeCache | None = None, max_bodies: int | None = None) -> Scene:
    """Validate bodies and transforms (the transforms first).

    Parameters
    ----------
    bodies : sequence of trimesh.Trimesh or (vertices (V, 3), faces (F, 3)) pairs
    transforms : None or (N, 4, 4) float
        World-from-body matrices.
    names : sequence of str or None, optional
        Names for messages.
    strict : bool
        Raise instead of warning for open, inside-out and zero-area meshes.
    cache : ShapeCache, optional
        Shapes seen before (a detector keeps one).
    max_bodies : int, optional
        Most bodies the caller can handle.

    Returns
    -------
    Scene
    """
    if isinstance(bodies, (str, bytes)) or not isinstance(bodies, Sequence):
        bodies = list(bodies)
    names = _checked_names(len(bodies), names, max_bodies)
    checked = check_transforms(transforms, len(bodies), names)
    prepared = PreparedBodies(bodies, names, cache=cache if cache is not None else ShapeCache(),
                              strict=strict)
    return prepared._scene(checked)


def _checked_names(n: int, names: Sequence[str | None] | None, max_bodies: int | None
                   ) -> list[str | None]:
    """A name (or None) per body, once the number of bodies is known to be allowed."""
    if max_bodies is not None and n > max_bodies:
        raise ValueError(f"{n} bodies is more than the {max_bodies} one query can hold; split "
                         "the scene into several queries")
    out = list(names) if names is not None else [None] * n
    if len(out) != n:
        raise ValueError(f"names must give one name per body: {len(out)} names, {n} bodies")
    return out

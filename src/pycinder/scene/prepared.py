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

import threading
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..util.text import plural
from .bodies import Scene, Shape, ShapeCache, _shapes_of, body_label, check_transforms, mesh_arrays


class PreparedBodies(Sequence):
    """Meshes checked once (see the module's docstring); a sequence of the bodies: the meshes as
    given, and ``(vertices, faces)`` for a body given new vertices by :meth:`update`.

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
    lock : threading.RLock, optional
        Held while the bodies change and while a query reads them (the detector's: its queries
        and the cache are serialised by it).
    """

    def __init__(self, bodies: Sequence[Any], names: Sequence[str | None] | None = None, *,
                 cache: ShapeCache, strict: bool = False, max_bodies: int | None = None,
                 lock: threading.RLock | None = None) -> None:
        if isinstance(bodies, (str, bytes)) or not isinstance(bodies, Sequence):
            bodies = list(bodies)
        self.names = _checked_names(len(bodies), names, max_bodies)
        self._bodies = list(bodies)
        self._cache, self._strict = cache, strict
        self._lock = lock if lock is not None else threading.RLock()
        with self._lock:
            cache.begin_query()
            try:
                shapes, body_shape = _shapes_of(self._bodies, self.names, cache, strict)
            finally:
                cache.end_query()
        self._state = _state(shapes, body_shape)
        self._faces = [mesh_arrays(b, body_label(i, self.names[i]))[1]
                       for i, b in enumerate(self._bodies)]
        """Each body's face array (the object) as its topology was found from."""

    @property
    def shapes(self) -> list[Shape]:
        """The distinct shapes, each once."""
        return self._state[0]

    @property
    def body_shape(self) -> np.ndarray:
        """(N,) int64: each body's shape."""
        return self._state[1]

    def __len__(self) -> int:
        return len(self._bodies)

    def __getitem__(self, index: Any) -> Any:
        return self._bodies[index]

    def __repr__(self) -> str:
        shapes = self.shapes
        return (f"PreparedBodies({len(self)} bodies, {len(shapes)} distinct meshes, "
                f"{sum(len(s.topology.faces) for s in shapes):,} triangles)")

    def update(self, index: int | Sequence[int], vertices: Any) -> None:
        """New vertices for bodies that deformed; each keeps its faces. A body whose faces are
        still the array they were when it was prepared keeps their topology, not looked up
        again (that array edited in place since is not seen: prepare the bodies again); faces
        replaced by another array (a trimesh's ``faces`` set anew) are looked up, and so are
        the faces of new vertices of another count.

        Parameters
        ----------
        index : int or sequence of int
            One body, or several.
        vertices : (V, 3) real, or a sequence of them
            Its vertices, or one array per body (V may change as far as the faces allow). They
            are checked and copied now (not hashed: they are taken to be new), so editing an
            array later changes nothing until it is passed here again (a result's
            :meth:`~pycinder.CollisionResult.contacts` come from its own records: results made
            before are unchanged).

        Raises
        ------
        ValueError
            Bad vertices, naming the body; the bodies are then as they were.
        IndexError
            A body that is not among these.
        """
        many = np.ndim(index) > 0
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
        with self._lock:
            shapes, body_shape = list(self.shapes), self.body_shape.copy()
            # An update is not a query: it ages none of the cache's shapes, and the shapes it
            # makes are held here only (a loop of updates leaves nothing in the cache). A body
            # whose face array is the one its topology was found from keeps that topology.
            own = [shapes[int(body_shape[i])].topology if faces is self._faces[i] else None
                   for (_, faces, _), i in zip(meshes, which)]
            new = self._cache.get_many(meshes, self._strict, keep=False, topologies=own)
            users = np.bincount(body_shape, minlength=len(shapes)).tolist()
            for (v, faces, _), i, shape in zip(meshes, which, new):
                old = int(body_shape[i])
                if users[old] == 1:
                    shapes[old] = shape  # its own shape: the same slot keeps the GPU's layout
                else:
                    users[old] -= 1
                    body_shape[i] = len(shapes)
                    shapes.append(shape)
                    users.append(1)
                self._bodies[i] = (v, faces)
                self._faces[i] = faces
            self._state = _state(shapes, body_shape)

    def scene(self, transforms: Any = None) -> Scene:
        """The validated scene of a query at ``transforms`` (N, 4, 4) (None: identities),
        checked like any query's."""
        return self._scene(check_transforms(transforms, len(self), self.names))

    def copies(self, index: np.ndarray, transforms: np.ndarray,
               names: Sequence[str | None] | None = None, *,
               boxes: tuple[np.ndarray, np.ndarray] | None = None) -> Scene:
        """The validated scene of copies of these bodies (many small scenes in one query: a
        robot's configurations), with no mesh checked again.

        Parameters
        ----------
        index : (M,) int
            The body each copy is of.
        transforms : (M, 4, 4) float
            Each copy's world-from-body matrix (checked as a query's).
        names : sequence of str or None, optional
            Each copy's name, for messages (any sequence: it is read only for the copy named).
        boxes : ((M, 3), (M, 3)) float, optional
            World boxes known to hold each copy at ``transforms`` (a robot check's, made on the
            GPU): the scene's :meth:`~Scene.world_boxes`, not measured again.

        Returns
        -------
        Scene
        """
        index = np.asarray(index, dtype=np.int64)
        names = [None] * len(index) if names is None else names
        return self._copies(index, check_transforms(transforms, len(index), names), names,
                            boxes)

    def _copies(self, index: np.ndarray, checked: np.ndarray, names: Sequence[str | None],
                boxes: tuple[np.ndarray, np.ndarray] | None = None) -> Scene:
        """:meth:`copies` of transforms ``checked`` (M, 4, 4) float64 that need no checking
        (checked by :meth:`copies`, or made by pycinder itself: a robot check's poses from pass
        K1, finite and proper by construction), which the scene takes over."""
        if index.ndim != 1 or (len(index) and (index.min() < 0 or index.max() >= len(self))):
            raise ValueError(f"index must be (M,) body indices below {len(self)}")
        scene = self._scene(checked, index, names)
        if boxes is not None:
            lo, hi = (np.asarray(b, np.float64) for b in boxes)
            if lo.shape != (len(index), 3) or hi.shape != (len(index), 3):
                raise ValueError(f"boxes must be two (M, 3) arrays for {len(index)} copies, "
                                 f"got {lo.shape} and {hi.shape}")
            scene.boxes = (lo, hi)
        return scene

    def _scene(self, checked: np.ndarray, index: np.ndarray | None = None,
               names: Sequence[str | None] | None = None) -> Scene:
        """The scene of checked transforms: of every body, or of the copies ``index`` named
        ``names``."""
        with self._lock:
            shapes, body_shape, offsets, per_body = self._state
        if index is not None:  # copies: their own per-body arrays
            body_shape, offsets, per_body = body_shape[index], offsets[index], {}
        # The stored vertices are relative to each shape's offset: fold it into the transforms
        # (a copy of the caller's, made by check_transforms).
        checked[:, :3, 3] += np.einsum("nij,nj->ni", checked[:, :3, :3], offsets)
        return Scene(shapes, body_shape, checked,
                     list(self.names) if names is None else names,  # type: ignore[arg-type]
                     per_body=per_body)


def _state(shapes: list[Shape], body_shape: np.ndarray
           ) -> tuple[list[Shape], np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The shapes some body uses, each once (by identity), in their first order; each body's
    index among them; each body's offset (see :class:`Scene`); and the per-body arrays every
    query's scene shares (:attr:`Scene.per_body`): one tuple, replaced whole."""
    index: dict[int, int] = {}
    kept: list[Shape] = []
    remap = np.empty(len(shapes), dtype=np.int64)
    used = np.zeros(len(shapes), dtype=bool)
    used[body_shape] = True
    for k, shape in enumerate(shapes):
        if used[k]:
            remap[k] = index.setdefault(id(shape), len(kept))
            if remap[k] == len(kept):
                kept.append(shape)
    body_shape = remap[body_shape]
    offsets = np.array([s.offset for s in kept]).reshape(-1, 3)[body_shape]
    return kept, body_shape, offsets, {}


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


def check_body_count(n: int, max_bodies: int | None) -> None:
    """Raise ``ValueError`` when ``n`` bodies are more than one query holds."""
    if max_bodies is not None and n > max_bodies:
        raise ValueError(f"{n} bodies is more than the {max_bodies} one query can hold; split "
                         "the scene into several queries")


def _checked_names(n: int, names: Sequence[str | None] | None, max_bodies: int | None
                   ) -> list[str | None]:
    """A name (or None) per body, once the number of bodies is known to be allowed."""
    check_body_count(n, max_bodies)
    out = list(names) if names is not None else [None] * n
    if len(out) != n:
        raise ValueError(f"names must give one name per body: {plural(len(out), 'name')}, "
                         f"{plural(n, 'body')}")
    return out

"""Scenes of a batch run: manifest lines in, checked scene entries out; meshes loaded by path.

A manifest is JSON lines, one scene a line::

    {"id": "a-17", "tolerance": 0.001,
     "bodies": [{"mesh": "parts/bracket.stl", "transform": [[1, 0, 0, 0], ...], "name": "bracket"},
                ...]}

``id`` (a string or an integer, unique) names the scene in the results; ``tolerance`` (world
units) and each body's ``transform`` (4 x 4, world from body; default identity) and ``name`` are
optional. Mesh paths are relative to the manifest's folder. In the Python API a body's ``mesh``
may also be a trimesh mesh or a ``(vertices, faces)`` pair; those travel with their scene,
while meshes given by path are loaded once per worker.
"""

from __future__ import annotations

import json
import os
import warnings
from collections import OrderedDict
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np


class ManifestError(ValueError):
    """A manifest that cannot be read: a line that is not a JSON object, an id missing,
    of the wrong type or repeated."""


def id_key(scene_id: Any) -> str:
    """The key an id is compared by (``1`` and ``"1"`` are different ids)."""
    return json.dumps(scene_id)


def check_id(scene_id: Any, where: str) -> Any:
    if isinstance(scene_id, bool) or not isinstance(scene_id, (str, int)):
        raise ManifestError(f"{where}: id must be a string or an integer, got {scene_id!r}")
    return scene_id


def read_manifest(path: str | Path) -> Iterator[dict]:
    """The scenes of a manifest file, in order, each a dict with ``id`` checked and unique.

    Raises ManifestError naming the file and line of the first line that is not a JSON object
    with a usable id, before any scene is yielded past it.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such manifest")
    seen: dict[str, int] = {}
    with open(path, encoding="utf-8") as f:
        for lineno, line in enumerate(f, 1):
            if not line.strip():
                continue
            where = f"{path}:{lineno}"
            try:
                entry = json.loads(line)
            except json.JSONDecodeError as exc:
                raise ManifestError(f"{where}: not JSON ({exc.msg} at column {exc.colno})") \
                    from None
            if not isinstance(entry, dict):
                raise ManifestError(f"{where}: a scene must be a JSON object, got "
                                    f"{type(entry).__name__}")
            if "id" not in entry:
                raise ManifestError(f"{where}: the scene has no id")
            key = id_key(check_id(entry["id"], where))
            if key in seen:
                raise ManifestError(f"{where}: id {entry['id']!r} repeats line {seen[key]}")
            seen[key] = lineno
            yield entry


def normalize(entry: Any, position: int, base: str | Path | None = None) -> dict:
    """A scene entry checked for structure, with mesh paths made absolute.

    Parameters
    ----------
    entry : dict
        ``{"id", "tolerance", "bodies": [{"mesh", "transform", "name"}, ...]}``.
    position : int
        Its place in the input: the id when it has none.
    base : path, optional
        Folder that relative mesh paths start from (default: the working directory).

    Raises
    ------
    ValueError
        Naming the scene and the body, for a problem no worker could get past.
    """
    if not isinstance(entry, dict):
        raise ValueError(f"scene {position}: expected a dict with 'bodies', got "
                         f"{type(entry).__name__}")
    scene_id = check_id(entry.get("id", position), f"scene {position}")
    where = f"scene {scene_id!r}"
    unknown = set(entry) - {"id", "tolerance", "bodies"}
    if unknown:
        raise ValueError(f"{where}: unknown keys {sorted(unknown)} (a scene has id, tolerance, "
                         "bodies)")
    bodies = entry.get("bodies")
    if not isinstance(bodies, (list, tuple)):
        raise ValueError(f"{where}: 'bodies' must be a list of bodies")
    out = []
    for j, body in enumerate(bodies):
        label = f"{where} body {j}"
        if not isinstance(body, dict) or "mesh" not in body:
            raise ValueError(f"{label}: a body is a dict with 'mesh' (and 'transform', 'name')")
        unknown = set(body) - {"mesh", "transform", "name"}
        if unknown:
            raise ValueError(f"{label}: unknown keys {sorted(unknown)}")
        mesh = body["mesh"]
        if isinstance(mesh, (str, os.PathLike)):
            mesh = os.path.abspath(os.path.join(base or os.getcwd(), os.fspath(mesh)))
        transform = body.get("transform")
        if transform is not None:
            try:
                transform = np.asarray(transform, dtype=np.float64)
            except (TypeError, ValueError):
                raise ValueError(f"{label}: transform must be 4 x 4 numbers") from None
            if transform.shape != (4, 4):
                raise ValueError(f"{label}: transform must be 4 x 4, got shape "
                                 f"{transform.shape}")
        name = body.get("name")
        if name is not None and not isinstance(name, str):
            raise ValueError(f"{label}: name must be a string, got {name!r}")
        out.append({"mesh": mesh, "transform": transform, "name": name})
    tolerance = entry.get("tolerance")
    if tolerance is not None and (isinstance(tolerance, bool)
                                  or not isinstance(tolerance, (int, float))):
        raise ValueError(f"{where}: tolerance must be a number of world units, got "
                         f"{tolerance!r}")
    return {"id": scene_id, "tolerance": tolerance, "bodies": out}


def body_name(body: dict, j: int) -> str:
    """A body's name in results: its own, else its mesh file's name, else its index."""
    if body.get("name"):
        return body["name"]
    if isinstance(body["mesh"], str):
        return os.path.basename(body["mesh"])
    return f"body {j}"


def body_label(scene_id: Any, j: int, name: str) -> str:
    """A body in messages: its scene's id, its place and its name (:func:`body_name`), as in
    ``scene 'a-17' body 1 ('bracket')``."""
    return f"scene {scene_id!r} body {j} ({name!r})"


class MeshCache:
    """Meshes by path, each read and checked once (least recently used out, bounded by bytes).

    Parameters
    ----------
    shapes : pycinder.scene.ShapeCache
        The detector's shapes: a mesh is checked into it when read, so that its warnings
        (open, inside out) are kept with the mesh and given to every scene that uses it.
    strict : bool
        Open, inside-out and zero-area meshes are errors.
    max_bytes : int
    """

    def __init__(self, shapes: Any, strict: bool = False, max_bytes: int = 1 << 30) -> None:
        self.shapes = shapes
        self.strict = strict
        self.max_bytes = max_bytes
        self.nbytes = 0
        self.loads = 0
        self._entries: OrderedDict[str, tuple[Any, list[str]]] = OrderedDict()

    def get(self, path: str) -> tuple[Any, list[str]]:
        """The mesh at ``path`` (a trimesh.Trimesh) and the warnings it raised."""
        hit = self._entries.get(path)
        if hit is not None:
            self._entries.move_to_end(path)
            return hit
        mesh = _single_mesh(path)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            self.shapes.get(mesh.vertices, mesh.faces, path, self.strict)
        entry = (mesh, sorted({str(w.message) for w in caught}))
        self.loads += 1
        self._entries[path] = entry
        self.nbytes += mesh.vertices.nbytes + mesh.faces.nbytes
        while self.nbytes > self.max_bytes and len(self._entries) > 1:
            _, (old, _) = self._entries.popitem(last=False)
            self.nbytes -= old.vertices.nbytes + old.faces.nbytes
        return entry


def _single_mesh(path: str) -> Any:
    """The one mesh of a file, checked and loaded as ``pycinder check`` loads it (with its
    instance transform applied); a file that holds several bodies is an error here, since a
    manifest body names one mesh."""
    from ..files import display_name, load_file

    bodies = load_file(path, display_name(path))
    if len(bodies) != 1:
        raise ValueError(f"{display_name(path)} holds {len(bodies)} bodies "
                         f"({', '.join(b.name for b in bodies[:4])}...); a manifest body is one "
                         "mesh: list each part as a body of its own")
    body = bodies[0]
    if np.allclose(body.transform, np.eye(4)):
        return body.mesh
    mesh = body.mesh.copy()
    mesh.apply_transform(body.transform)
    return mesh

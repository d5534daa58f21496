"""Meshes from files, for ``pycinder check`` and ``pycinder debug-buffers``.

    paths -> checks before loading (kind of file, size, what its header claims)
          -> trimesh.load_scene -> one body per geometry instance of the scene graph
          -> checks after loading (triangles, NaN vertices) -> FileBody list

* **Formats**: STL, OBJ, PLY, OFF, glTF (``.gltf`` and ``.glb``) and 3MF (which needs lxml:
  ``pip install 'pycinder[files]'``). Point clouds and 2-D drawings are not meshes. IFC files
  (``.ifc``) are read by :mod:`pycinder.files.ifc_elements`, one body per element (``pip install
  'pycinder[bim]'``).
* **Scene files** (glTF, 3MF, OBJ with several ``o`` objects) give one body per geometry instance,
  named ``file:node`` after the scene graph, with the instance's transform; a file with one body
  is named after the file alone.
* **Limits** (:class:`Limits`) are checked before anything is loaded: the file's size, what an
  archive unpacks to, and the triangle count its header claims (or, for text formats, a count of
  its face lines). A binary STL whose header claims more triangles than the file holds, or a glTF
  buffer claiming more bytes than it has, is refused as such.
* **Names**: any file name works, including bytes that are not UTF-8: files are opened by Python
  and handed to trimesh as open files, and names are shown with such bytes escaped.
* **Units** are not converted: coordinates are used as they are in each file. Files that declare
  different units (3MF and glTF do) get a warning.
* **Duplicates**: a file given twice (the same path) gives bodies named ``a.stl#1`` and
  ``a.stl#2``, in the order given.
* **Components**: a body may hold several disconnected parts (two boxes in one STL file).
  :func:`split_components` makes each part a body of its own, named ``a.stl[0]``, ``a.stl[1]``,
  ... in the order of their first triangles in the file; without it,
  :func:`warn_overlapping_components` warns about a body whose parts overlap each other (one
  body is never tested against itself).

Every problem raises :class:`FileError` with the file's name and what is wrong with it;
:func:`load_bodies` reads every file and raises one :class:`FileErrors` naming every bad file.
"""

from __future__ import annotations

import logging
import os
import re
import warnings
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..util.text import plural

from .checks import (DEFAULT_MAX_BYTES, DEFAULT_MAX_TRIANGLES, MAX_ARCHIVE_MEMBERS, MESH_FORMATS,
                     FileBody, FileCheck, FileError, FileErrors, FileWarning, Limits,
                     OverlappingComponentsWarning, check_file, display_name, file_labels,
                     human_bytes, parse_size)

if TYPE_CHECKING:
    from ..detector import Detector
    from ..result import Stats


# -- loading --------------------------------------------------------------------------------


class _TrimeshLog(logging.Handler):
    """Collects what trimesh logs while it loads a file (nothing reaches stderr on its own)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


def _load_scene(path: str, ext: str, label: str) -> tuple[Any, list[str]]:
    """trimesh's scene of the file, and what trimesh logged on the way."""
    import trimesh

    if ext == "3mf":
        from ..util.optional import require

        require("lxml", f"{label}: reading 3MF files", "files")
    log = logging.getLogger("trimesh")
    handler = _TrimeshLog()
    propagate = log.propagate
    log.addHandler(handler)
    log.propagate = False
    options: dict[str, Any] = {"process": False}
    if ext == "obj":
        options.update(split_objects=True, group_material=False)
    try:
        with open(path, "rb") as f:
            scene = trimesh.load_scene(f, file_type=ext,
                                       resolver=trimesh.resolvers.FilePathResolver(
                                           os.path.abspath(path)), **options)
    except Exception as exc:  # trimesh raises many types; the message says which and why
        why = str(exc) or type(exc).__name__
        raise FileError(f"{label}: could not parse it as {MESH_FORMATS[ext]}: {why}") from exc
    finally:
        log.removeHandler(handler)
        log.propagate = propagate
    return scene, handler.messages


def _natural(text: str) -> list[Any]:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", text)]


def _nonfinite_message(label: str, ext: str, path: str, vertices: np.ndarray) -> str | None:
    """What is wrong with NaN or infinite vertices of a geometry, or None."""
    bad = ~np.isfinite(vertices).all(axis=1)
    if not bad.any():
        return None
    n = int(bad.sum())
    first = int(np.flatnonzero(bad)[0])
    count = plural(n, "vertex", "vertices") + (" is" if n == 1 else " are")
    if ext == "obj":
        line = _obj_vertex_line(path)
        where = f"vertex {line[0]} on line {line[1]}" if line else f"vertex {first + 1}"
        return f"{label}: {count} NaN or infinite (first: {where}, counting from 1 as OBJ does)"
    if ext == "stl":
        return f"{label}: {count} NaN or infinite (first: a corner of triangle {first // 3 + 1}, " \
               "counting from 1)"
    return f"{label}: {count} NaN or infinite (first: vertex {first}, counting from 0 as the " \
           "file's faces do)"


def _obj_vertex_line(path: str) -> tuple[int, int] | None:
    """(vertex number from 1, line number from 1) of the first non-finite ``v`` line."""
    vertex = 0
    with open(path, "rb") as f:
        for line_no, line in enumerate(f, 1):
            if line.startswith(b"v ") or line.startswith(b"v\t"):
                vertex += 1
                try:
                    values = [float(w) for w in line.split()[1:4]]
                except ValueError:
                    return vertex, line_no
                if not np.isfinite(values).all():
                    return vertex, line_no
    return None


def load_file(path: str, label: str, limits: Limits = Limits()) -> list[FileBody]:
    """The bodies of one file (see the module's doc), checked.

    Parameters
    ----------
    path : str
        The file (any name the operating system allows).
    label : str
        How messages name it.
    limits : Limits

    Returns
    -------
    list of FileBody
        One per geometry instance; warnings (:class:`FileWarning`) for parts left out and for
        what trimesh reported while loading.

    Raises
    ------
    FileError
    """
    import trimesh

    ext = check_file(path, label, limits)
    if ext == "ifc":  # one body per element, by IfcOpenShell (pycinder[bim])
        from .ifc_elements import load_file as load_ifc

        return load_ifc(path, label, limits)
    scene, logged = _load_scene(path, ext, label)
    for message in logged:
        warnings.warn(f"{label}: trimesh: {message}", FileWarning, stacklevel=2)
    nodes = sorted(scene.graph.nodes_geometry, key=_natural)
    meshes = {}
    left_out = []
    for node in nodes:
        transform, geometry = scene.graph[node]
        mesh = scene.geometry[geometry]
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            left_out.append((node, type(mesh).__name__))
        else:
            meshes[node] = (np.asarray(transform, np.float64), geometry)
    if not meshes:
        kinds = sorted({kind for _, kind in left_out})
        what = f" (it holds {', '.join(kinds)} only)" if left_out else ""
        raise FileError(f"{label}: holds no triangles{what}")
    several = len(meshes) > 1
    for node, kind in left_out:
        warnings.warn(f"{label}:{node} is a {kind} with no triangles: left out", FileWarning,
                      stacklevel=2)
    used = {geometry for _, geometry in meshes.values()}
    limits_check = FileCheck(path, label, ext, 0, limits)
    limits_check.triangles(sum(len(scene.geometry[g].faces) for g in used), "holds")
    for geometry in used:
        mesh = scene.geometry[geometry]
        where = label if not several else f"{label}:{geometry}"
        problem = _nonfinite_message(where, ext, path, np.asarray(mesh.vertices))
        if problem:
            raise FileError(problem)
        mesh.merge_vertices(merge_tex=True, merge_norm=True)  # by position alone
    units = getattr(scene, "units", None)
    return [FileBody(f"{label}:{node}" if several else label, scene.geometry[geometry],
                     transform, units) for node, (transform, geometry) in meshes.items()]


def load_bodies(paths: Sequence[str], limits: Limits = Limits(),
                progress: Callable[[int, int, str], None] | None = None) -> list[FileBody]:
    """The bodies of several files, named by :func:`file_labels`, checked and loaded in turn.

    Every file is read, also after one that cannot be used, so that one error names every bad
    file.

    Parameters
    ----------
    paths : sequence of str
    limits : Limits
    progress : callable, optional
        Called as ``progress(done, total, label)`` before each file.

    Returns
    -------
    list of FileBody

    Raises
    ------
    FileErrors
        Naming every file that cannot be used (also one that needs a package that is not
        installed), one message per file in its ``messages``, in the order given.
    """
    bodies: list[FileBody] = []
    errors: list[str] = []
    for k, (path, label) in enumerate(zip(paths, file_labels(paths))):
        if progress:
            progress(k, len(paths), label)
        try:
            bodies += load_file(path, label, limits)
        except (FileError, ImportError) as exc:
            errors.append(str(exc))
    if errors:
        raise FileErrors(errors)
    units = {b.units for b in bodies if b.units}
    if len(units) > 1:
        declared = ", ".join(sorted({f"{b.name.split(':')[0]} in {b.units}" for b in bodies
                                     if b.units}))
        warnings.warn(f"the files declare different units ({declared}); pycinder compares "
                      "coordinates as they are, without converting them", FileWarning,
                      stacklevel=2)
    return bodies


def component_labels(links: np.ndarray, n: int) -> np.ndarray:
    """The connected component of each of ``n`` nodes joined by ``links``, in NumPy alone (the
    base install has neither SciPy nor networkx, which trimesh's graph functions need).

    Parameters
    ----------
    links : (E, 2) int
        Pairs of joined nodes.
    n : int
        Nodes.

    Returns
    -------
    (n,) int64
        Each node's component, named by its smallest node.
    """
    label = np.arange(n, dtype=np.int64)
    a, b = np.asarray(links, dtype=np.int64).reshape(-1, 2).T
    while True:  # the smaller label crosses each link, then labels point at their own labels
        joined = np.minimum(label[a], label[b])
        new = label.copy()
        np.minimum.at(new, a, joined)
        np.minimum.at(new, b, joined)
        new = new[new]
        if np.array_equal(new, label):
            return label
        label = new


def components(mesh: Any) -> list[Any]:
    """The disconnected parts of ``mesh`` (sharing no edge), in the order of their first
    triangles; ``[mesh]`` itself when it is one part."""
    labels = component_labels(np.asarray(mesh.face_adjacency), len(mesh.faces))
    found, first, which = np.unique(labels, return_index=True, return_inverse=True)
    if len(found) < 2:
        return [mesh]
    by_part = np.split(np.argsort(which, kind="stable"), np.cumsum(np.bincount(which))[:-1])
    faces = [by_part[k] for k in np.argsort(first)]
    return mesh.submesh(faces, only_watertight=False, append=False)


def body_components(bodies: Sequence[FileBody]) -> list[list[Any]]:
    """Each body's :func:`components`; a geometry placed several times is split once."""
    split: dict[int, list[Any]] = {}
    for body in bodies:
        if id(body.mesh) not in split:
            split[id(body.mesh)] = components(body.mesh)
    return [split[id(body.mesh)] for body in bodies]


def split_components(bodies: Sequence[FileBody]) -> list[FileBody]:
    """Each body's disconnected parts as bodies of their own, named ``name[0]``, ``name[1]``,
    ... (in the order of their first triangles); a body of one part is kept as it is.

    Parameters
    ----------
    bodies : sequence of FileBody

    Returns
    -------
    list of FileBody
    """
    out = []
    for body, pieces in zip(bodies, body_components(bodies)):
        if len(pieces) == 1:
            out.append(body)
        else:
            out += [FileBody(f"{body.name}[{k}]", piece, body.transform, body.units)
                    for k, piece in enumerate(pieces)]
    return out



# -- what one query of the bodies does not say ----------------------------------------------


def tolerance_range(bodies: Sequence[FileBody], stats: Stats, tolerance: float | None = None
                    ) -> list[float] | None:
    """The tolerance of a focused query of ``bodies``, smallest and largest over its pairs (the
    ``tolerance`` of ``pycinder check --json``).

    Parameters
    ----------
    bodies : sequence of FileBody
        The N bodies the query ran on.
    stats : Stats
        The focused query's stats: its ``candidates`` and ``tolerance``.
    tolerance : float, optional
        The request's tolerance in world units (default: relative to each pair's smaller body,
        :func:`pycinder.tolerance.default_pair_tolerances`).

    Returns
    -------
    list of 2 float, or None
        [smallest, largest] in world units over the candidate pairs; with no candidate pair,
        what any pair of the bodies would have had; None with fewer than two bodies.
    """
    from ..tolerance import body_sizes, default_pair_tolerances

    if stats.candidates:
        return [float(t) for t in stats.tolerance]
    if len(bodies) < 2:
        return None
    lo = np.array([b.mesh.bounds[0] for b in bodies])
    hi = np.array([b.mesh.bounds[1] for b in bodies])
    size = np.sort(body_sizes(lo, hi, np.array([b.transform for b in bodies])))
    # A pair's default tolerance follows its smaller body: the smallest over all pairs is the
    # smallest body's, the largest the second largest body's.
    tol = default_pair_tolerances(size[[0, -2]], size[[1, -1]], tolerance)
    return [float(t) for t in tol]


def boxes_meeting(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Whether each box meets another one (the broad phase's sweep, touching included).

    Parameters
    ----------
    lo, hi : (n, 3) float
        The boxes' corners.

    Returns
    -------
    (n,) bool
        True for each box that meets at least one other box.
    """
    from ..focused.broad.broad_numpy import sweep_and_prune

    meets = np.zeros(len(lo), dtype=bool)
    meets[sweep_and_prune(lo, hi).ravel()] = True
    return meets


_QUERY_ERRORS = (ValueError, RuntimeError, OSError, TypeError, ImportError, MemoryError)
"""What a failed query of the components raises: said in a warning, not raised."""


def warn_overlapping_components(bodies: Sequence[FileBody], detector: Detector) -> None:
    """Warn (:class:`OverlappingComponentsWarning`) about each body whose disconnected
    components overlap each other, which one query of the bodies cannot report: one body is
    never tested against itself.

    Components whose bounding boxes meet (:func:`boxes_meeting`) are tested as bodies of their
    own by ``detector``, in one query; inside-out closed components (cavities of a hollow body)
    are left out. When that query fails, each body concerned gets a warning that says so.

    Parameters
    ----------
    bodies : sequence of FileBody
        The bodies, each made of one or more components (:func:`body_components`).
    detector : Detector
        The detector that ran the bodies' query (its request is the components' too).
    """
    parts: list[Any] = []
    transforms: list[np.ndarray] = []
    labels: list[tuple[int, int]] = []  # (body, component) of each part tested
    split = body_components(bodies)
    for b, (body, pieces) in enumerate(zip(bodies, split)):
        keep = [k for k, piece in enumerate(pieces)
                if len(pieces) > 1 and not (piece.is_watertight and piece.volume < 0)]
        lo = np.array([pieces[k].bounds[0] for k in keep]).reshape(-1, 3)
        hi = np.array([pieces[k].bounds[1] for k in keep]).reshape(-1, 3)
        touching = [k for k, meets in zip(keep, boxes_meeting(lo, hi)) if meets]
        parts += [pieces[k] for k in touching]
        transforms += [body.transform] * len(touching)
        labels += [(b, k) for k in touching]
    if not parts:
        return
    try:
        with warnings.catch_warnings():  # the bodies' own warnings are given already
            warnings.simplefilter("ignore")
            found = detector.find_collisions(parts, np.array(transforms)).pairs
    except _QUERY_ERRORS as exc:
        for b in sorted({b for b, _ in labels}):
            warnings.warn(f"{bodies[b].name}: its disconnected components could not be tested "
                          f"against each other ({exc}); pass --split to test them as bodies",
                          OverlappingComponentsWarning, stacklevel=2)
        return
    overlaps: dict[int, list[str]] = {}
    for i, j in found.tolist():
        (b, k), (c, m) = labels[i], labels[j]
        if b == c:
            overlaps.setdefault(b, []).append(f"[{min(k, m)}] and [{max(k, m)}]")
    for b, which in sorted(overlaps.items()):
        name, count = bodies[b].name, len(split[b])
        shown = ", ".join(sorted(which)[:5]) + (", ..." if len(which) > 5 else "")
        warnings.warn(
            f"{name}: {plural(count, 'disconnected component')}, of which "
            f"{plural(len(which), 'pair overlaps', 'pairs overlap')} ({shown}); a body is not "
            "tested against itself, so this is not reported as a collision: pass --split to "
            f"test each component as a body of its own ({name}[0], {name}[1], ...)",
            OverlappingComponentsWarning, stacklevel=2)

__all__ = [
    "DEFAULT_MAX_BYTES", "DEFAULT_MAX_TRIANGLES", "MAX_ARCHIVE_MEMBERS", "MESH_FORMATS", "FileBody",
    "FileError", "FileErrors", "FileWarning", "Limits", "OverlappingComponentsWarning",
    "body_components", "boxes_meeting", "check_file", "component_labels", "components",
    "display_name", "file_labels", "human_bytes", "load_bodies", "load_file", "parse_size",
    "split_components", "tolerance_range", "warn_overlapping_components",
]

"""Meshes from files, for ``pycinder check`` and ``pycinder debug-buffers``.

    paths -> checks before loading (kind of file, size, what its header claims)
          -> trimesh.load_scene -> one body per geometry instance of the scene graph
          -> checks after loading (triangles, NaN vertices) -> FileBody list

* **Formats**: STL, OBJ, PLY, OFF, glTF (``.gltf`` and ``.glb``) and 3MF (which needs lxml:
  ``pip install 'pycinder[files]'``). Point clouds and 2-D drawings are not meshes. IFC files
  (``.ifc``) are read by :mod:`pycinder.bim.ifc`, one body per element (``pip install
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
  ... in the order of their first triangles in the file.

Every problem raises :class:`FileError` with the file's name and what is wrong with it;
:func:`load_bodies` reads every file and raises one :class:`FileErrors` naming every bad file.
"""

from __future__ import annotations

import json
import logging
import os
import re
import struct
import warnings
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .util.text import plural

MESH_FORMATS = {"stl": "STL", "obj": "OBJ", "ply": "PLY", "off": "OFF", "glb": "glTF",
                "gltf": "glTF", "3mf": "3MF", "ifc": "IFC"}
"""The file extensions read, and the format each names."""

DEFAULT_MAX_BYTES = 512 * 2**20
"""A file (or what a 3MF package unpacks to, or the buffers a glTF file uses) may hold this many
bytes (``--max-file-size``)."""
DEFAULT_MAX_TRIANGLES = 10_000_000
"""A file may hold this many triangles (``--max-triangles``)."""
MAX_ARCHIVE_MEMBERS = 10_000
"""A 3MF package may hold this many files."""


class FileError(ValueError):
    """A file that cannot be used; the message names it and says why."""


class FileErrors(FileError):
    """Several files that cannot be used: one message per file, in :attr:`messages`.

    Parameters
    ----------
    messages : list of str
        One message per bad file, each naming it and saying what is wrong.
    """

    def __init__(self, messages: Sequence[str]) -> None:
        self.messages = list(messages)
        super().__init__("\n".join(self.messages))


class FileWarning(UserWarning):
    """Something about a file that the user should know: parts left out, units that differ."""


class OverlappingComponentsWarning(FileWarning):
    """A body whose disconnected components overlap each other: one body is never tested
    against itself, so such an overlap is not reported as a collision."""


@dataclass(frozen=True)
class Limits:
    """What a file may hold, checked before it is loaded.

    Attributes
    ----------
    max_bytes : int
        Bytes of the file; for 3MF also what it unpacks to; for glTF also its buffers.
    max_triangles : int
        Triangles, as its header claims or its face lines count.
    """

    max_bytes: int = DEFAULT_MAX_BYTES
    max_triangles: int = DEFAULT_MAX_TRIANGLES

    def __post_init__(self) -> None:
        for name in ("max_bytes", "max_triangles"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                raise ValueError(f"{name} must be a positive whole number, got {value!r}")


@dataclass
class FileBody:
    """One body read from a file.

    Attributes
    ----------
    name : str
        The file's name, with ``:node`` when the file holds several bodies.
    mesh : trimesh.Trimesh
        The geometry in its own coordinates (shared by the instances of one geometry).
    transform : (4, 4) float64
        World from geometry: the scene graph's transform of the instance (identity for plain
        mesh files).
    units : str or None
        The units the file declares, if any.
    """

    name: str
    mesh: Any
    transform: np.ndarray
    units: str | None = None


def display_name(path: str | os.PathLike[str]) -> str:
    """``path`` as text that can be printed: bytes that are not UTF-8 shown as ``\\xff``."""
    return os.fsencode(path).decode("utf-8", "backslashreplace")


def parse_size(text: str) -> int:
    """Bytes from ``"512M"``, ``"2G"``, ``"1.5GiB"``, ``"800k"`` or ``"100000"`` (binary units).

    Raises
    ------
    ValueError
        Text that is not a positive size.
    """
    match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([kmgt]?)(i?b)?\s*", text, re.IGNORECASE)
    if not match:
        raise ValueError(f"{text!r} is not a size (examples: 512M, 2G, 100000)")
    value = float(match.group(1)) * 1024 ** " kmgt".index(match.group(2).lower() or " ")
    if value < 1:
        raise ValueError(f"{text!r} is not a positive size")
    return int(value)


def human_bytes(n: float) -> str:
    """``n`` bytes as text: ``"1.5 GiB"``, ``"512 MiB"``, ``"300 bytes"``."""
    for unit, scale in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return plural(int(n), "byte")


# -- checks before loading ------------------------------------------------------------------


class _Check:
    """What one file may hold, with messages that name it."""

    def __init__(self, path: str, label: str, fmt: str, size: int, limits: Limits) -> None:
        self.path, self.label, self.fmt, self.size, self.limits = path, label, fmt, size, limits

    def fail(self, why: str) -> FileError:
        return FileError(f"{self.label}: {why}")

    def bytes(self, n: int, what: str) -> None:
        if n > self.limits.max_bytes:
            raise self.fail(f"{what} {human_bytes(n)}, over the limit of "
                            f"{human_bytes(self.limits.max_bytes)} (raise it with "
                            "--max-file-size)")

    def triangles(self, n: int, what: str = "holds") -> None:
        if n > self.limits.max_triangles:
            raise self.fail(f"{what} {n:,} triangles, over the limit of "
                            f"{self.limits.max_triangles:,} (raise it with --max-triangles)")

    def count(self, needle: bytes, start: int = 0) -> int:
        """Occurrences of ``needle`` in the file from byte ``start``, read in chunks."""
        total, tail = 0, b""
        with open(self.path, "rb") as f:
            f.seek(start)
            while chunk := f.read(1 << 22):
                data = tail + chunk
                total += data.count(needle)  # the tail is too short to hold one alone
                tail = data[len(data) - len(needle) + 1:]
        return total


def _check_stl(c: _Check, head: bytes) -> None:
    if c.size >= 84:
        claimed = struct.unpack("<I", head[80:84])[0]
        if 84 + 50 * claimed == c.size:
            c.triangles(claimed, "its header claims")
            return
        if not head.lstrip().lower().startswith(b"solid"):
            raise c.fail(f"could not parse it as STL: its binary header claims {claimed:,} "
                         f"triangles ({human_bytes(84 + 50 * claimed)}), but the file holds "
                         f"{human_bytes(c.size)} (truncated, or not an STL file)")
    elif not head.lstrip().lower().startswith(b"solid"):
        raise c.fail(f"could not parse it as STL: {plural(c.size, 'byte')} "
                     f"{'is' if c.size == 1 else 'are'} too few for a binary STL and it does not "
                     "start with 'solid' as a text STL does")
    c.triangles(c.count(b"facet normal"), "it has")


def _check_obj(c: _Check, head: bytes) -> None:
    c.triangles(c.count(b"\nf ") + head.startswith(b"f "), "it has face lines for at least")


def _check_off(c: _Check, head: bytes) -> None:
    words = re.sub(rb"#[^\n]*", b"", head[:4096]).split()
    if not words or not words[0].endswith(b"OFF"):
        raise c.fail("could not parse it as OFF: it does not start with 'OFF'")
    try:
        faces = int(words[2])
    except (IndexError, ValueError):
        raise c.fail("could not parse it as OFF: no vertex and face counts after 'OFF'") from None
    c.triangles(faces, "its header claims at least")


_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2,
              "uint16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4,
              "float32": 4, "double": 8, "float64": 8}


def _check_ply(c: _Check, head: bytes) -> None:
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise c.fail("could not parse it as PLY: no 'ply' ... 'end_header' header in its first "
                     f"{plural(len(head), 'byte')}")
    header_bytes = head.index(b"\n", end) + 1 if b"\n" in head[end:] else len(head)
    lines = head[:end].decode("ascii", "replace").splitlines()
    binary = any(line.startswith("format binary") for line in lines)
    elements: list[list[Any]] = []  # [name, count, min bytes per item]
    for line in lines:
        words = line.split()
        if words[:1] == ["element"] and len(words) >= 3:
            try:
                elements.append([words[1], int(words[2]), 0])
            except ValueError:
                raise c.fail(f"could not parse it as PLY: bad element line {line!r}") from None
        elif words[:1] == ["property"] and elements:
            if words[1:2] == ["list"] and len(words) >= 5:
                # a list: its count, and (for a face) at least three indices
                elements[-1][2] += _PLY_SIZES.get(words[2], 1) + 3 * _PLY_SIZES.get(words[3], 1)
            elif len(words) >= 3:
                elements[-1][2] += _PLY_SIZES.get(words[1], 1)
    faces = sum(count for name, count, _ in elements if name == "face")
    c.triangles(faces, "its header claims at least")
    # Every item takes at least its bytes in a binary file, or two characters in a text file.
    least = header_bytes + sum(count * (size if binary else 2) for _, count, size in elements)
    if least > c.size:
        claims = ", ".join(plural(count, name) for name, count, _ in elements)
        raise c.fail(f"its PLY header claims {claims}, at least {human_bytes(least)}, but the "
                     f"file holds {human_bytes(c.size)}: it is truncated or its header is wrong")


_GLTF_COMPONENT = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_GLTF_TYPE = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def _check_gltf_document(c: _Check, doc: Any, binary_chunk: int | None) -> None:
    """What a glTF document claims against what its buffers hold and the limits."""
    if not isinstance(doc, dict):
        raise c.fail("could not parse it as glTF: its JSON is not an object")
    base = os.path.dirname(c.path)
    buffers = doc.get("buffers") or []
    held: list[int] = []
    for i, buf in enumerate(buffers):
        claimed = int(buf.get("byteLength", 0))
        uri = buf.get("uri")
        if uri is None:
            have, where = (binary_chunk or 0), "the file's binary chunk"
        elif uri.startswith("data:"):
            have, where = len(uri.partition(",")[2]) * 3 // 4, "its data URI"
        else:
            target = os.path.join(base, uri)
            if not os.path.isfile(target):
                raise c.fail(f"buffer {i} is in {uri!r}, which is not there")
            have, where = os.path.getsize(target), repr(uri)
        if claimed > have:
            raise c.fail(f"buffer {i} claims {human_bytes(claimed)}, but {where} holds "
                         f"{human_bytes(have)}: the file is damaged or hostile")
        held.append(claimed)
    c.bytes(sum(held), "its buffers hold")
    views = doc.get("bufferViews") or []
    for i, view in enumerate(views):
        b = int(view.get("buffer", -1))
        end = int(view.get("byteOffset", 0)) + int(view.get("byteLength", 0))
        if not 0 <= b < len(held) or end > held[b]:
            raise c.fail(f"buffer view {i} reaches past its buffer: the file is damaged")
    accessors = doc.get("accessors") or []
    for i, acc in enumerate(accessors):
        item = _GLTF_COMPONENT.get(acc.get("componentType"), 4) * _GLTF_TYPE.get(acc.get("type"), 1)
        count = int(acc.get("count", 0))
        c.bytes(count * item, f"accessor {i} claims")
        if "bufferView" in acc:
            v = int(acc["bufferView"])
            if not 0 <= v < len(views):
                raise c.fail(f"accessor {i} names buffer view {v}, which does not exist")
            stride = int(views[v].get("byteStride", item))
            need = int(acc.get("byteOffset", 0)) + (max(count, 1) - 1) * stride + item
            if need > int(views[v].get("byteLength", 0)):
                raise c.fail(f"accessor {i} claims {count:,} items, more than its buffer view "
                             "holds: the file is damaged or hostile")
    triangles = 0
    for mesh in doc.get("meshes") or []:
        for prim in mesh.get("primitives") or []:
            if prim.get("mode", 4) != 4:
                continue
            which = prim.get("indices", (prim.get("attributes") or {}).get("POSITION"))
            if isinstance(which, int) and 0 <= which < len(accessors):
                triangles += int(accessors[which].get("count", 0)) // 3
    c.triangles(triangles, "its meshes claim")


def _check_glb(c: _Check, head: bytes) -> None:
    if c.size < 20 or head[:4] != b"glTF":
        raise c.fail("could not parse it as binary glTF: it does not start with 'glTF'")
    _, length, json_length, kind = struct.unpack("<4I", head[4:20])
    if length != c.size:
        raise c.fail(f"its glTF header claims {human_bytes(length)}, but the file holds "
                     f"{human_bytes(c.size)}: it is truncated or damaged")
    if kind != 0x4E4F534A or 20 + json_length > c.size:
        raise c.fail("could not parse it as binary glTF: its first chunk is not its JSON")
    with open(c.path, "rb") as f:
        f.seek(20)
        text = f.read(json_length)
        chunk = f.read(8)
    binary = struct.unpack("<I", chunk[:4])[0] if len(chunk) == 8 else None
    if binary is not None and 28 + json_length + binary > c.size:
        raise c.fail(f"its binary chunk claims {human_bytes(binary)}, more than the file "
                     "holds: it is truncated or damaged")
    _check_gltf_json(c, text, binary)


def _check_gltf(c: _Check, head: bytes) -> None:
    with open(c.path, "rb") as f:
        _check_gltf_json(c, f.read(), None)


def _check_gltf_json(c: _Check, text: bytes, binary_chunk: int | None) -> None:
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise c.fail(f"could not parse its glTF JSON: {exc}") from None
    _check_gltf_document(c, doc, binary_chunk)


def _check_3mf(c: _Check, head: bytes) -> None:
    try:
        archive = zipfile.ZipFile(c.path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise c.fail(f"could not open it as a 3MF package (a zip archive): {exc}") from None
    with archive:
        members = archive.infolist()
        if len(members) > MAX_ARCHIVE_MEMBERS:
            raise c.fail(f"its package holds {len(members):,} files, over the "
                         f"{MAX_ARCHIVE_MEMBERS:,} a 3MF file may hold")
        # A member never unpacks past the size the archive declares for it (zipfile stops
        # there and fails its checksum), so the declared sizes bound what loading reads.
        c.bytes(sum(m.file_size for m in members), "its package unpacks to")
        triangles = 0
        for m in members:
            if m.filename.lower().endswith(".model"):
                with archive.open(m) as f:
                    tail = b""
                    while chunk := f.read(1 << 22):
                        data = tail + chunk
                        triangles += data.count(b"<triangle ")
                        tail = data[-9:]
    c.triangles(triangles, "its models have")


def _check_ifc(c: _Check, head: bytes) -> None:
    """An IFC file is STEP text (ISO 10303-21); its elements are read by :mod:`pycinder.bim.ifc`."""
    if not head.lstrip().startswith(b"ISO-10303-21"):
        raise c.fail("is not an IFC file in STEP form (it does not start with ISO-10303-21; "
                     "ifcXML and ifcZIP are not read)")


_CHECKS: dict[str, Callable[[_Check, bytes], None]] = {
    "stl": _check_stl, "obj": _check_obj, "off": _check_off, "ply": _check_ply,
    "glb": _check_glb, "gltf": _check_gltf, "3mf": _check_3mf, "ifc": _check_ifc}


def check_file(path: str, label: str, limits: Limits) -> str:
    """The format of the file at ``path`` (a key of :data:`MESH_FORMATS`), after checking that
    it is a file of a known format within ``limits`` (size, and what its header claims).

    Raises
    ------
    FileError
        Naming ``label`` and what is wrong.
    """
    formats = ", ".join(f".{k}" for k in MESH_FORMATS)
    if not os.path.exists(path):
        raise FileError(f"{label}: no such file")
    if os.path.isdir(path):
        raise FileError(f"{label}: is a directory, not a mesh file (formats read: {formats})")
    if not os.path.isfile(path):
        raise FileError(f"{label}: is not a regular file")
    ext = os.path.splitext(path)[1].lower().lstrip(".")
    if not ext:
        raise FileError(f"{label}: has no file extension to tell its format (formats read: "
                        f"{formats})")
    if ext not in MESH_FORMATS:
        raise FileError(f"{label}: unknown mesh format '.{ext}' (formats read: {formats})")
    size = os.path.getsize(path)
    check = _Check(path, label, ext, size, limits)
    if size == 0:
        raise check.fail("is empty")
    check.bytes(size, "is")
    with open(path, "rb") as f:
        head = f.read(65536)
    _CHECKS[ext](check, head)
    return ext


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
        from .util.optional import require

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
        from .bim.ifc import load_file as load_ifc

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
    limits_check = _Check(path, label, ext, 0, limits)
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


def file_labels(paths: Sequence[str]) -> list[str]:
    """How messages and body names call the files at ``paths``: each file's name; the paths as
    given where two files share a name; and ``#1``, ``#2``, ... after a path given more than once.
    """
    labels = [display_name(os.path.basename(p) or p) for p in paths]
    if len(set(labels)) < len(set(zip(labels, map(os.fsencode, paths)))):
        labels = [display_name(p) for p in paths]  # different files of one name
    seen: dict[str, int] = {}
    numbered = []
    for label in labels:
        if labels.count(label) > 1:
            seen[label] = seen.get(label, 0) + 1
            label = f"{label}#{seen[label]}"
        numbered.append(label)
    return numbered


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

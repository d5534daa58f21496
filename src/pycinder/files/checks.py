"""What every file reader shares: the bodies read (:class:`FileBody`), the errors and warnings,
the limits (:class:`Limits`), the checks made before a file is loaded (:func:`check_file`) and the
names messages give files (:func:`file_labels`). Mesh files (:mod:`pycinder.files`) and IFC files
(:mod:`pycinder.files.ifc_elements`) are read with them."""

from __future__ import annotations

import json
import os
import re
import struct
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..util.text import plural

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


class FileCheck:
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


def _check_stl(c: FileCheck, head: bytes) -> None:
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


def _check_obj(c: FileCheck, head: bytes) -> None:
    c.triangles(c.count(b"\nf ") + head.startswith(b"f "), "it has face lines for at least")


def _check_off(c: FileCheck, head: bytes) -> None:
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


def _check_ply(c: FileCheck, head: bytes) -> None:
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


def _check_gltf_document(c: FileCheck, doc: Any, binary_chunk: int | None) -> None:
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


def _check_glb(c: FileCheck, head: bytes) -> None:
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


def _check_gltf(c: FileCheck, head: bytes) -> None:
    with open(c.path, "rb") as f:
        _check_gltf_json(c, f.read(), None)


def _check_gltf_json(c: FileCheck, text: bytes, binary_chunk: int | None) -> None:
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise c.fail(f"could not parse its glTF JSON: {exc}") from None
    _check_gltf_document(c, doc, binary_chunk)


def _check_3mf(c: FileCheck, head: bytes) -> None:
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


def _check_ifc(c: FileCheck, head: bytes) -> None:
    """An IFC file is STEP text (ISO 10303-21); its elements are read by
    :mod:`pycinder.files.ifc_elements`."""
    if not head.lstrip().startswith(b"ISO-10303-21"):
        raise c.fail("is not an IFC file in STEP form (it does not start with ISO-10303-21; "
                     "ifcXML and ifcZIP are not read)")


_CHECKS: dict[str, Callable[[FileCheck, bytes], None]] = {
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
    check = FileCheck(path, label, ext, size, limits)
    if size == 0:
        raise check.fail("is empty")
    check.bytes(size, "is")
    with open(path, "rb") as f:
        head = f.read(65536)
    _CHECKS[ext](check, head)
    return ext


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

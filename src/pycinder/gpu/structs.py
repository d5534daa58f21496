"""Structs that the host writes and WGSL reads, declared once in Python.

A :class:`Struct` is a list of fields with WGSL types. From it come both sides of the layout:

- the WGSL ``struct`` declaration (:meth:`Struct.wgsl`), generated into the shader's source, so
  no shader declares by hand a struct that the host also writes;
- a NumPy structured dtype with every field at the offset WGSL's alignment rules give it
  (:attr:`Struct.dtype`), so the host writes fields by name (``block["face_cap"] = n``), never by
  offset or position.

The layout is checked against WGSL's rules for the address space the struct is used in (a
``uniform`` struct's arrays need a 16-byte stride), and a field whose host layout would differ
from WGSL's (an array of ``vec3``, whose stride is 16 bytes for 12 of data) is refused: declare
``vec4`` instead.

Where WGSL's alignment leaves bytes between fields or at the end, the struct declares them as
fields of its own (``pad0``, ``pad1``, ... of type ``u32``), in the WGSL and in the dtype alike:
NumPy's structured promotion (``np.concatenate``, among others) packs a dtype's undeclared gaps
away, and an array so packed would reach the GPU with every struct after the first misplaced.

>>> s = Struct("Example", [("count", "u32", "items"), ("origin", "vec3f", ""),
...                        ("scale", "f32", "")])
>>> [s.offset(f) for f in ("count", "origin", "scale")], s.size
([0, 16, 28], 32)
>>> print(s.wgsl())
struct Example {
    count: u32,  // items
    pad0: u32,  // padding
    pad1: u32,  // padding
    pad2: u32,  // padding
    origin: vec3f,
    scale: f32,
};
>>> import numpy as np
>>> np.concatenate([s.zeros(1), s.zeros(1)]).dtype.itemsize
32
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

_SCALARS = {"u32": "<u4", "i32": "<i4", "f32": "<f4"}
_SUFFIX = {"u": "u32", "i": "i32", "f": "f32"}
_ARRAY = re.compile(r"^array<\s*(.+?)\s*,\s*(\d+)u?\s*>$")
_VEC = re.compile(r"^vec([234])([uif])$")
_MAT = re.compile(r"^mat([234])x([234])f$")


@dataclass(frozen=True)
class _Layout:
    align: int
    size: int
    format: str | tuple
    """NumPy format of the field (a subarray for vectors, matrices and arrays)."""


def _round_up(n: int, k: int) -> int:
    return -(-n // k) * k


def _layout(wgsl: str, uniform: bool, where: str) -> _Layout:
    """Alignment, size and host format of a WGSL type (WGSL spec, "Alignment and Size")."""
    if wgsl in _SCALARS:
        return _Layout(4, 4, _SCALARS[wgsl])
    m = _VEC.match(wgsl)
    if m:
        n, scalar = int(m.group(1)), _SCALARS[_SUFFIX[m.group(2)]]
        return _Layout(8 if n == 2 else 16, 4 * n, (scalar, (n,)))
    m = _MAT.match(wgsl)
    if m:
        columns, rows = int(m.group(1)), int(m.group(2))
        align = 8 if rows == 2 else 16
        if rows == 3:
            raise ValueError(f"{where}: {wgsl} has padded columns; declare mat{columns}x4f")
        return _Layout(align, columns * align, ("<f4", (columns, rows)))
    m = _ARRAY.match(wgsl)
    if m:
        element, count = _layout(m.group(1), uniform, where), int(m.group(2))
        stride = _round_up(element.size, element.align)
        if uniform and stride % 16:
            raise ValueError(f"{where}: {wgsl} has a {stride}-byte stride; arrays in the uniform "
                             "address space need a multiple of 16 (use vec4 elements)")
        if stride != element.size:
            raise ValueError(f"{where}: {wgsl} pads each element ({element.size} bytes in a "
                             f"{stride}-byte stride); declare elements without padding")
        inner = element.format
        base, shape = (inner, ()) if isinstance(inner, str) else inner
        return _Layout(element.align, count * stride, (base, (count, *shape)))
    raise ValueError(f"{where}: unsupported WGSL type {wgsl!r}")


@dataclass(frozen=True)
class Field:
    """One field: its name, WGSL type and what it holds (a comment in the generated WGSL)."""

    name: str
    wgsl: str
    doc: str = ""


class Struct:
    """A struct shared by the host and WGSL, declared once.

    Parameters
    ----------
    name : str
        The WGSL name.
    fields : sequence of Field or (name, wgsl type, doc) tuples
    uniform : bool
        Used in the uniform address space (its arrays need a 16-byte stride).
    doc : str
        What the struct is (a comment above the generated declaration).
    """

    def __init__(self, name: str, fields: Sequence[Field | tuple[str, ...]], *,
                 uniform: bool = False, doc: str = "") -> None:
        self.name = name
        self.uniform = uniform
        self.doc = doc
        given = tuple(f if isinstance(f, Field) else Field(*f) for f in fields)
        names = [f.name for f in given]
        if len(set(names)) != len(names):
            raise ValueError(f"struct {name}: a field name appears twice in {names}")
        laid: list[Field] = []
        offsets, formats, offset, align = [], [], 0, 4
        pads = 0

        def pad(until: int) -> None:
            nonlocal offset, pads
            while offset < until:  # WGSL's sizes and alignments are multiples of 4 bytes
                laid.append(Field(f"pad{pads}", "u32", "padding"))
                offsets.append(offset)
                formats.append(_SCALARS["u32"])
                offset += 4
                pads += 1

        for f in given:
            lay = _layout(f.wgsl, uniform, f"{name}.{f.name}")
            pad(_round_up(offset, lay.align))
            laid.append(f)
            offsets.append(offset)
            formats.append(lay.format)
            offset += lay.size
            align = max(align, lay.align)
        pad(_round_up(offset, align))
        self.fields = tuple(laid)
        names = [f.name for f in laid]
        if pads and len(set(names)) != len(names):
            raise ValueError(f"struct {name}: a field is named like the padding ({names})")
        self.align = align
        self.size = offset
        self._offsets = dict(zip(names, offsets))
        self.dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets,
                               "itemsize": self.size})

    def offset(self, field: str) -> int:
        """Byte offset of a field."""
        return self._offsets[field]

    def field_size(self, field: str) -> int:
        """Bytes of a field."""
        return self.dtype.fields[field][0].itemsize

    def zeros(self, count: int | None = None, *, stride: int | None = None) -> np.ndarray:
        """A zeroed host copy: one struct (``count`` None, a 0-d structured array) or ``count``
        of them, ``stride`` bytes apart (default: the struct's size, as in a WGSL array; a
        larger stride places each in its own block, for dynamic uniform offsets)."""
        dtype = self.dtype
        if stride is not None:
            if stride < self.size or stride % self.align:
                raise ValueError(f"struct {self.name} ({self.size} bytes, align {self.align}) "
                                 f"does not fit a {stride}-byte stride")
            dtype = np.dtype({"names": dtype.names,
                              "formats": [dtype.fields[n][0] for n in dtype.names],
                              "offsets": [dtype.fields[n][1] for n in dtype.names],
                              "itemsize": stride})
        return np.zeros(() if count is None else count, dtype=dtype)

    def wgsl(self) -> str:
        """The WGSL declaration."""
        lines = [f"// {line}" for line in self.doc.splitlines()]
        lines.append(f"struct {self.name} {{")
        for f in self.fields:
            comment = f"  // {f.doc}" if f.doc else ""
            lines.append(f"    {f.name}: {f.wgsl},{comment}")
        lines.append("};")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"Struct({self.name!r}, {len(self.fields)} fields, {self.size} bytes)"


def declarations(structs: Sequence[Struct]) -> str:
    """WGSL declarations of ``structs``, in order, as a block of generated source."""
    body = "\n\n".join(s.wgsl() for s in structs)
    return f"// Generated from Python declarations (pycinder): edit the Python, not this.\n{body}\n"


__all__ = ["Field", "Struct", "declarations"]

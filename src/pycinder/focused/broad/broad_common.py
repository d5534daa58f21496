"""What the broad phase's passes share with each other and with their shaders, declared once.

The structs the host writes (:data:`BODY`, :data:`PARAMS`) are generated into the shaders'
source; the two buffers the shaders use as arrays of atomic words (:data:`GRID`,
:data:`COUNTS`) are declared as structs too, and the shaders index them by word constants
generated from the declarations (:func:`word_consts`), so neither side holds an offset of its
own. The host reads the counts and the grid's set-up back by name (:data:`READBACK`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import wgpu

from ...gpu.bindings import Stage
from ...gpu.buffers import GrowableBuffer
from ...gpu.device import Gpu
from ...gpu.structs import Field, Struct
from ...gpu.table import PassInfo

PAD_SCALE = 2.0 ** -19
"""Padding per unit of a row's sum of magnitudes (see :mod:`pycinder.focused.broad`)."""
ORIGIN_PAD_SCALE = 2.0 ** -40
"""Padding per unit of the origin's largest coordinate (the float64 reference's rounding)."""
SORT_THREADS = 256
"""Threads per workgroup of the sort passes."""
SORT_BLOCK = 2 * SORT_THREADS
"""Sort elements per workgroup of the local sort (two per thread)."""
WIDE_BODIES = 32
"""Most boxes kept out of the grid for their width."""
HIST_BINS = 256
"""Bins of the histogram of the boxes' widths (quarter octaves from 2^-31 to 2^33)."""
FIRST_PAIRS = 4096
"""Fewest pairs the pairs buffer holds and the first readback copies."""
COORDINATE_LIMIT = 1e18
"""Largest box, radius or transform entry (translations from the scene's centre): their float32
products stay far from overflow."""
MAX_KEY = 0xFFFFFFFE
"""Largest within key or group rank (0xFFFFFFFF marks the sort's padding)."""

BODY = Struct("Body", [
    ("rows", "array<vec4f, 3>", "world-from-body rows (linear part, translation less the origin)"),
    ("lo", "vec3f", "body-space box minimum"),
    ("radius", "f32", "bounding-sphere radius about the box's centre"),
    ("hi", "vec3f", "body-space box maximum"),
    ("within", "u32", "within key (rank): only bodies with equal keys pair"),
    ("group", "u32", "group (rank): with use_groups, only bodies of different groups pair"),
], doc="One body as pass B1 reads it.")

PARAMS = Struct("Params", [
    ("n", "u32", "bodies"),
    ("count", "u32", "sort elements (a power of two, at least SORT_BLOCK)"),
    ("axis", "u32", "sweep axis"),
    ("capacity", "u32", "pairs the pairs buffer holds"),
    ("use_groups", "u32", "1: only pairs of different groups"),
    ("base_pad", "f32", "added to every box's padding (rounding of the float64 reference)"),
], uniform=True, doc="The broad phase's frame, read by every pass.")

_SETUP = [
    Field("cell_size", "vec2f", "size of the grid's cells on the two axes after the sweep axis"),
    Field("wide_from", "f32", "width across the sweep axis from which a box is wide"),
    Field("wide_count", "u32", "boxes that are wide"),
]

GRID = Struct("Grid", [
    ("high", "array<u32, 3>", "per world axis: the largest box centre (order-preserving bits)"),
    ("low", "array<u32, 3>", "per world axis: the complement of the smallest centre's bits"),
    *_SETUP,
    ("histogram", f"array<u32, {HIST_BINS}>", "boxes by width across the sweep axis"),
    ("wide_list", f"array<u32, {WIDE_BODIES}>", "sorted positions of the wide boxes"),
], doc="The grid across the sweep axis: what B1 gathers (centre ranges grow by atomicMax from\n"
       "0, widths by atomicAdd), what B2 makes of it (the set-up), the wide boxes B6 lists.")

COUNTS = Struct("Counts", [
    ("pairs", "u32", "pairs found (those past the capacity are counted, not stored)"),
    ("wide_listed", "u32", "wide boxes listed by B6"),
    ("unfinished", "u32", "boxes whose sweep ran out of its budget"),
    ("wide_overflow", "u32", "wide boxes B6 could not list (never: B2 counted them)"),
], doc="Counts appended to through atomics.")

READBACK = Struct("BroadReadback", [*COUNTS.fields, *_SETUP],
                  doc="The first bytes of a frame's readback: the counts, then the grid's set-up.")


def word_consts(struct: Struct, prefix: str) -> dict[str, int]:
    """Word index of every field of ``struct`` (``{prefix}_{FIELD}``) and its size in words
    (``{prefix}_WORDS``), for a shader that uses the struct as an array of atomic words."""
    out = {f"{prefix}_{f.name.upper()}": struct.offset(f.name) // 4 for f in struct.fields}
    out[f"{prefix}_WORDS"] = struct.size // 4
    return out


CONSTS: dict[str, int | float] = {
    "SORT_THREADS": SORT_THREADS, "SORT_BLOCK": SORT_BLOCK, "PAD_SCALE": PAD_SCALE,
    "WIDE_BODIES": WIDE_BODIES, "HIST_BINS": HIST_BINS,
    **word_consts(GRID, "GRID"), **word_consts(COUNTS, "COUNT"),
}
"""The constants generated into every broad-phase shader."""

PARAMS_BINDING = (PARAMS.size + 15) // 16 * 16
"""Bytes of the uniform binding of :data:`PARAMS`."""

assert GRID.offset("high") == 0 and GRID.offset("low") == 3 * 4, "B1 reduces words 0-5 locally"


@dataclass
class BroadBuffers:
    """The broad phase's buffers, made once; the growable ones grow when a frame needs more.

    Attributes
    ----------
    params : uniform :data:`PARAMS`; steps : uniform ``SortStep`` blocks (pass B4, B5)
    bodies : (N,) :data:`BODY`
    boxes_lo, boxes_hi : (N, 4) float32
        World boxes; ``w``: the within key's and the group's bits.
    elements : (count, 4) uint32
        Sort elements (within key, column, ordered start on the sweep axis, body).
    sorted_lo, sorted_hi : (N, 4) float32; sorted_body : (N,) uint32
        The boxes in sorted order, and their bodies.
    unfinished : (N,) uint32
        Sorted positions of the boxes whose sweep ran out of its budget.
    pairs : (capacity, 2) uint32
    counts : :data:`COUNTS`; grid : :data:`GRID`
    """

    params: GrowableBuffer
    steps: GrowableBuffer
    bodies: GrowableBuffer
    boxes_lo: GrowableBuffer
    boxes_hi: GrowableBuffer
    elements: GrowableBuffer
    sorted_lo: GrowableBuffer
    sorted_hi: GrowableBuffer
    sorted_body: GrowableBuffer
    unfinished: GrowableBuffer
    pairs: GrowableBuffer
    counts: wgpu.GPUBuffer
    grid: wgpu.GPUBuffer

    @classmethod
    def create(cls, device: wgpu.GPUDevice) -> BroadBuffers:
        u = wgpu.BufferUsage
        readable = u.STORAGE | u.COPY_SRC
        uniform = u.UNIFORM | u.COPY_DST

        def grow(label: str, usage: int = u.STORAGE) -> GrowableBuffer:
            return GrowableBuffer(device, label, usage)

        def fixed(label: str, size: int) -> wgpu.GPUBuffer:
            return device.create_buffer(label=label, size=size,
                                        usage=u.STORAGE | u.COPY_SRC | u.COPY_DST)

        return cls(
            params=grow("broad phase parameters", uniform),
            steps=grow("broad phase sort steps", uniform),
            bodies=grow("broad phase bodies", u.STORAGE | u.COPY_DST),
            boxes_lo=grow("world box minima"), boxes_hi=grow("world box maxima"),
            elements=grow("sort elements"),
            sorted_lo=grow("sorted minima", readable), sorted_hi=grow("sorted maxima", readable),
            sorted_body=grow("sorted bodies", readable),
            unfinished=grow("unfinished sweeps", readable),
            pairs=grow("candidate pairs", readable),
            counts=fixed("broad phase counts", COUNTS.size),
            grid=fixed("broad phase grid", GRID.size))

    @property
    def params_binding(self) -> tuple[wgpu.GPUBuffer, int, int]:
        """``(buffer, offset, size)`` of the frame's :data:`PARAMS`."""
        return self.params.buffer, 0, PARAMS_BINDING


@dataclass(frozen=True)
class BroadFrame:
    """The sizes of one call, as the passes dispatch them.

    Attributes
    ----------
    n : int
        Bodies.
    count : int
        Sort elements: a power of two, at least :data:`SORT_BLOCK`.
    steps : tuple of (str, int, int)
        The sort's dispatches (:func:`pycinder.focused.broad.b4_sort.sort_steps`).
    """

    n: int
    count: int
    steps: tuple[tuple[str, int, int], ...]


class BroadPass:
    """A pass of the broad phase: its pipeline, made once (``SHADER``, ``ENTRY``, ``STRUCTS``),
    labelled by its :class:`~pycinder.gpu.table.PassInfo`."""

    INFO: ClassVar[PassInfo]
    SHADER: ClassVar[str]
    ENTRY: ClassVar[str]
    STRUCTS: ClassVar[tuple[Struct, ...]] = (PARAMS,)

    def __init__(self, gpu: Gpu) -> None:
        self.stage = Stage(gpu, self.SHADER, self.ENTRY, label=self.INFO.title,
                           structs=self.STRUCTS, consts=CONSTS)


__all__ = ["BODY", "BroadBuffers", "BroadFrame", "BroadPass", "CONSTS", "COUNTS", "GRID", "PARAMS",
           "READBACK", "word_consts"]

"""Everything the focused passes' shaders share with Python, declared once.

The WGSL prelude (``//!include layout`` in a shader) is generated from this module by
:func:`wgsl_prelude`, so a counter index, a flag bit, a workgroup size or a field of a shared
struct can never differ between the host and the GPU. The structs here are those several passes
share (tiles, clusters, the indirect arguments); each pass declares its own parameters beside it.
"""

from __future__ import annotations

from .structs import Struct

WORKGROUP = 64
"""Threads per workgroup of the focused compute passes."""

ROW = 32768
"""Workgroups per row of a dispatch (under WebGPU's 65535 per dimension)."""

CLUSTER_FACES = 64
"""Faces per culling cluster. Pass F2 clips one face per thread of a workgroup, so a cluster has at
most :data:`WORKGROUP` faces; its edges (about twice as many) are strided over by pass F5."""

TILE = Struct("Tile", [
    ("m0", "array<vec4f, 3>", "tile-from-body rows (u, v, z) for body a"),
    ("m1", "array<vec4f, 3>", "tile-from-body rows for body b"),
    ("window", "vec4u", "atlas column, atlas row (in this round), width, height"),
    ("slab", "vec4f", "z0, z1: depth range of the box, in pixels; zw unused"),
    ("bodies", "vec2u", "body a, body b"),
    ("flags", "u32", "FLAG_* bits"),
    ("pair", "u32", "the candidate pair's index"),
], doc="An orthographic view of one candidate pair (a, b) over the box where they can touch.")

CLUSTER = Struct("Cluster", [
    ("face_start", "u32", ""),
    ("face_count", "u32", ""),
    ("edge_start", "u32", ""),
    ("edge_count", "u32", ""),
], doc="Up to CLUSTER_FACES faces and the edges they own, contiguous in the packed arrays.")

INDIRECT_ARGS = Struct("IndirectArgs", [
    ("clip", "array<u32, 3>", "F2 clip: one workgroup per kept cluster"),
    ("edges", "array<u32, 3>", "F5 edge list and F6: one workgroup per kept edge cluster"),
    ("draw", "array<u32, 4>", "F3: vertices, instances, first vertex, first instance"),
    ("surface", "array<u32, 3>", "F4 surface test: WORKGROUP active pixels per workgroup"),
    ("retry_cull", "array<u32, 3>", "F1 cull of a retry round"),
    ("cut", "array<u32, 3>", "F2 cuts: WORKGROUP listed faces per workgroup"),
    ("edge_test", "array<u32, 3>", "F5 edge test: WORKGROUP listed edges per workgroup"),
], doc="Indirect dispatch and draw arguments, written on the GPU by the passes' decisions.")

RECORD = Struct("Record", [
    ("tile", "u32", "the tile's index in its frame"),
    ("uv", "u32", "pixel u | v << 16"),
    ("z_bits", "u32", "f32 bits of the sample's depth z in the tile"),
    ("ident", "u32", "id | kind << RECORD_KIND_SHIFT | side << RECORD_SIDE_BIT"),
], doc="One sample found inside the other body, or one crossing (passes F4-F6).")

SHARED_STRUCTS = (TILE, CLUSTER, INDIRECT_ARGS, RECORD)
"""The structs generated into every shader that includes the layout."""

# Tile flags.
FLAG_COUNT_BACK = 1
"""Count the crossings behind the overlap box instead of in front of it."""
FLAG_MIRROR = (2, 4)
"""Body a's (body b's) transform reverses orientation, so its faces' facing flips."""
FLAG_SKIP_IF_HIT = 8
"""Skip the tile once another tile of its pair found a hit."""
FLAG_OPEN = (16, 32)
"""Body a (body b) is not a closed solid: nothing is tested against its inside (it has none);
its surface is tested by the edge-face crossing pass instead."""
FLAG_STOP_AT_FIRST = 64
"""Skip the tile once any pair of the frame is found (a query that asks only whether anything
collides: :meth:`pycinder.Detector.in_collision`)."""

# Counters of a frame (``counters`` buffer). Items and triangles are reset every round.
COUNTER_NAMES = (
    "C_FACE_ITEMS",        # kept (tile, side, cluster) face items of this round
    "C_EDGE_ITEMS",        # kept edge items of this round
    "C_TRIS",              # clipped triangles of this round
    "C_ACTIVE",            # pixels with at least one listed crossing (this round)
    "C_RECORDS",           # records appended (samples found inside the other body, crossings)
    "C_UNDECIDED",         # samples at pixels whose crossing list overflowed
    "C_SAMPLES",           # edge samples tested
    "C_RETRY_TILES",       # tiles run again in the frame's own retry round (longer lists)
    "C_MAX_FACE_ITEMS",
    "C_MAX_EDGE_ITEMS",
    "C_MAX_TRIS",
    "C_TOTAL_TRIS",
    "C_TOTAL_FACE_ITEMS",
    "C_TOTAL_EDGE_ITEMS",
    "C_CUTS",              # faces listed for cutting by pass F2 (this round)
    "C_AGAIN",             # tiles left undecided whose answer could still change (host retries)
    "C_EDGES",             # edges listed for sampling by pass F5 (this round)
    "C_MAX_EDGES",
    "C_FOUND",             # non-zero once any pair of the frame is found
    "C_RETRY_ROWS",        # rows the retry rounds' layout needs for every tile chosen (pass F7)
    "C_RETRY_CHOSEN",      # tiles pass F7 chose to run again (C_RETRY_TILES of them fit)
)
COUNTERS = len(COUNTER_NAMES)
(C_FACE_ITEMS, C_EDGE_ITEMS, C_TRIS, C_ACTIVE, C_RECORDS, C_UNDECIDED, C_SAMPLES, C_RETRY_TILES,
 C_MAX_FACE_ITEMS, C_MAX_EDGE_ITEMS, C_MAX_TRIS, C_TOTAL_TRIS, C_TOTAL_FACE_ITEMS,
 C_TOTAL_EDGE_ITEMS, C_CUTS, C_AGAIN, C_EDGES, C_MAX_EDGES, C_FOUND, C_RETRY_ROWS,
 C_RETRY_CHOSEN) = range(COUNTERS)
ROUND_COUNTERS = 4
"""The first counters, reset before every round (and C_CUTS, C_EDGES)."""

# The fields of a record's ``ident`` (see RECORD).
RECORD_KIND_SHIFT = 29
RECORD_ID_MASK = (1 << RECORD_KIND_SHIFT) - 1
RECORD_EDGE, RECORD_SURFACE, RECORD_CROSSING = 0, 1, 2
"""Record kinds: an edge sample inside the other body (id: packed edge), a surface point inside it
(id: packed face), an edge crossing a face of the other body (id: packed edge)."""
RECORD_SIDE_BIT = 31

# Per-tile counts: (found, undecided); the undecided word's top bit says that pass F6 stopped at
# its loop budget (longer lists cannot help such a tile; thinner boxes can).
UNDECIDED_BUDGET_BIT = 1 << 31


def wgsl_prelude() -> str:
    """WGSL ``const`` declarations of this module's values."""
    lines = ["// Generated from pycinder/layout.py: edit the Python, not this."]

    def const(name: str, value: int) -> None:
        lines.append(f"const {name}: u32 = {int(value)}u;")

    const("WORKGROUP", WORKGROUP)
    const("ROW", ROW)
    const("CLUSTER_FACES", CLUSTER_FACES)
    const("FLAG_COUNT_BACK", FLAG_COUNT_BACK)
    const("FLAG_MIRROR0", FLAG_MIRROR[0])
    const("FLAG_MIRROR1", FLAG_MIRROR[1])
    const("FLAG_SKIP_IF_HIT", FLAG_SKIP_IF_HIT)
    const("FLAG_OPEN0", FLAG_OPEN[0])
    const("FLAG_OPEN1", FLAG_OPEN[1])
    const("FLAG_STOP_AT_FIRST", FLAG_STOP_AT_FIRST)
    for i, name in enumerate(COUNTER_NAMES):
        const(name, i)
    const("ROUND_COUNTERS", ROUND_COUNTERS)
    const("RECORD_KIND_SHIFT", RECORD_KIND_SHIFT)
    const("RECORD_ID_MASK", RECORD_ID_MASK)
    const("RECORD_EDGE", RECORD_EDGE)
    const("RECORD_SURFACE", RECORD_SURFACE)
    const("RECORD_CROSSING", RECORD_CROSSING)
    const("RECORD_SIDE_BIT", RECORD_SIDE_BIT)
    const("UNDECIDED_BUDGET_BIT", UNDECIDED_BUDGET_BIT)
    lines += [s.wgsl() for s in SHARED_STRUCTS]
    return "\n".join(lines) + "\n"


assert CLUSTER_FACES <= WORKGROUP, "pass F2 clips one face per thread"

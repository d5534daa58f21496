"""Decoding what the GPU wrote: pixel records, unique pairs, world points, stats.

The colour target is ``rgba32uint``; after passes 4 and 7 a pixel holds

=======  =====================================================================
channel  meaning
=======  =====================================================================
r        penetrating body id (body index + 1, 1..65535; 0: no collision)
g        penetrated body id (body index + 1)
b        depth of the penetrating edge's fragment, as the bits of a float32
a        payload of that edge: its global edge index + 1 (``encode="edge"``)
         or its world-space normal packed 10:10:10 (``encode="normal"``)
=======  =====================================================================

This keeps the paper's two 16-bit ids per pixel (its RG and BA) in the first two 32-bit channels
and uses the other two for data the paper could only dream of encoding.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .view import View

RECORD_DTYPE = np.dtype([
    ("x", np.int32),
    ("y", np.int32),
    ("depth", np.float32),
    ("penetrating", np.int32),
    ("penetrated", np.int32),
    ("edge", np.int32),
    ("normal", np.float32, (3,)),
    ("view", np.int16),
])
"""One row per collision pixel.

x, y : pixel column and row (row 0 at the top of the image)
depth : depth of the penetrating edge's fragment, 0 at the near plane, 1 at the far plane
penetrating : index of the body whose edge lies inside the other
penetrated : index of the body the edge lies in
edge : index of that edge among the penetrating body's unique edges (-1 when normals are encoded)
normal : world-space normal of the edge (mean of its two faces) when ``encode="normal"``, else NaN
view : index of the view the pixel belongs to
"""


@dataclass
class Stats:
    """What a query did and what it cost."""

    readback: str = "full"
    self_interference: str = "filter"
    resolution: tuple[int, int] = (0, 0)
    views: int = 1
    bytes_read: int = 0
    records: int = 0
    self_interference_pixels: int = 0
    """Pixels blanked by the filter because a body's edge was counted inside itself."""
    unidentified_pixels: int = 0
    """Pixels with a non-zero count that no single body claimed (blanked)."""
    possibly_lost: int = 0
    """Lossy modes: how many blocks merged two different records (0 means nothing was dropped)."""
    mip_level: int = 0
    """Mip-map level read back (mipmap and adaptive modes)."""
    uploaded_vertex_bytes: int = 0
    wall_ms: dict[str, float] = field(default_factory=dict)
    gpu_ms: dict[str, float] = field(default_factory=dict)
    adapter: str = ""

    def merge(self, other: Stats) -> None:
        for name in ("bytes_read", "records", "self_interference_pixels", "unidentified_pixels",
                     "possibly_lost", "uploaded_vertex_bytes"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        self.mip_level = max(self.mip_level, other.mip_level)
        for d, o in ((self.wall_ms, other.wall_ms), (self.gpu_ms, other.gpu_ms)):
            for k, v in o.items():
                d[k] = d.get(k, 0.0) + v


@dataclass
class CollisionResult:
    """The answer to one query.

    pairs : (K, 2) int64, unique colliding pairs ``(i, j)`` with ``i < j``, sorted
    records : structured array of :data:`RECORD_DTYPE`, one row per collision pixel
    views : the view of each ``records["view"]`` index
    """

    pairs: np.ndarray
    records: np.ndarray
    views: list[View]
    resolution: tuple[int, int]
    stats: Stats
    edge_table: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    """The scene's (edges (E, 2), edge_start (N+1,), vertex_start (N+1,)), for :meth:`edges`."""

    @property
    def is_collision(self) -> bool:
        return len(self.pairs) > 0

    def __bool__(self) -> bool:
        return self.is_collision

    def points(self) -> np.ndarray:
        """World-space points of the records, (len(records), 3) float64."""
        out = np.zeros((len(self.records), 3))
        w, h = self.resolution
        for k, view in enumerate(self.views):
            sel = self.records["view"] == k
            if sel.any():
                r = self.records[sel]
                out[sel] = view.unproject(r["x"], r["y"], r["depth"], w, h)
        return out

    def edge_vertices(self) -> np.ndarray:
        """Each record's penetrating edge as (len(records), 2) int64 vertex indices of the
        penetrating body (indices into that body's own vertex array)."""
        if self.edge_table is None or (self.records["edge"] < 0).any():
            raise ValueError("edge indices are not encoded (encode='normal')")
        edges, edge_start, vertex_start = self.edge_table
        pen = self.records["penetrating"].astype(np.int64)
        return edges[edge_start[pen] + self.records["edge"]].astype(np.int64) - vertex_start[pen, None]

    def pair_names(self, names: Sequence[str]) -> set[tuple[str, str]]:
        """The pairs as a set of name tuples, as trimesh's ``return_names`` gives them."""
        return {tuple(sorted((names[i], names[j]))) for i, j in self.pairs.tolist()}


def unpack_normals(packed: np.ndarray) -> np.ndarray:
    """10:10:10 packed normals (n,) uint32 to unit vectors (n, 3) float32."""
    q = np.stack([(packed >> s) & 1023 for s in (0, 10, 20)], axis=1).astype(np.float32)
    n = q / 1023.0 * 2.0 - 1.0
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def make_records(pixel: np.ndarray, pen_id: np.ndarray, pend_id: np.ndarray, depth_bits: np.ndarray,
                 payload: np.ndarray, width: int, view_index: int, encode: str,
                 edge_start: np.ndarray) -> np.ndarray:
    """Structured records from decoded channels, all (n,) uint32 arrays, sorted by pixel."""
    order = np.argsort(pixel, kind="stable")
    pixel, pen_id, pend_id, depth_bits, payload = (
        a[order] for a in (pixel, pen_id, pend_id, depth_bits, payload))
    rec = np.zeros(len(pixel), dtype=RECORD_DTYPE)
    rec["x"] = pixel % width
    rec["y"] = pixel // width
    rec["depth"] = depth_bits.astype(np.uint32).view(np.float32)
    rec["penetrating"] = pen_id.astype(np.int64) - 1
    rec["penetrated"] = pend_id.astype(np.int64) - 1
    rec["view"] = view_index
    if encode == "normal":
        rec["edge"] = -1
        rec["normal"] = unpack_normals(payload.astype(np.uint32))
    else:
        rec["edge"] = payload.astype(np.int64) - 1 - edge_start[rec["penetrating"]]
        rec["normal"] = np.nan
    return rec


def decode_image(image: np.ndarray, width: int, view_index: int, encode: str,
                 edge_start: np.ndarray) -> np.ndarray:
    """Records from a filtered image, (H*W*4,) uint32 as read back."""
    image = image.reshape(-1, 4)
    pixel = np.flatnonzero(image[:, 0])
    rows = image[pixel]
    return make_records(pixel.astype(np.uint32), rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3],
                        width, view_index, encode, edge_start)


def decode_compact(data: np.ndarray, width: int, view_index: int, encode: str,
                   edge_start: np.ndarray) -> np.ndarray:
    """Records from compacted rows (pixel, r << 16 | g, depth bits, payload), (K*4,) uint32."""
    rows = data.reshape(-1, 4)
    return make_records(rows[:, 0], rows[:, 1] >> 16, rows[:, 1] & 0xFFFF, rows[:, 2], rows[:, 3],
                        width, view_index, encode, edge_start)


def unique_pairs(records: np.ndarray) -> np.ndarray:
    """Unique sorted (K, 2) int64 pairs with i < j from records."""
    if len(records) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    a = records["penetrating"].astype(np.int64)
    b = records["penetrated"].astype(np.int64)
    # One int64 key per pair: a 1-D unique is far faster than np.unique(axis=0).
    key = np.unique(np.minimum(a, b) << 16 | np.maximum(a, b))
    return np.stack([key >> 16, key & 0xFFFF], axis=1)

"""The collision record: what the GPU writes for each edge sample found inside another body, and
how it becomes one row of :data:`RECORD_DTYPE`. All decoding lives here.

Scene strategy: the colour target is ``rgba32uint``; after passes 4 and 7 a pixel holds

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
and uses the other two for data the paper could only dream of encoding. The compact readback
writes each surviving pixel as ``(pixel index, r << 16 | g, b, a)``.

Focused strategy: pass F4 appends ``(tile, u | v << 16, f32 bits of z, edge | side << 31)`` per
sample; the tile names the pair, so the penetrated body is the other one of its pair.
"""

from __future__ import annotations

import numpy as np

RECORD_DTYPE = np.dtype([
    ("point", np.float64, (3,)),
    ("penetrating", np.int32),
    ("penetrated", np.int32),
    ("edge", np.int32),
    ("face", np.int32),
    ("normal", np.float32, (3,)),
    ("view", np.int32),
    ("x", np.int32),
    ("y", np.int32),
    ("depth", np.float32),
])
"""One row per collision sample.

point : world-space point that was found inside the penetrated body (a pixel centre at the depth
    of the penetrating edge: within half a pixel's diagonal of that edge)
penetrating : index of the body whose edge lies inside the other
penetrated : index of the body the edge lies in
edge : index of that edge among the penetrating body's unique edges (``topology.edges``), or -1
    for a surface sample
face : focused strategy, surface samples: the penetrating body's face (index into its faces)
    whose point lies inside the penetrated body; -1 for edge samples
normal : with ``encode="normal"``, the world-space normal of the edge (mean of its two faces) or
    of the face; else NaN
view : scene strategy: index of the view; focused strategy: index of the tile
x, y : pixel column and row in that view or tile (row 0 at the top)
depth : scene strategy: depth of the edge's fragment, 0 at the near plane and 1 at the far plane;
    focused strategy: depth along the tile's view direction, in pixels from the tile's box centre
"""


def empty_records() -> np.ndarray:
    return np.zeros(0, dtype=RECORD_DTYPE)


def unpack_normals(packed: np.ndarray) -> np.ndarray:
    """10:10:10 packed normals (n,) uint32 to unit vectors (n, 3) float32."""
    q = np.stack([(packed >> s) & 1023 for s in (0, 10, 20)], axis=1).astype(np.float32)
    n = q / 1023.0 * 2.0 - 1.0
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def scene_records(pixel: np.ndarray, pen_id: np.ndarray, pend_id: np.ndarray,
                  depth_bits: np.ndarray, payload: np.ndarray, width: int, view_index: int,
                  encode: str, edge_start: np.ndarray) -> np.ndarray:
    """Records of the scene strategy from decoded channels (all (n,) uint32), sorted by pixel.

    ``point`` is left at zero; the scene strategy fills it from the view that drew the pixel.
    """
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
    rec["face"] = -1
    if encode == "normal":
        rec["edge"] = -1
        rec["normal"] = unpack_normals(payload.astype(np.uint32))
    else:
        rec["edge"] = payload.astype(np.int64) - 1 - edge_start[rec["penetrating"]]
        rec["normal"] = np.nan
    return rec


def decode_image(image: np.ndarray, width: int, view_index: int, encode: str,
                 edge_start: np.ndarray) -> np.ndarray:
    """Scene records from a filtered image, (H*W*4,) uint32 as read back."""
    image = image.reshape(-1, 4)
    pixel = np.flatnonzero(image[:, 0])
    rows = image[pixel]
    return scene_records(pixel.astype(np.uint32), rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3],
                         width, view_index, encode, edge_start)


def decode_compact(data: np.ndarray, width: int, view_index: int, encode: str,
                   edge_start: np.ndarray) -> np.ndarray:
    """Scene records from compacted rows (pixel, r << 16 | g, depth bits, payload), (K*4,) uint32."""
    rows = data.reshape(-1, 4)
    return scene_records(rows[:, 0], rows[:, 1] >> 16, rows[:, 1] & 0xFFFF, rows[:, 2], rows[:, 3],
                         width, view_index, encode, edge_start)


def pair_keys(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """One int64 key per unordered pair of body indices (n,) and (n,): ``min << 32 | max``.
    Keys sort as the pairs ``(i, j)``, ``i < j``, do; a 1-D unique or isin on them is far faster
    than one over (n, 2) rows."""
    a, b = np.asarray(a, np.int64), np.asarray(b, np.int64)
    return np.minimum(a, b) << 32 | np.maximum(a, b)


def unique_pairs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unique sorted (K, 2) int64 pairs ``(i, j)``, ``i < j``, from two (n,) arrays of bodies."""
    if len(a) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    key = np.unique(pair_keys(a, b))
    return np.stack([key >> 32, key & 0xFFFFFFFF], axis=1)

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

Focused strategy: passes F4-F6 append a :data:`~pycinder.gpu.layout.RECORD` per sample (tile,
u | v << 16, f32 bits of z, id | kind | side); the tile names the pair, so the penetrated body is
the other one of its pair.
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
    ("pixel_x", np.int32),
    ("pixel_y", np.int32),
    ("pixel_z", np.float32),
])
"""One row per collision sample: a point of one body (on an edge, or on its surface) found
inside another body.

A record is a *sample*, not a contact: a pair has as many records as the pixels that found it.
For one contact per contact region, with its normal and penetration depth, use
:meth:`CollisionResult.contacts() <pycinder.CollisionResult.contacts>`.

point : (3,) float64
    World-space point found inside the penetrated body: a pixel centre at the depth where the
    penetrating body's edge or face crosses it, so within half a pixel's diagonal of that edge
    or face.
penetrating : int32
    Index of the body whose edge or surface lies inside the other.
penetrated : int32
    Index of the body it lies in.
edge : int32
    Index of that edge among the penetrating body's unique edges (``topology.edges``;
    :meth:`CollisionResult.edge_vertices` gives its two vertices), or -1 for a surface sample
    and for the scene strategy with ``encode="normal"``.
face : int32
    Focused strategy, surface samples: the penetrating body's face (an index into the faces it
    was given) whose point lies inside the penetrated body; -1 for edge samples.
normal : (3,) float32
    Filled whenever normals are asked for (``encode="normal"``), on every record of either
    strategy: the world-space unit outward normal of the penetrating body there (of the face for
    a surface sample; of the edge, the mean of its two faces' normals, for an edge sample). NaN
    when normals are not asked for. It is the penetrating surface's own normal, not a contact
    normal between the two bodies.
view : int32
    Which image the sample was found in: focused strategy, the index of its tile
    (``result.tiles``); scene strategy, the index of its view (``result.views``).
pixel_x, pixel_y : int32
    The pixel's column and row in that tile or view (row 0 at the top).
pixel_z : float32
    The sample's third screen coordinate in that tile or view. Focused strategy: its distance
    along the tile's view direction from the tile's box centre, in pixel widths (so a few
    hundred in a long tile; ``result.tiles.to_world(view, pixel_x + 0.5, pixel_y + 0.5,
    pixel_z)`` gives ``point``). Scene strategy: the depth-buffer value, 0 at the near plane and
    1 at the far plane. Neither is a penetration depth.
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
    rec["pixel_x"] = pixel % width
    rec["pixel_y"] = pixel // width
    rec["pixel_z"] = depth_bits.astype(np.uint32).view(np.float32)
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
    key = pair_keys(a, b)
    if len(key) > 1 and not (key[1:] > key[:-1]).all():  # already unique and sorted: kept
        key = np.unique(key)
    return np.stack([key >> 32, key & 0xFFFFFFFF], axis=1)

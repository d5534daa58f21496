"""Pass H1, depth: for each candidate pair, how far body a must move along each of
:data:`LINES` lines, either way, to leave body b behind on every ray parallel to it, exactly (in
single precision) over every face of a and face of b whose projections along it can meet
(``measure_depth.wgsl``; which cluster pairs meet along which lines:
:mod:`~pycinder.focused.measure.h1_items`). The hard-clash query's one pass; what its figures
promise is in :mod:`pycinder.focused.modes.hardclash`."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from ...gpu.buffers import GrowableBuffer
from ...gpu.layout import CLUSTER_FACES, WORKGROUP
from ...gpu.table import PassInfo
from .pair_work import FRAME, ITEM, PARAMS, ClusterPairPass

WORLD_LINES = 13
"""Lines fixed in the world: through a cube's centre and its faces, edges and corners."""
LINES = 6 + WORLD_LINES
"""Lines per pair: body a's three axes, body b's, then the world's (see :func:`lines`)."""
SLACK = 2.0**-18
"""Rounding allowed in the shader's inside and crossing tests, relative to the faces' size."""
WHOLE_FACES = 256
"""Most faces of the body a whole item keeps in workgroup memory (the other's are shared among
the threads)."""
WHOLE_WORK = 2**16
"""Most face pairs of a pair measured by one workgroup as a whole item (which stops at the first
line that clears the pair); larger pairs are measured cluster pair by cluster pair."""
ITEM_WHOLE = 1
"""``whole`` bit of an item: its faces are its pair's two bodies whole (its only item)."""
ITEM_FLIPPED = 2
"""``whole`` bit of a whole item: body a's faces are the ones in workgroup memory."""
ROUNDS = ((0, 1, 2, 3, 4, 5), tuple(range(6, 6 + WORLD_LINES)))
"""The lines items of a cluster of each body measure in each round: the bodies' own axes first
(they most often clear a touching pair at once), then the world's, for the pairs not cleared
yet."""
ITEM_SKIP_SHIFT = 8
"""First of the ``whole`` bits (one per line, :data:`LINES` in all) naming the lines an item
skips: its faces' projections along them are apart, so they add nothing there."""
DONE = 2 * LINES
"""The word of each pair that counts the threads that finished its items (after its figures'
``2 * LINES``)."""


_WORLD = np.array([(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1),
                   (0, 1, 1), (0, 1, -1), (1, 1, 1), (1, 1, -1), (1, -1, 1), (-1, 1, 1)],
                  np.float64)


def lines(transform_a: np.ndarray, transform_b: np.ndarray) -> np.ndarray:
    """The unit directions of each pair's lines, as the shader's ``line()`` makes them: body a's
    three axes (its transform's columns), body b's, then the :data:`WORLD_LINES` world lines.

    Parameters
    ----------
    transform_a, transform_b : (K, 4, 4) float
        The pairs' world-from-body matrices.

    Returns
    -------
    (K, LINES, 3) float64
    """
    k = len(transform_a)
    out = np.empty((k, LINES, 3))
    out[:, 0:3] = np.swapaxes(np.asarray(transform_a, np.float64)[:, :3, :3], 1, 2)
    out[:, 3:6] = np.swapaxes(np.asarray(transform_b, np.float64)[:, :3, :3], 1, 2)
    out[:, 6:] = _WORLD
    length = np.linalg.norm(out, axis=2, keepdims=True)
    return np.where(length > 0, out / np.where(length > 0, length, 1.0), [0.0, 0.0, 1.0])


def decode(words: np.ndarray) -> np.ndarray:
    """Floats of the shader's order-preserving words (0, no figure, decodes to -inf).

    Parameters
    ----------
    words : (...,) uint32

    Returns
    -------
    (...,) float64
    """
    words = np.asarray(words, np.uint32)
    high = (words & np.uint32(0x80000000)) != 0
    bits = np.where(high, words & np.uint32(0x7FFFFFFF), ~words)
    out = bits.view(np.float32).astype(np.float64)
    return np.where(words == 0, -np.inf, out)


def hull_lower_bound(figures: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """A lower bound of convex pairs' penetration depths from their measured figures.

    Moving body a by ``U w`` (``w`` one of the 2 :data:`LINES` signed directions, ``U`` its
    figure) just clears body b, so for convex bodies each point ``U w`` lies on the boundary of
    the convex set of translations that do not separate them (``B - A``), and so does their
    convex hull's inside. The penetration depth, the distance from the origin to that set's
    boundary, is therefore at least the distance from the origin to the hull's boundary: the
    least offset of the hull's facets. Where the best direction was measured, a facet lies in
    the boundary's plane there and the bound meets the figure.

    Parameters
    ----------
    figures : (K, 2 LINES) float64
        Per pair, the figure of each word (``2 line + way``; way 0 along the line's direction,
        way 1 against it), at least 0.
    directions : (K, LINES, 3) float64
        The lines' unit directions (:func:`lines`).

    Returns
    -------
    (K,) float64
        The bound (0 where a figure is 0 or the hull is flat: the origin is not inside it);
        needs scipy (qhull), else 0 for every pair.
    """
    out = np.zeros(len(figures))
    try:
        from scipy.spatial import ConvexHull, QhullError
    except ImportError:  # the bound falls back to the directions' cosine (see hardclash)
        return out
    signed = np.concatenate([directions, -directions], axis=2).reshape(len(figures), 2 * LINES, 3)
    for k in np.flatnonzero(np.all(figures > 0, axis=1)):
        points = figures[k, :, None] * signed[k]
        try:
            hull = ConvexHull(points)
        except QhullError:
            continue
        out[k] = max(float(-hull.equations[:, 3].max()), 0.0)
    return out


class Depth(ClusterPairPass):
    """H1: one workgroup per item (the pair's bodies whole, entry point ``depth``, or a cluster of
    each, ``depth_clusters``); per pair and line, the largest ``depth_b - depth_a`` and
    ``depth_a - depth_b`` over the rays that meet both bodies (atomicMax)."""

    INFO: ClassVar[PassInfo] = PassInfo(
        "H1", "depth", "how far one body of each candidate pair must move along each of 19 "
        "lines, either way, to clear the other, face pair by face pair", when="hard-clash "
        "queries")
    SHADER, ENTRY, WORDS, START = "measure_depth", "depth", 2 * LINES + 1, 0
    SECOND = "depth_clusters"
    CONSTS: ClassVar[dict[str, int | float]] = {
        "LINES": LINES, "SLACK": SLACK, "WHOLE_FACES": WHOLE_FACES, "ITEM_WHOLE": ITEM_WHOLE,
        "ITEM_FLIPPED": ITEM_FLIPPED, "ITEM_SKIP_SHIFT": ITEM_SKIP_SHIFT, "WORDS": 2 * LINES + 1,
        "DONE": DONE}

    def second(self, items: np.ndarray) -> np.ndarray:
        """The items of a cluster of each body (not whole): the second entry point's."""
        return (items["whole"] & ITEM_WHOLE) == 0

    def run(self, positions: GrowableBuffer, faces: GrowableBuffer, items: np.ndarray,
            frames: np.ndarray) -> np.ndarray:
        """Measure (arguments as :meth:`~pycinder.focused.measure.pair_work.ClusterPairPass.words`).

        Items of a cluster of each body measure their lines in :data:`ROUNDS`, each a dispatch:
        a pair that a line of one round clears is not measured in the next ones, as a whole item
        stops at the first line that clears its pair (its figures up to that line are the same,
        its later lines' are those of no ray).

        Returns
        -------
        (K, LINES, 2) float64
            Per pair and line, the translation of body a along the line's direction (``[..., 0]``)
            and against it (``[..., 1]``) that clears body b on every ray the pair's items meet
            (-inf where no ray meets both bodies).
        """
        later = self.second(items)
        unfinished = np.zeros(len(frames), bool)
        if not later.any():
            words = self._finished(positions, faces, items, frames, unfinished)
            return decode(self._again(positions, faces, items, frames, words, unfinished)
                          ).reshape(-1, LINES, 2)
        every = (1 << LINES) - 1
        words = np.zeros((len(frames), 2 * LINES), np.uint32)
        open_pairs = np.ones(len(frames), bool)
        batch = items[~later]
        same = _same_axes(frames)
        for group in ROUNDS:
            others = every & ~sum(1 << i for i in group)
            part = items[later & open_pairs[items["pair"]]]
            part["whole"] |= np.uint32(others << ITEM_SKIP_SHIFT)
            # A world axis that is one of the bodies' axes measured already takes its figures.
            for axis in range(3):
                earlier = same[part["pair"], axis]
                taken = (earlier >= 0) & (earlier < min(group))
                part["whole"][taken] |= np.uint32(1 << (ITEM_SKIP_SHIFT + 6 + axis))
            part = part[(part["whole"] >> ITEM_SKIP_SHIFT) & every != every]
            batch = np.concatenate([batch, part])
            if len(batch):
                words = np.maximum(words, self._finished(positions, faces, batch, frames,
                                                         unfinished))
            for axis in range(3):
                if 6 + axis in group:
                    k = np.flatnonzero(open_pairs & (same[:, axis] >= 0)
                                       & (same[:, axis] < min(group)))
                    line = 2 * same[k, axis]
                    words[k, 2 * (6 + axis)] = words[k, line]
                    words[k, 2 * (6 + axis) + 1] = words[k, line + 1]
            open_pairs &= ~_clears(words, group)
            batch = items[:0]
        words = self._again(positions, faces, items, frames, words, unfinished)
        return decode(words).reshape(-1, LINES, 2)

    def _finished(self, positions: GrowableBuffer, faces: GrowableBuffer, items: np.ndarray,
                  frames: np.ndarray, unfinished: np.ndarray) -> np.ndarray:
        """One dispatch's figures, (K, 2 LINES) uint32; marks in ``unfinished`` (K,) bool the
        pairs some of whose items' threads did not all finish (word :data:`DONE`)."""
        words = self.words(positions, faces, items, frames)
        expected = WORKGROUP * np.bincount(items["pair"].astype(np.int64),
                                           minlength=len(frames))
        unfinished |= words[:, DONE] < expected
        return words[:, :DONE]

    def _again(self, positions: GrowableBuffer, faces: GrowableBuffer, items: np.ndarray,
               frames: np.ndarray, words: np.ndarray, unfinished: np.ndarray) -> np.ndarray:
        """``words`` with the pairs ``unfinished`` measured again, every line of theirs, in
        items of at most a cluster of each body (:func:`split_items`): a whole item's rounds
        run as many workgroups of one round each. A pair whose items still do not finish is a
        RuntimeError: its figures would be wrong, and a clash could be missed."""
        if not unfinished.any():
            return words
        again = split_items(items[unfinished[items["pair"]]])
        still = np.zeros(len(frames), bool)
        words = words.copy()
        measured = self._finished(positions, faces, again, frames, still)
        k = np.flatnonzero(unfinished)
        words[k] = measured[k]
        if still.any():
            raise RuntimeError(
                f"this adapter ({self.gpu.description}) ended pass H1's workgroups of "
                f"{int(still.sum())} pairs before all their threads finished, even in items of "
                f"one cluster of each body; their hard-clash figures cannot be trusted")
        return words


def split_items(items: np.ndarray) -> np.ndarray:
    """Items of at most :data:`~pycinder.gpu.layout.CLUSTER_FACES` faces of each body covering
    ``items`` (I,) (whole items unflipped: body a's faces as a), measuring every line.

    Returns
    -------
    (J,) structured array of :data:`ITEM`
    """
    out = []
    for item in items:
        flipped = bool(item["whole"] & ITEM_FLIPPED)
        a_start, a_count = int(item["a_start"]), int(item["a_count"])
        b_start, b_count = int(item["b_start"]), int(item["b_count"])
        if flipped:
            a_start, a_count, b_start, b_count = b_start, b_count, a_start, a_count
        starts_a = np.arange(0, a_count, CLUSTER_FACES)
        starts_b = np.arange(0, b_count, CLUSTER_FACES)
        part = ITEM.zeros(len(starts_a) * len(starts_b))
        part["pair"] = item["pair"]
        sa, sb = np.repeat(starts_a, len(starts_b)), np.tile(starts_b, len(starts_a))
        part["a_start"], part["a_count"] = a_start + sa, np.minimum(CLUSTER_FACES, a_count - sa)
        part["b_start"], part["b_count"] = b_start + sb, np.minimum(CLUSTER_FACES, b_count - sb)
        out.append(part)
    return np.concatenate(out) if out else ITEM.zeros(0)


def _same_axes(frames: np.ndarray) -> np.ndarray:
    """Per pair and world axis (x, y, z: lines 6 to 8), the first of the bodies' axes (lines 0
    to 5) that is exactly that axis in single precision (a unit column of a body that is neither
    turned nor scaled along it): the shader's view of the two is the same, and so are their
    figures (-1 where none)."""
    columns = np.concatenate([np.swapaxes(frames["m0"][:, :, :3], 1, 2),
                              np.swapaxes(frames["m1"][:, :, :3], 1, 2)], axis=1)  # (K, 6, 3)
    out = np.full((len(frames), 3), -1, np.int64)
    for axis in range(3):
        alone = (columns[:, :, axis] == 1) & (np.count_nonzero(columns, axis=2) == 1)
        out[:, axis] = np.where(alone.any(axis=1), np.argmax(alone, axis=1), -1)
    return out


def _clears(words: np.ndarray, group: tuple[int, ...]) -> np.ndarray:
    """Which pairs (words (K, 2 LINES) uint32) a line of ``group`` clears: no ray meets both
    bodies along it, or one way along it leaves them apart (as the shader's ``clears``)."""
    ahead, behind = words[:, 2 * np.array(group)], words[:, 2 * np.array(group) + 1]
    zero = np.uint32(0x80000000)  # the word of 0.0
    return np.any((ahead == 0) | (ahead <= zero) | (behind <= zero), axis=1)


__all__ = ["DONE", "FRAME", "ITEM", "ITEM_FLIPPED", "ITEM_SKIP_SHIFT", "ITEM_WHOLE", "LINES",
           "PARAMS", "ROUNDS", "SLACK", "WHOLE_FACES", "WHOLE_WORK", "WORLD_LINES", "Depth",
           "decode", "hull_lower_bound", "lines", "split_items"]

"""Broad phase: world boxes per frame, and the candidate pairs whose boxes overlap.

Sweep and prune, vectorised: the boxes are sorted along the axis where their centres spread most,
each box is paired with the boxes that start before it ends on that axis (one ``searchsorted``),
and the pairs are kept where the boxes also overlap on the other two axes. No Python loop runs per
body or per pair; memory is bounded by processing the sweep in chunks.
"""

from __future__ import annotations

import numpy as np

CHUNK_PAIRS = 4_000_000
"""Most axis-overlap pairs expanded at once (about 100 MB of temporaries)."""

ALL_PAIRS_BELOW = 32
"""Fewer boxes than this are tested pair by pair: a handful of array operations instead of the
sweep's two dozen (2 boxes: about 20 microseconds instead of 100)."""


def side_by_side(lo: np.ndarray, hi: np.ndarray, keys: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Boxes whose x extents are replaced by exact ranks, laid side by side by key: boxes of
    different keys never meet, boxes of one key meet exactly as before.

    Parameters
    ----------
    lo, hi : (N, 3) float
    keys : (N,) int

    Returns
    -------
    lo, hi : (N, 3) float64
    """
    n = len(lo)
    # Ranks of all starts and ends along x, a start before an end of equal value (touching
    # boxes meet): lo_i <= hi_j exactly when rank(lo_i) < rank(hi_j).
    order = np.lexsort((np.repeat([0, 1], n), np.concatenate([lo[:, 0], hi[:, 0]])))
    rank = np.empty(2 * n)
    rank[order] = np.arange(2 * n)
    base = np.unique(keys, return_inverse=True)[1].reshape(-1) * 2.0 * n
    lo, hi = np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)
    lo[:, 0], hi[:, 0] = base + rank[:n], base + rank[n:]
    return lo, hi


def sweep_and_prune(lo: np.ndarray, hi: np.ndarray, within: np.ndarray | None = None,
                    groups: np.ndarray | None = None) -> np.ndarray:
    """All pairs of boxes that overlap (touching counts as overlapping).

    Parameters
    ----------
    lo, hi : (N, 3) float
        Box corners.
    within : (N,) int, optional
        Only pairs of boxes with the same key (the scenes of a batch).
    groups : (N,) int, optional
        Only pairs of boxes in different groups.

    Returns
    -------
    (K, 2) int64
        Pairs ``(i, j)`` with ``i < j``, sorted.
    """
    n = len(lo)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    if n < ALL_PAIRS_BELOW:
        return _all_pairs(lo, hi, within, groups)
    if within is not None:
        lo, hi = side_by_side(lo, hi, within)
    centre = 0.5 * (lo + hi)
    axis = int(np.argmax(centre.var(axis=0)))
    order = np.argsort(lo[:, axis], kind="stable")
    # The sweep axis's bounds in sweep order, and the other two axes' as contiguous columns
    # (gathers from them are faster).
    start_at = lo[:, axis].take(order)
    end_at = hi[:, axis].take(order)
    others = [(lo[:, a].take(order), hi[:, a].take(order)) for a in range(3) if a != axis]
    # For the box at sorted position i, the boxes i+1 .. end[i]-1 start before it ends.
    end = np.searchsorted(start_at, end_at, side="right")
    count = np.maximum(end - np.arange(1, n + 1), 0)
    # Positions fit 32 bits in any scene that fits a GPU: half the memory traffic.
    index = np.int32 if n < 2**31 else np.int64
    out = []
    cum = np.cumsum(count)
    start = 0
    while start < n:
        # Take as many boxes as keep the expansion under CHUNK_PAIRS (at least one).
        base = cum[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(cum, base + CHUNK_PAIRS, side="right")))
        stop = min(stop, n)
        c = count[start:stop]
        total = int(cum[stop - 1] - base)
        if total:
            rows = np.arange(start, stop, dtype=index)
            i = np.repeat(rows, c)
            # j runs from i + 1 within each box's run: a step of 1, and at a run's first
            # candidate the jump from the last run's end to the new run's i + 1.
            j = np.arange(total, dtype=index)
            j += np.repeat(rows + 1 - (np.cumsum(c) - c).astype(index), c)
            # One axis at a time: the second tests only the pairs the first kept.
            for axis_lo, axis_hi in others:
                keep = axis_lo.take(j) <= axis_hi.take(i)
                keep &= axis_lo.take(i) <= axis_hi.take(j)
                i, j = i[keep], j[keep]
            out.append((order.take(i), order.take(j)))
        start = stop
    if not out:
        return np.zeros((0, 2), dtype=np.int64)
    a_ = np.concatenate([a for a, _ in out]) if len(out) > 1 else out[0][0]
    b_ = np.concatenate([b for _, b in out]) if len(out) > 1 else out[0][1]
    first, second = np.minimum(a_, b_), np.maximum(a_, b_)
    if groups is not None:
        across = groups[first] != groups[second]
        first, second = first[across], second[across]
    # Sorted by (first, second): one sort of a key instead of a lexsort of the pairs.
    key = first.astype(np.int64) * n + second
    key.sort()
    pairs = np.empty((len(key), 2), dtype=np.int64)
    np.floor_divide(key, n, out=pairs[:, 0])
    np.subtract(key, pairs[:, 0] * n, out=pairs[:, 1])
    return pairs


def _all_pairs(lo: np.ndarray, hi: np.ndarray, within: np.ndarray | None,
               groups: np.ndarray | None) -> np.ndarray:
    """:func:`sweep_and_prune` of a few boxes, every pair tested."""
    i, j = np.triu_indices(len(lo), 1)  # (i, j) with i < j, sorted
    keep = ((lo[i] <= hi[j]) & (lo[j] <= hi[i])).all(axis=1)
    if within is not None:
        keep &= within[i] == within[j]
    if groups is not None:
        keep &= groups[i] != groups[j]
    return np.stack([i[keep], j[keep]], axis=1).astype(np.int64)

"""Broad phase: world boxes per frame, and the candidate pairs whose boxes overlap.

Sweep and prune, vectorised: the boxes are sorted along the axis where their centres spread most,
each box is paired with the boxes that start before it ends on that axis (one ``searchsorted``),
and the pairs are kept where the boxes also overlap on the other two axes. In a scene of many
boxes, the sweep runs band by band across the axis where the centres spread next most (a box
copied into each band it meets, a pair kept in one band), which expands a few times fewer pairs.
No Python loop runs per body or per pair; memory is bounded by processing the sweep in chunks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CHUNK_PAIRS = 4_000_000
"""Most axis-overlap pairs expanded at once (about 100 MB of temporaries)."""

BANDS_FROM = 256
"""Fewer boxes than this are swept along one axis, in one band."""

MAX_COPIES = 3
"""Most copies of a box, on average, that bands across the sweep may make (see
:func:`_bands`); beyond it the boxes are swept in one band."""

ALL_PAIRS_BELOW = 32
"""Fewer boxes than this are tested pair by pair: a handful of array operations instead of the
sweep's two dozen (2 boxes: about 20 microseconds instead of 100)."""


@dataclass(frozen=True, eq=False)
class PairList:
    """A fixed list of the only pairs a query may test, given where a batch's ``within`` keys go
    (:func:`sweep_and_prune`, and every entry point of the focused strategy that takes
    ``within``): the candidates are the pairs of the list whose boxes overlap, in its order. A
    robot's check gives the pairs its allowed-collision matrix leaves to check, one set per
    configuration, and no sweep runs.

    Parameters
    ----------
    pairs : (K, 2) int
        Pairs ``(i, j)`` with ``i < j``, sorted, each once.
    culled : bool
        The pairs were culled already, by boxes that hold the bodies (a robot check's pass K2,
        :mod:`pycinder.robot.k2_pair_cull`): every pair is a candidate, and no box is tested. A pair
        whose bodies' boxes are apart is found apart by the planner.
    """

    pairs: np.ndarray
    culled: bool = False

    def __post_init__(self) -> None:
        pairs = np.asarray(self.pairs, dtype=np.int64)
        if pairs.ndim != 2 or pairs.shape[1] != 2:
            raise ValueError(f"a pair list is (K, 2), got shape {pairs.shape}")
        if len(pairs) and not ((pairs[:, 0] >= 0).all() and (pairs[:, 0] < pairs[:, 1]).all()):
            raise ValueError("a pair list's pairs are (i, j) with 0 <= i < j")
        object.__setattr__(self, "pairs", pairs)

    def meeting(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """(K', 2) int64: the pairs whose boxes ``lo``, ``hi`` (N, 3) overlap (touching counts),
        in the list's order (all of them, where :attr:`culled`).

        Raises
        ------
        ValueError
            A pair names a box past the N given, or the pairs are not sorted, each once."""
        # Gathers along contiguous rows (an axis of 3 per body is slow to gather by body).
        a, b = np.ascontiguousarray(self.pairs[:, 0]), np.ascontiguousarray(self.pairs[:, 1])
        n = len(lo)
        if len(b) and b.max() >= n:
            raise ValueError(f"a pair list names box {int(b.max())} of {n}")
        key = a * n + b
        if len(key) > 1 and not (key[1:] > key[:-1]).all():
            raise ValueError("a pair list's pairs must be sorted, each once")
        if self.culled:
            return self.pairs
        lo_t, hi_t = np.ascontiguousarray(lo.T), np.ascontiguousarray(hi.T)
        meet = ((lo_t.take(a, axis=1) <= hi_t.take(b, axis=1))
                & (lo_t.take(b, axis=1) <= hi_t.take(a, axis=1))).all(axis=0)
        return self.pairs[meet]


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
    # Exact keys of all starts and ends along x (touching boxes meet, see _ranks), each key's
    # boxes after the last key's.
    start, end = _ranks(lo[:, 0], hi[:, 0])
    base = np.unique(keys, return_inverse=True)[1].reshape(-1) * 4.0 * n
    lo, hi = np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)
    lo[:, 0], hi[:, 0] = base + start, base + end
    return lo, hi


def sweep_and_prune(lo: np.ndarray, hi: np.ndarray, within: np.ndarray | PairList | None = None,
                    groups: np.ndarray | None = None) -> np.ndarray:
    """All pairs of boxes that overlap (touching counts as overlapping).

    Parameters
    ----------
    lo, hi : (N, 3) float
        Box corners.
    within : (N,) int or PairList, optional
        Only pairs of boxes with the same key (the scenes of a batch); or only the pairs of a
        :class:`PairList` (then no sweep runs, and ``groups`` must be None).
    groups : (N,) int, optional
        Only pairs of boxes in different groups.

    Returns
    -------
    (K, 2) int64
        Pairs ``(i, j)`` with ``i < j``, sorted (a pair list's: in its order).
    """
    if isinstance(within, PairList):
        if groups is not None:
            raise ValueError("a pair list names its pairs: groups do not apply")
        return within.meeting(lo, hi)
    n = len(lo)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    if n < ALL_PAIRS_BELOW:
        return _all_pairs(lo, hi, within, groups)
    if within is not None:
        lo, hi = side_by_side(lo, hi, within)
    centre = 0.5 * (lo + hi)
    sweep, across, last = (int(a) for a in np.argsort(-centre.var(axis=0), kind="stable"))
    box, band, base, width = _bands(lo[:, across], hi[:, across])
    if width:
        # Exact integer keys of the starts and ends along the sweep axis (see _ranks), the
        # copy's band first, so that copies of different bands never meet.
        start_rank, end_rank = _ranks(lo[:, sweep], hi[:, sweep])
        stride = np.int64(4 * n)
        start_key = band * stride + start_rank.take(box)
        order = np.argsort(start_key)
        box, band = box.take(order), band.take(order)
        start_at = start_key.take(order)
        end = np.searchsorted(start_at, band * stride + end_rank.take(box), side="left")
    else:
        box = np.argsort(lo[:, sweep])
        start_at = lo[:, sweep].take(box)
        end = np.searchsorted(start_at, hi[:, sweep].take(box), side="right")
    # The other two axes' bounds in sweep order, as contiguous columns (gathers from them are
    # faster); the axis the bands do not sort first, as it keeps fewer pairs.
    others = [(lo[:, a].take(box), hi[:, a].take(box)) for a in (last, across)]
    i, j = _sweep(end, others)
    if width:
        # A pair of boxes that share several bands is met in each: keep it in the band of the
        # larger of their starts across (both boxes were copied into it).
        start_across = others[1][0]
        owner = _band_of(np.maximum(start_across.take(i), start_across.take(j)), base, width)
        keep = owner == band.take(i)
        i, j = i[keep], j[keep]
    a_, b_ = box.take(i), box.take(j)
    first, second = np.minimum(a_, b_), np.maximum(a_, b_)
    if groups is not None:
        across_groups = groups[first] != groups[second]
        first, second = first[across_groups], second[across_groups]
    # Sorted by (first, second): one sort of a key instead of a lexsort of the pairs.
    key = first.astype(np.int64) * n + second
    key.sort()
    pairs = np.empty((len(key), 2), dtype=np.int64)
    np.floor_divide(key, n, out=pairs[:, 0])
    np.subtract(key, pairs[:, 0] * n, out=pairs[:, 1])
    return pairs


def _ranks(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Integer keys (N,) int64 of the starts and ends along one axis, in one order with them
    all: ``start[j] < end[i]`` exactly when ``lo[j] <= hi[i]`` (a start before an end of equal
    value: touching boxes meet); below ``4 N``."""
    n = len(lo)
    every = np.concatenate([lo, hi])
    order = np.argsort(every)
    ordered = every.take(order)
    # Equal values share a rank: the number of distinct values below them.
    distinct = np.empty(2 * n, dtype=np.int64)
    distinct[0] = 0
    np.cumsum(ordered[1:] != ordered[:-1], out=distinct[1:])
    rank = np.empty(2 * n, dtype=np.int64)
    rank[order] = distinct
    return 2 * rank[:n], 2 * rank[n:] + 1


def _band_width(lo: np.ndarray, hi: np.ndarray) -> float:
    """The width of the bands across the sweep (see :func:`_bands`), 0 for one band: a box's
    median extent ``hi - lo`` (N,), and no less than makes about N bands."""
    n = len(lo)
    if n < BANDS_FROM:
        return 0.0
    extent = hi - lo
    width = float(np.partition(extent, n // 2)[n // 2])
    span = float(hi.max() - lo.min())
    if not (np.isfinite(span) and span > 0 and width > 0):
        return 0.0
    return max(width, span / n)


def _band_of(x: np.ndarray, base: float, width: float) -> np.ndarray:
    """The band (int64) of values ``x`` across the sweep, bands ``width`` wide from ``base``:
    the same float operations for every value, so a larger value never falls in an earlier
    band."""
    return np.floor((x - base) / width).astype(np.int64)


def _bands(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The boxes' copies into the bands across the sweep that their extents ``lo``, ``hi``
    (N,) meet: ``box`` and ``band`` (M,) int64, one row per copy, and where the bands start and
    their width (0 for one band; :func:`_band_of` gives a value's band).

    Boxes are swept band by band: a pair that overlaps across the sweep shares a band, and
    the sweep expands only the pairs of one band that overlap along it, a few times fewer in a
    dense scene than along the whole axis. Bands are about a box's median extent wide (the
    width that makes the fewest pairs expanded when boxes are alike, :func:`_band_width`); no
    bands (one copy of each box, in band 0) for fewer than :data:`BANDS_FROM` boxes, or when
    the copies would be more than :data:`MAX_COPIES` per box."""
    n = len(lo)
    one = (np.arange(n, dtype=np.int64), np.zeros(n, dtype=np.int64), 0.0, 0.0)
    width = _band_width(lo, hi)
    if width == 0.0:
        return one
    base = float(lo.min())
    first, end = _band_of(lo, base, width), _band_of(hi, base, width)
    count = end - first + 1
    if int(count.sum()) > MAX_COPIES * n or int(end.max()) == 0 or int(count.min()) < 1:
        return one  # too many copies, one band, or a box inside out
    box = np.repeat(np.arange(n, dtype=np.int64), count)
    band = np.arange(len(box), dtype=np.int64) + np.repeat(first - (np.cumsum(count) - count),
                                                            count)
    return box, band, base, width


def _sweep(end: np.ndarray, others: list[tuple[np.ndarray, np.ndarray]]
           ) -> tuple[np.ndarray, np.ndarray]:
    """Positions ``(i, j)``, ``i < j``, of the items that overlap, items sorted by their
    starts along the sweep: the items ``i + 1 .. end[i] - 1`` (those after ``i`` that start
    before it ends) that overlap it on the ``others`` axes ((lo, hi) of each, in the same
    order). In chunks of at most :data:`CHUNK_PAIRS` expanded pairs."""
    n = len(end)
    count = np.maximum(end - np.arange(1, n + 1), 0)
    # Positions fit 32 bits in any scene that fits a GPU: half the memory traffic.
    index = np.int32 if n < 2**31 else np.int64
    out_i, out_j = [], []
    cum = np.cumsum(count)
    start = 0
    while start < n:
        # Take as many items as keep the expansion under CHUNK_PAIRS (at least one).
        base = cum[start - 1] if start else 0
        stop = max(start + 1, int(np.searchsorted(cum, base + CHUNK_PAIRS, side="right")))
        stop = min(stop, n)
        c = count[start:stop]
        total = int(cum[stop - 1] - base)
        if total:
            rows = np.arange(start, stop, dtype=index)
            i = np.repeat(rows, c)
            # j runs from i + 1 within each item's run: a step of 1, and at a run's first
            # candidate the jump from the last run's end to the new run's i + 1.
            j = np.arange(total, dtype=index)
            j += np.repeat(rows + 1 - (np.cumsum(c) - c).astype(index), c)
            # One axis at a time: the second tests only the pairs the first kept.
            for axis_lo, axis_hi in others:
                keep = axis_lo.take(j) <= axis_hi.take(i)
                keep &= axis_lo.take(i) <= axis_hi.take(j)
                i, j = i[keep], j[keep]
            out_i.append(i)
            out_j.append(j)
        start = stop
    if not out_i:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    if len(out_i) == 1:
        return out_i[0], out_j[0]
    return np.concatenate(out_i), np.concatenate(out_j)


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

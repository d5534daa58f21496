"""Where a demo marks a colliding pair: one point per pair, taken from the pair's records.

A record is a sample of one body's surface (or near one of its edges) that the detector found
inside the other body, so every record lies in the two bodies' overlap. The mark of a pair is its
record nearest the mean of its records: a point of the overlap near its middle.
"""

from __future__ import annotations

import numpy as np

from ..records import pair_keys


def pair_points(records: np.ndarray, pairs: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """One contact point per pair.

    Parameters
    ----------
    records : structured array
        The result's records (fields ``point``, ``penetrating``, ``penetrated``).
    pairs : (K, 2) int
        The pairs to mark.
    fallback : (K, 3) float
        The point used for a pair without records (with ``records="found"`` every reported
        pair has at least one).

    Returns
    -------
    (K, 3) float64
        The record of each pair nearest the mean of its records.
    """
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    out = np.asarray(fallback, np.float64).reshape(-1, 3).copy()
    if len(pairs) == 0 or len(records) == 0:
        return out
    keys = pair_keys(pairs[:, 0], pairs[:, 1])
    order = np.argsort(keys)
    rec_keys = pair_keys(records["penetrating"], records["penetrated"])
    slot = np.clip(np.searchsorted(keys[order], rec_keys), 0, len(keys) - 1)
    mine = keys[order][slot] == rec_keys
    which = order[slot[mine]]  # the pair of each of its records
    points = np.asarray(records["point"], np.float64)[mine]
    if len(points) == 0:
        return out
    count = np.bincount(which, minlength=len(pairs))
    mean = np.stack([np.bincount(which, points[:, k], len(pairs)) for k in range(3)], axis=1)
    mean /= np.maximum(count, 1)[:, None]
    distance = np.linalg.norm(points - mean[which], axis=1)
    nearest = np.lexsort((distance, which))  # by pair, nearest first
    first = nearest[np.r_[True, which[nearest][1:] != which[nearest][:-1]]]
    out[which[first]] = points[first]
    return out

"""Pass C1, distance: the distance between two bodies' surfaces, per candidate pair, exactly (in
single precision), cluster pair by cluster pair (``measure_distance.wgsl``). The clearance query's
one pass; what it is given and what its figures promise is in
:mod:`pycinder.focused.modes.clearance`."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from ...gpu.buffers import GrowableBuffer
from ...gpu.table import PassInfo
from .pair_work import FRAME, ITEM, PARAMS, ClusterPairPass

FAR = int(np.float32(np.inf).view(np.uint32))
"""The figure of a pair no item measured (its bits: +inf)."""

ROUNDS = (1, 8)
"""Items of each pair measured by the rounds of :meth:`Distance.nearest` before the last: the
first round measures each pair's item whose clusters are nearest each other (where touching
pairs touch), the next its next 7, the last all the others still within reach."""


class Distance(ClusterPairPass):
    """C1: one workgroup per item (a cluster of body a and one of body b whose boxes are within
    the clearance); per pair the smallest distance found (atomicMin)."""

    INFO: ClassVar[PassInfo] = PassInfo(
        "C1", "distance", "distance between the surfaces of each candidate pair, cluster pair "
        "by cluster pair", when="clearance queries")
    SHADER, ENTRY, WORDS, START = "measure_distance", "distance", 1, FAR

    def run(self, positions: GrowableBuffer, faces: GrowableBuffer, items: np.ndarray,
            frames: np.ndarray) -> np.ndarray:
        """Measure (arguments as :meth:`~pycinder.focused.measure.pair_work.ClusterPairPass.words`).

        Returns
        -------
        (K,) float32
            Per pair the smallest distance between its surfaces found in its items (+inf for a
            pair with no item).
        """
        return self.words(positions, faces, items, frames)[:, 0].view(np.float32).copy()

    def nearest(self, positions: GrowableBuffer, faces: GrowableBuffer, items: np.ndarray,
                frames: np.ndarray, gap: np.ndarray, apart: np.ndarray, margin: np.ndarray
                ) -> np.ndarray:
        """:meth:`run`'s figures, measuring only the items that can lower them.

        An item's distance lies between its ``gap`` and its ``apart``; measured, it is at least
        its gap less its rounding. So an item whose gap exceeds a pair's least ``apart``, or the
        least distance measured so far, by more than ``margin`` (at least twice that rounding)
        could not be below the least found, and is left out: each pair's items are measured in
        rounds, in the order of their ``apart`` (:data:`ROUNDS`), each round taking only the
        items still within reach of the least distance found (none once it is 0). The figures
        are :meth:`run`'s over every item, bit for bit.

        Parameters
        ----------
        positions, faces : GrowableBuffer
        items : (I,) structured array of :data:`~pycinder.focused.measure.pair_work.ITEM`
        frames : (K,) structured array of :data:`~pycinder.focused.measure.pair_work.FRAME`
        gap, apart : (I,) float64
            A lower and an upper bound of each item's distance.
        margin : (K,) float64
            Per pair, at least twice the rounding of a distance measured in its frame.

        Returns
        -------
        (K,) float32
        """
        pair = items["pair"].astype(np.int64)
        bound = np.full(len(frames), np.inf)
        np.minimum.at(bound, pair, apart)
        within = np.flatnonzero(gap <= bound[pair] + margin[pair])
        order = within[np.lexsort((apart[within], pair[within]))]
        rank = np.arange(len(order)) - np.searchsorted(pair[order], pair[order])
        found = np.full(len(frames), np.inf, np.float32)
        start = 0
        for end in (*ROUNDS, None):
            part = order[(rank >= start) & ((rank < end) if end is not None else True)]
            least = found[pair[part]].astype(np.float64)
            part = part[(least > 0) & (gap[part] <= least + margin[pair[part]])]
            if len(part):
                found = np.minimum(found, self.run(positions, faces, items[part], frames))
            start = end if end is not None else start
        return found


__all__ = ["FAR", "FRAME", "ITEM", "PARAMS", "ROUNDS", "Distance"]

"""Pass C1, distance: the distance between two bodies' surfaces, per candidate pair, exactly (in
single precision), cluster pair by cluster pair (``distance.wgsl``). The clearance query's one
pass; what it is given and what its figures promise is in
:mod:`pycinder.focused.modes.clearance`."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from ...gpu.buffers import GrowableBuffer
from ...gpu.table import PassInfo
from .pairwork import FRAME, ITEM, PARAMS, ClusterPairPass

FAR = int(np.float32(np.inf).view(np.uint32))
"""The figure of a pair no item measured (its bits: +inf)."""


class Distance(ClusterPairPass):
    """C1: one workgroup per item (a cluster of body a and one of body b whose boxes are within
    the clearance); per pair the smallest distance found (atomicMin)."""

    INFO: ClassVar[PassInfo] = PassInfo(
        "C1", "distance", "distance between the surfaces of each candidate pair, cluster pair "
        "by cluster pair", when="clearance queries")
    SHADER, ENTRY, WORDS, START = "distance", "distance", 1, FAR

    def run(self, positions: GrowableBuffer, faces: GrowableBuffer, items: np.ndarray,
            frames: np.ndarray) -> np.ndarray:
        """Measure (arguments as :meth:`~pycinder.focused.modes.pairwork.ClusterPairPass.words`).

        Returns
        -------
        (K,) float32
            Per pair the smallest distance between its surfaces found in its items (+inf for a
            pair with no item).
        """
        return self.words(positions, faces, items, frames)[:, 0].view(np.float32).copy()


__all__ = ["FAR", "FRAME", "ITEM", "PARAMS", "Distance"]

"""What every system of the benchmark answers: :class:`System`, which the peers
(:mod:`~benchmarks.peers`, :mod:`~benchmarks.warp_peer`) and pycinder's own
entry implement."""

from __future__ import annotations

import numpy as np

from pycinder.testing.scenes import Scene


class System:
    name = "system"

    def prepare(self, scene: Scene) -> None:
        """Untimed set-up for a scene (rigid geometry is built here)."""

    def step(self, scene: Scene, k: int) -> np.ndarray:
        """The colliding pairs (K, 2) of frame k, including any per-frame update work."""
        raise NotImplementedError

"""What a query mode may ask of the strategy that runs it: :class:`ModeHost`.

The focused strategy makes each mode with itself as the host and calls the mode's ``run``; a mode
reads the strategy only through this interface, so the modes never import the strategy and the
strategy's own modules never need a mode to be read.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from ...gpu.device import Gpu
    from ..broad.broad_numpy import PairList
    from ...request import CollisionRequest
    from ...result import Stats
    from ...scene import Scene
    from ...scene.pack import ShapePack
    from ...strategy import Pending
    from ..frame.frames import FocusedFrames


class ModeHost(Protocol):
    """The strategy a mode runs on: its device, its request, its shapes and frames, and its
    interference test (the strategy's default mode)."""

    gpu: Gpu
    request: CollisionRequest
    frames: FocusedFrames
    """The frames' buffers hold the shapes as last uploaded by :meth:`pack`."""

    def pack(self, scene: Scene, stats: Stats) -> ShapePack:
        """The scene's shapes packed and uploaded."""
        ...

    def submit_interference(self, scene: Scene, stats: Stats,
                            groups: np.ndarray | None = None, records: str | None = None,
                            within: np.ndarray | PairList | None = None,
                            body_tolerances: np.ndarray | None = None,
                            stop_at_first: bool = False) -> Pending:
        """The interference test of ``scene``, submitted."""
        ...

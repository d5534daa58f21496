"""How the scene strategy handles self-interference (paper 4.3.1), one small class per mode.

A mode chooses the pass table and plan the frame runs (see :mod:`pycinder.gpu.states`), how
far edges are moved outwards, and whether normals must be packed. The focused strategy needs none
of this: it only ever tests a body's edges against the other body of a pair.
"""

from __future__ import annotations

import numpy as np

from ..gpu.states import PASSES, PLAN, PREVENT, PREVENT_PLAN, PassState, RenderStep
from ..request import CollisionRequest
from ..view import View


class SelfInterference:
    name = ""
    table: dict[int, PassState] = PASSES
    plan: tuple[RenderStep, ...] = PLAN
    needs_normals = False

    def __init__(self, request: CollisionRequest) -> None:
        self.request = request

    def edge_offset(self, view: View, resolution: int, centre: np.ndarray) -> float:
        """How far edges move outwards along their vertex normals, in world units."""
        return 0.0


class Prevent(SelfInterference):
    """4.3.1.3 done in the shader: a body's faces are never counted in front of its own edges."""

    name = "prevent"
    table = PREVENT
    plan = PREVENT_PLAN


class Filter(SelfInterference):
    """4.3.1.2: let self-interference register, then blank ``r == g`` pixels before readback."""

    name = "filter"


class Offset(SelfInterference):
    """4.3.1.1: move edges outwards along vertex normals (default: half a pixel of the view at the
    scene's centre, so it works through any view)."""

    name = "offset"
    needs_normals = True

    def edge_offset(self, view: View, resolution: int, centre: np.ndarray) -> float:
        if self.request.edge_offset is not None:
            return float(self.request.edge_offset)
        return 0.5 * view.pixel_size_at(centre, resolution)


SELF_INTERFERENCE: dict[str, type[SelfInterference]] = {
    m.name: m for m in (Prevent, Filter, Offset)}

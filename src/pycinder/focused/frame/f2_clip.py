"""Pass F2, clip: the faces of each kept cluster projected into their tile and clipped to its
window, as triangles for pass F3 (``frame_clip.wgsl``: ``clip`` passes on the faces within the
window and lists the rest, ``cut`` cuts those, one thread each)."""

from __future__ import annotations

from typing import ClassVar

from ...gpu.bindings import Stage, dispatch
from ...gpu.device import Gpu
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .arguments import Arguments
from .atlas_buffers import Encoding
from .scope import ComputeScope

PARAMS = Struct("ClipParams", [
    ("tri_cap", "u32", "triangles the buffer holds (and faces the cut list holds)"),
    ("item_cap", "u32", "face items the buffer holds"),
], uniform=True)


class Clip:
    """F2: clip, then cut the faces reaching beyond their window (watertight: both faces of an
    edge cut it at the same point)."""

    SHADER: ClassVar[str] = "frame_clip"
    """Its shader, ``shaders/frame_clip.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "F2", "clip", "kept faces into their tile's window, cut watertight", when="every round")
    PARAMS: ClassVar[Struct] = PARAMS

    def __init__(self, gpu: Gpu, arguments: Arguments) -> None:
        self.clip = Stage(gpu, self.SHADER, "clip", label=self.INFO.title, structs=(PARAMS,))
        self.cut = Stage(gpu, self.SHADER, "cut", label="F2 clip: cuts", structs=(PARAMS,))
        self.arguments = arguments

    def write_params(self, e: Encoding) -> None:
        p = e.frame_params("clip")
        p["tri_cap"] = e.buffers.caps.tris
        p["item_cap"] = e.state.items

    def encode(self, scope: ComputeScope, e: Encoding) -> None:
        b = e.buffers
        bind = dict(tiles=b.tiles, clusters=b.clusters, positions=b.positions, faces=b.faces,
                    face_items=b.face_items, tris=b.tris, counters=b.counters,
                    params=e.frame_params.binding("clip"), tri_face=b.tri_face, cuts=b.cuts)
        cpass = scope.begin(self.INFO.title)
        dispatch(cpass, self.clip, self.clip.group(**bind), indirect=b.args_at("clip"))
        self.arguments.encode(cpass, e, "after_clip_faces")
        dispatch(cpass, self.cut, self.cut.group(**bind), indirect=b.args_at("cut"))
        self.arguments.encode(cpass, e, "after_clip")


__all__ = ["Clip"]

"""Pass F3, crossings: the one rasterised pass of the focused strategy. Every clipped face of
both bodies is drawn once into the atlas; at each pixel centre it covers, it crosses the pixel's
ray: in front of the tile's box (behind it, for tiles counting backwards) it adds to its body's
winding there, as passes 2 and 3 of the paper do in the stencil buffer; within the box it is
listed with its depth, facing and face (``frame_crossings.wgsl``)."""

from __future__ import annotations

from typing import ClassVar

import wgpu

from ...gpu.bindings import Profiler, Stage
from ...gpu.device import Gpu
from ...gpu.states import FOCUSED_CROSSINGS
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .atlas_buffers import Encoding, Round

ATLAS = Struct("Atlas", [
    ("width", "u32", "atlas pixels per row (the stride of the per-pixel buffers)"),
    ("height", "u32", "rows of the render target"),
    ("capacity", "u32", "list entries per pixel"),
    ("target_width", "u32", "columns of the render target (at least `width`)"),
], uniform=True)


class Crossings:
    """F3: per pixel, the winding outside the box and the list of crossings inside it. The
    render target only rasterises (nothing is written to it); it is made here, and grown when
    an atlas needs more."""

    STATE = FOCUSED_CROSSINGS
    SHADER: ClassVar[str] = "frame_crossings"
    """Its shader, ``shaders/frame_crossings.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "F3", "crossings", "every face crossing of each pixel ray, per body", kind="render",
        state=f"no depth, no stencil, cull {FOCUSED_CROSSINGS.cull}, no colour writes",
        when="every round")
    PARAMS: ClassVar[Struct] = ATLAS

    def __init__(self, gpu: Gpu) -> None:
        self.gpu = gpu
        state = self.STATE
        self.stage = Stage(gpu, self.SHADER, render={
            "primitive": {"topology": "triangle-list", "cull_mode": state.cull},
            "targets": [{"format": "r8unorm", "write_mask": state.write_mask}]},
            label=self.INFO.title, structs=(ATLAS,))
        self.target: wgpu.GPUTexture | None = None
        self.view: wgpu.GPUTextureView | None = None
        self.generation = 0
        """Render targets made so far (the frames' recorded rounds name the latest)."""

    def ensure_target(self, width: int, rows: int) -> None:
        """A render target of at least ``width`` x ``rows`` pixels (raises ValueError over the
        device's texture limit). A new one is made a power of two in each direction (within the
        limit) and never smaller than the last: frames whose atlases differ a little keep it, and
        the rounds recorded with it (one byte a pixel)."""
        old = self.target
        if old is not None and old.width >= width and old.height >= rows:
            return
        if old is not None:
            width, rows = max(width, old.width), max(rows, old.height)
        limit = self.gpu.max_resolution
        if width > limit or rows > limit:
            raise ValueError(f"an atlas of {width} x {rows} pixels is over this device's "
                             f"texture limit of {limit}; lower memory_budget")
        size = [min(1 << (max(n, 1) - 1).bit_length(), limit) for n in (width, rows)]
        self.target = self.gpu.device.create_texture(
            label="atlas", size=(size[0], size[1], 1), format="r8unorm",
            usage=wgpu.TextureUsage.RENDER_ATTACHMENT)
        self.view = self.target.create_view()
        self.generation += 1

    def write_params(self, e: Encoding) -> None:
        for name, retry in (("atlas", False), ("atlas retry", True)):
            p = e.frame_params(name)
            p["width"] = e.state.atlas_width
            p["height"] = self.target.height
            p["capacity"] = e.state.capacity_of(retry)
            p["target_width"] = self.target.width

    def encode(self, encoder: wgpu.GPUCommandEncoder, profiler: Profiler, e: Encoding,
               r: Round) -> None:
        b = e.buffers
        rpass = encoder.begin_render_pass(
            label=f"{self.INFO.title}, round {r.block}",
            color_attachments=[{"view": self.view, "load_op": "load", "store_op": "discard"}],
            **profiler.writes(self.INFO.title))
        rpass.set_pipeline(self.stage.pipeline)
        rpass.set_bind_group(0, self.stage.group(
            r.kind, tris=b.tris, tiles=b.tiles, pixels=b.pixels, crossings=b.lists,
            atlas=e.frame_params.binding("atlas retry" if r.retry else "atlas"),
            tri_face=b.tri_face, active_pixels=b.active, counters=b.counters))
        b_args, offset = b.args_at("draw")
        rpass.draw_indirect(b_args, offset)
        rpass.end()


__all__ = ["Crossings"]

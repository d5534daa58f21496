"""Passes 1-7 of the whole-scene strategy: edges into depth, virtual ray casting in the stencil,
and identification (the paper's Appendix A).

One pipeline per pass, built from the state table in :mod:`pycinder.gpu.states` (the single
source of each pass's depth, stencil and cull state) once per detector. The pipelines share one
bind group, bound by the names ``wholescene_raycast.wgsl`` declares. The draw commands of a scene
are recorded into render bundles once per topology and replayed every frame; a frame only uploads
transforms (and changed vertices) and its :data:`FRAME` block.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import replace
from typing import TYPE_CHECKING, ClassVar

import wgpu

from ..gpu.bindings import Stage
from ..gpu.buffers import RECORD_FORMAT, SceneBuffers, Targets
from ..gpu.device import Gpu
from ..gpu.states import DEPTH_CLEAR, PASSES, PLAN, STENCIL_MASK, PassState, RenderStep
from ..gpu.structs import Struct
from ..gpu.table import PassInfo

if TYPE_CHECKING:
    from .encoding import SceneFrame

FRAME = Struct("Frame", [
    ("edge_offset", "f32", "offset of edge vertices along their vertex normal, in world units "
                           "(self_interference=\"offset\")"),
    ("payload_mode", "u32", "PAYLOAD_EDGE_INDEX or PAYLOAD_NORMAL: what channel a holds"),
], uniform=True, doc="What passes 1 and 4 need of the view: written by the host once per view.")

PAYLOAD = {"PAYLOAD_EDGE_INDEX": 0, "PAYLOAD_NORMAL": 1}
"""Values of ``Frame.payload_mode``: the edge's global index + 1, or its packed world normal."""


def pass_info(state: PassState) -> PassInfo:
    """The pass table's row of one of passes 1-7, from its state."""
    return PassInfo(str(state.number), state.name, state.purpose, "render", state.summary,
                    "every view, body by body" if state.per_body else "every view")


class RaycastPasses:
    """Passes 1-7: their render pipelines, their :data:`FRAME` block, their bind group by name,
    and the recording of their draws, grouped into the render steps of a plan.

    Parameters
    ----------
    gpu : Gpu
    states : dict of int to PassState
        The pass table (``PASSES``, or ``PREVENT`` for paper 4.3.1.3).
    plan : tuple of RenderStep
        The render passes that passes 1-7 are grouped into.
    """

    SHADER: ClassVar[str] = "wholescene_raycast"
    """Its shader, ``shaders/wholescene_raycast.wgsl``."""
    INFOS: ClassVar[tuple[PassInfo, ...]] = tuple(pass_info(s) for s in PASSES.values())
    STRUCTS: ClassVar[tuple[Struct, ...]] = (FRAME,)

    def __init__(self, gpu: Gpu, states: dict[int, PassState] = PASSES,
                 plan: tuple[RenderStep, ...] = PLAN) -> None:
        self.gpu = gpu
        self.states, self.plan = states, plan
        self.stages = {n: self._stage(s) for n, s in states.items()}
        self.pipelines = {n: stage.pipeline for n, stage in self.stages.items()}
        self.frame = FRAME.zeros()
        self.frame_buffer = gpu.device.create_buffer(
            label="frame", size=-(-FRAME.size // 16) * 16,  # uniform bindings: whole 16 bytes
            usage=wgpu.BufferUsage.UNIFORM | wgpu.BufferUsage.COPY_DST)
        self._capture: Stage | None = None
        self._bundles: dict[tuple, list[wgpu.GPURenderBundle]] = {}
        self._bind_group: wgpu.GPUBindGroup | None = None

    def _stage(self, state: PassState) -> Stage:
        """The pipeline of one pass, with the state of its row of the table."""
        edges = state.draws == "edges"
        fragment = "fs_edge" if edges else "fs_face"
        if state.skip_own_faces:
            fragment = "fs_face_prevent"
        stencil_face = {"compare": state.stencil_compare, "fail_op": "keep",
                        "depth_fail_op": "keep", "pass_op": state.stencil_pass_op}
        render = {
            "vertex": "vs_edge" if edges else "vs_face", "fragment": fragment,
            "primitive": {"topology": "line-list" if edges else "triangle-list",
                          "front_face": "ccw", "cull_mode": state.cull},
            "depth_stencil": {
                "format": self.gpu.depth_format,
                "depth_write_enabled": state.depth_write,
                "depth_compare": state.depth_compare,
                "stencil_front": stencil_face, "stencil_back": stencil_face,
                "stencil_read_mask": STENCIL_MASK, "stencil_write_mask": STENCIL_MASK},
            "targets": [{"format": RECORD_FORMAT, "write_mask": state.write_mask}],
        }
        return Stage(self.gpu, self.SHADER, render=render, label=f"pass {state.number}: "
                     f"{state.purpose}", structs=self.STRUCTS, consts=PAYLOAD, layout="declared")

    def capture_pipeline(self) -> wgpu.GPURenderPipeline:
        """Pass 1 writing r, b, a as well (as the prevent table's pass 1 does): for the debug
        capture, whose readout of the depth buffer is the b channel (the edge's depth bits)."""
        if self._capture is None:
            self._capture = self._stage(replace(self.states[1], color_writes="rba"))
        return self._capture.pipeline

    def write_frame(self, edge_offset: float, payload_normal: bool) -> None:
        """Write the :data:`FRAME` block of the next view.

        Parameters
        ----------
        edge_offset : float
            World units that passes 1 and 4 move edges along their vertex normals.
        payload_normal : bool
            Channel a holds the packed edge normal (else the edge's index + 1).
        """
        self.frame["edge_offset"] = edge_offset
        self.frame["payload_mode"] = PAYLOAD["PAYLOAD_NORMAL" if payload_normal
                                             else "PAYLOAD_EDGE_INDEX"]
        self.gpu.device.queue.write_buffer(self.frame_buffer, 0, self.frame)

    def bind_group(self, buffers: SceneBuffers, targets: Targets) -> wgpu.GPUBindGroup:
        """The bind group of every pass, by binding name (bundles are re-recorded when it
        changes, that is when a buffer grew)."""
        group = self.stages[1].group(
            "scene", frame=self.frame_buffer, edge_owner_tex=targets.edge_owner_view,
            **{name: buffers.storage[name] for name in SceneBuffers.NAMES})
        if group is not self._bind_group:
            self._bind_group = group
            self._bundles.clear()
        return group

    def record(self, enc: wgpu.GPURenderCommandsMixin, passes: Iterable[int], buffers: SceneBuffers,
               bind_group: wgpu.GPUBindGroup, capture: bool = False) -> None:
        """Record the draws of ``passes`` (in paper order) onto a render pass or bundle encoder:
        one draw per pass over all bodies, then the per-body passes body by body."""
        scene = buffers.scene
        passes = sorted(passes)
        enc.set_bind_group(0, bind_group)
        enc.set_index_buffer(buffers.index.buffer, wgpu.IndexFormat.uint32)
        n_edge_vertices = 2 * len(scene.edges)
        n_indices = len(scene.indices)
        for n in passes:
            if self.states[n].per_body:
                continue
            enc.set_pipeline(self.capture_pipeline() if capture and n == 1 else self.pipelines[n])
            if self.states[n].draws == "edges":
                enc.draw(n_edge_vertices)
            else:
                enc.draw_indexed(n_indices)
        per_body = [n for n in passes if self.states[n].per_body]
        if per_body:
            starts = (3 * scene.face_start).tolist()
            for b in range(len(starts) - 1):
                for n in per_body:
                    enc.set_pipeline(self.pipelines[n])
                    enc.draw_indexed(starts[b + 1] - starts[b], 1, starts[b])

    def bundles(self, buffers: SceneBuffers, targets: Targets) -> list[wgpu.GPURenderBundle]:
        """One bundle per step of the plan for the current scene, recorded once per topology."""
        bind_group = self.bind_group(buffers, targets)
        key = buffers.scene.topology_ids
        if key not in self._bundles:
            self._bundles.clear()
            out = []
            for step in self.plan:
                enc = self.gpu.device.create_render_bundle_encoder(
                    color_formats=[RECORD_FORMAT], depth_stencil_format=self.gpu.depth_format)
                self.record(enc, step.passes, buffers, bind_group)
                out.append(enc.finish())
            self._bundles[key] = out
        return self._bundles[key]

    def encode(self, frame: SceneFrame) -> None:
        """Record passes 1-7 of the uploaded scene: one render pass per step of the plan, each
        timed by the frame's profiler under the step's title."""
        bundles = self.bundles(frame.buffers, frame.targets)
        for step, bundle in zip(self.plan, bundles):
            rp = begin_step(frame.encoder, frame.targets, step,
                            **frame.profiler.writes(step.title))
            rp.execute_bundles([bundle])
            rp.end()

    def encode_each(self, device: wgpu.GPUDevice, buffers: SceneBuffers, targets: Targets,
                    hook: Callable[[str], None]) -> None:
        """Run each pass in its own render pass and submission, calling ``hook("pass N")``
        after each, for the debug capture.

        Passes 5-7 stay together (they run body by body); the steps' own starts (clears,
        copies) stay where they are. Pass 1 also writes its edges' depth bits into the colour
        target (channel b) for the hook to read, and the colour target is cleared again after it
        where the plan would not do so."""
        bind_group = self.bind_group(buffers, targets)
        for step in self.plan:
            for k, chunk in enumerate(self._chunks(step)):
                encoder = device.create_command_encoder()
                start = step if k == 0 else RenderStep(chunk, False, False)
                rp = begin_step(encoder, targets, start)
                self.record(rp, chunk, buffers, bind_group, capture=True)
                rp.end()
                device.queue.submit([encoder.finish()])
                hook(f"pass {chunk[-1]}")
                if chunk == (1,) and self.states[1].color_writes != "rba" \
                        and len(step.passes) > 1:
                    encoder = device.create_command_encoder()
                    begin_step(encoder, targets, RenderStep((), False, True)).end()
                    device.queue.submit([encoder.finish()])

    def _chunks(self, step: RenderStep) -> list[tuple[int, ...]]:
        """The passes of a step, one by one, except consecutive per-body passes together."""
        chunks: list[tuple[int, ...]] = []
        for n in step.passes:
            if chunks and self.states[n].per_body and self.states[chunks[-1][-1]].per_body:
                chunks[-1] += (n,)
            else:
                chunks.append((n,))
        return chunks


def begin_step(encoder: wgpu.GPUCommandEncoder, targets: Targets, step: RenderStep,
               **timestamps: dict) -> wgpu.GPURenderPassEncoder:
    """Start the render pass of one step (paper lines 4-7 for the first); ``timestamps`` are the
    profiler's keyword arguments."""
    if step.copy_owner_before:
        # The colour target holds the edge owners after pass 1: keep a copy to read from.
        encoder.copy_texture_to_texture(
            {"texture": targets.records}, {"texture": targets.edge_owner},
            (targets.width, targets.height, 1))
    colour = "clear" if step.clear_colour else "load"
    depth_stencil = "clear" if step.clear_depth_stencil else "load"
    return encoder.begin_render_pass(
        label=step.title,
        color_attachments=[{"view": targets.records_view, "clear_value": (0, 0, 0, 0),
                            "load_op": colour, "store_op": "store"}],
        depth_stencil_attachment={
            "view": targets.depth_stencil_view,
            "depth_clear_value": DEPTH_CLEAR, "depth_load_op": depth_stencil,
            "depth_store_op": "store", "stencil_clear_value": 0,
            "stencil_load_op": depth_stencil, "stencil_store_op": "store",
        },
        **timestamps,
    )


__all__ = ["FRAME", "PAYLOAD", "RaycastPasses", "begin_step", "pass_info"]

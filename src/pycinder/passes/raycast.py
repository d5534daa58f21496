"""Passes 1-7: edges into depth, virtual ray casting in the stencil, and identification.

Pipelines are built from the state table in :mod:`pycinder.passes.states` once per detector. The
draw commands of a scene are recorded into render bundles once per topology and replayed every
frame; a frame only uploads transforms (and changed vertices).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

import wgpu

from ..gpu.buffers import RECORD_FORMAT, SceneBuffers, Targets
from ..gpu.device import Gpu, shader_source
from .states import DEPTH_CLEAR, PASSES, PLAN, STENCIL_MASK, PassState, RenderStep

_VERTEX, _FRAGMENT = wgpu.ShaderStage.VERTEX, wgpu.ShaderStage.FRAGMENT


def _bind_group_layout(device: wgpu.GPUDevice) -> wgpu.GPUBindGroupLayout:
    entries = [{"binding": 0, "visibility": _VERTEX,
                "buffer": {"type": wgpu.BufferBindingType.uniform}}]
    entries += [{"binding": b, "visibility": _VERTEX,
                 "buffer": {"type": wgpu.BufferBindingType.read_only_storage}} for b in range(1, 8)]
    entries.append({"binding": 8, "visibility": _FRAGMENT,
                    "texture": {"sample_type": wgpu.TextureSampleType.uint}})
    return device.create_bind_group_layout(label="raycast", entries=entries)


class RaycastPasses:
    """The render pipelines of passes 1-7 and the recording of their draws.

    states : the pass table (``PASSES``, or ``PREVENT`` for paper 4.3.1.3)
    plan : the render steps the passes are grouped into
    """

    def __init__(self, gpu: Gpu, states: dict[int, PassState] = PASSES,
                 plan: tuple[RenderStep, ...] = PLAN) -> None:
        self.gpu = gpu
        device = gpu.device
        self.module = device.create_shader_module(label="raycast", code=shader_source("raycast"))
        self.layout = _bind_group_layout(device)
        pipeline_layout = device.create_pipeline_layout(bind_group_layouts=[self.layout])
        self.states = states
        self.plan = plan
        self.pipelines = {n: self._pipeline(pipeline_layout, s) for n, s in self.states.items()}
        self._pipeline_layout = pipeline_layout
        self._capture: wgpu.GPURenderPipeline | None = None
        self._bundles: dict[tuple, list[wgpu.GPURenderBundle]] = {}
        self._bind_group: wgpu.GPUBindGroup | None = None
        self._bind_key: tuple | None = None

    def _pipeline(self, layout: wgpu.GPUPipelineLayout, state: PassState) -> wgpu.GPURenderPipeline:
        edges = state.draws == "edges"
        fragment = "fs_edge" if edges else "fs_face"
        if state.skip_own_faces:
            fragment = "fs_face_prevent"
        stencil_face = {"compare": state.stencil_compare, "fail_op": "keep",
                        "depth_fail_op": "keep", "pass_op": state.stencil_pass_op}
        return self.gpu.device.create_render_pipeline(
            label=f"pass {state.number}: {state.purpose}",
            layout=layout,
            vertex={"module": self.module, "entry_point": "vs_edge" if edges else "vs_face"},
            primitive={"topology": "line-list" if edges else "triangle-list",
                       "front_face": "ccw", "cull_mode": state.cull},
            depth_stencil={
                "format": self.gpu.depth_format,
                "depth_write_enabled": state.depth_write,
                "depth_compare": state.depth_compare,
                "stencil_front": stencil_face,
                "stencil_back": stencil_face,
                "stencil_read_mask": STENCIL_MASK,
                "stencil_write_mask": STENCIL_MASK,
            },
            fragment={"module": self.module, "entry_point": fragment,
                      "targets": [{"format": RECORD_FORMAT, "write_mask": state.write_mask}]},
        )

    def capture_pipeline(self) -> wgpu.GPURenderPipeline:
        """Pass 1 writing r, b, a as well (as the prevent table's pass 1 does): for the debug
        capture, whose readout of the depth buffer is the b channel (the edge's depth bits)."""
        if self._capture is None:
            self._capture = self._pipeline(self._pipeline_layout,
                                           replace(self.states[1], color_writes="rba"))
        return self._capture

    def bind_group(self, buffers: SceneBuffers, targets: Targets) -> wgpu.GPUBindGroup:
        key = (buffers.generation, id(targets))
        if key != self._bind_key:
            entries = [{"binding": 0, "resource": {"buffer": buffers.frame}}]
            entries += [{"binding": i + 1, "resource": {"buffer": buffers.storage[n].buffer}}
                        for i, n in enumerate(SceneBuffers.NAMES)]
            entries.append({"binding": 8, "resource": targets.edge_owner_view})
            self._bind_group = self.gpu.device.create_bind_group(layout=self.layout, entries=entries)
            self._bind_key = key
            self._bundles.clear()
        return self._bind_group

    def record(self, enc: wgpu.GPURenderCommandsMixin, passes: Iterable[int], buffers: SceneBuffers,
               bind_group: wgpu.GPUBindGroup, capture: bool = False) -> None:
        """Record the draws of ``passes`` (in paper order) onto a render pass or bundle encoder."""
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

    def encode(self, encoder: wgpu.GPUCommandEncoder, buffers: SceneBuffers, targets: Targets,
               timestamp_writes: list[dict | None] | None = None) -> None:
        """Record passes 1-7 of the uploaded scene: one render pass per step of the plan."""
        bundles = self.bundles(buffers, targets)
        for i, (step, bundle) in enumerate(zip(self.plan, bundles)):
            ts = timestamp_writes[i] if timestamp_writes else None
            rp = self.begin_step(encoder, targets, step, timestamp_writes=ts)
            rp.execute_bundles([bundle])
            rp.end()

    @staticmethod
    def begin_step(encoder: wgpu.GPUCommandEncoder, targets: Targets, step: RenderStep,
                   timestamp_writes: dict | None = None) -> wgpu.GPURenderPassEncoder:
        """Start the render pass of one step (paper lines 4-7 for the first)."""
        if step.copy_owner_before:
            # The colour target holds the edge owners after pass 1: keep a copy to read from.
            encoder.copy_texture_to_texture(
                {"texture": targets.records}, {"texture": targets.edge_owner},
                (targets.width, targets.height, 1))
        colour = "clear" if step.clear_colour else "load"
        depth_stencil = "clear" if step.clear_depth_stencil else "load"
        kwargs = {"timestamp_writes": timestamp_writes} if timestamp_writes else {}
        return encoder.begin_render_pass(
            color_attachments=[{"view": targets.records_view, "clear_value": (0, 0, 0, 0),
                                "load_op": colour, "store_op": "store"}],
            depth_stencil_attachment={
                "view": targets.depth_stencil_view,
                "depth_clear_value": DEPTH_CLEAR, "depth_load_op": depth_stencil,
                "depth_store_op": "store", "stencil_clear_value": 0,
                "stencil_load_op": depth_stencil, "stencil_store_op": "store",
            },
            **kwargs,
        )

"""One frame of the paper's passes through one view: the runner that the scene strategy and the
debug capture share.

    passes 1-7 (grouped into render steps) -> self-interference filter -> readback mode's GPU work
    -> counters (16 bytes; nothing else when nothing survived) -> records

Normally each render step replays a render bundle recorded once per topology, and everything goes
in one submission. With a hook, every pass gets its own render pass and submission and the hook
runs after each, so the debug capture can read the depth, stencil and colour buffers between
passes (the paper's Figures 9 to 13).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import wgpu

from .gpu.buffers import Readback, SceneBuffers, Targets
from .gpu.device import Gpu
from .passes.filter import FilterPass
from .passes.raycast import RaycastPasses
from .passes.states import RenderStep
from .readback import ReadbackMode
from .result import Stats

Hook = Callable[[str], None]
"""Called with ``"pass N"`` after pass N (``"pass 7"`` after passes 5-7, which run body by body)
and with ``"filter"`` after the filter."""


class FrameRunner:
    """Runs passes 1-7, the filter and the readback of one view.

    Parameters
    ----------
    gpu : Gpu
    raycast : RaycastPasses
    filter_pass : FilterPass
    readback : ReadbackMode
    targets : Targets
    buffers : SceneBuffers
        The uploaded scene, with the view's matrices already written.
    profile : bool
        Time each render step and the filter with timestamp queries.
    """

    def __init__(self, gpu: Gpu, raycast: RaycastPasses, filter_pass: FilterPass,
                 readback: ReadbackMode, targets: Targets, buffers: SceneBuffers,
                 profile: bool = False) -> None:
        self.gpu, self.raycast, self.filter, self.readback = gpu, raycast, filter_pass, readback
        self.targets, self.buffers = targets, buffers
        device = gpu.device
        self.counters = Readback(device, "counters readback")
        self.records = Readback(device, "records readback")
        self.profile = profile and gpu.timestamps
        if self.profile:
            self.stage_names = [" + ".join(f"pass {n}" for n in step.passes)
                                for step in raycast.plan] + ["filter"]
            n = 2 * len(self.stage_names)
            self.queries = device.create_query_set(type="timestamp", count=n)
            self.query_buf = device.create_buffer(
                size=8 * n, usage=wgpu.BufferUsage.QUERY_RESOLVE | wgpu.BufferUsage.COPY_SRC)
            self.query_readback = Readback(device, "timestamps readback")

    def _timestamps(self, i: int) -> dict | None:
        if not self.profile:
            return None
        return {"query_set": self.queries, "beginning_of_pass_write_index": 2 * i,
                "end_of_pass_write_index": 2 * i + 1}

    def _passes_with_hook(self, hook: Hook) -> None:
        """Each pass in its own render pass and submission, except that passes 5-7 stay together
        (they run body by body); the steps' own starts (clears, copies) stay where they are. Pass
        1 also writes its edges' depth bits into the colour target (channel b) for the hook to
        read, and the colour target is cleared again after it where the plan would not do so."""
        device = self.gpu.device
        raycast = self.raycast
        bind_group = raycast.bind_group(self.buffers, self.targets)
        for step in raycast.plan:
            chunks: list[tuple[int, ...]] = []
            for n in step.passes:
                if chunks and raycast.states[n].per_body and raycast.states[chunks[-1][-1]].per_body:
                    chunks[-1] += (n,)
                else:
                    chunks.append((n,))
            for k, chunk in enumerate(chunks):
                encoder = device.create_command_encoder()
                start = step if k == 0 else RenderStep(chunk, False, False)
                rp = RaycastPasses.begin_step(encoder, self.targets, start)
                raycast.record(rp, chunk, self.buffers, bind_group, capture=True)
                rp.end()
                device.queue.submit([encoder.finish()])
                hook(f"pass {chunk[-1]}")
                if chunk == (1,) and raycast.states[1].color_writes != "rba" \
                        and len(chunks) > 1:
                    encoder = device.create_command_encoder()
                    RaycastPasses.begin_step(encoder, self.targets,
                                             RenderStep((), False, True)).end()
                    device.queue.submit([encoder.finish()])

    def run(self, stats: Stats, hook: Hook | None = None) -> np.ndarray:
        """Run the passes, the filter and the readback mode's GPU work; returns the header
        (counters first) as uint32 words."""
        device = self.gpu.device
        encoder = device.create_command_encoder()
        steps = len(self.raycast.plan)
        if hook is None:
            self.raycast.encode(encoder, self.buffers, self.targets,
                                [self._timestamps(i) for i in range(steps)] if self.profile else None)
        else:
            self._passes_with_hook(hook)
        self.filter.encode(encoder, self.targets,
                           timestamp_writes=self._timestamps(steps) if hook is None else None)
        if hook is not None:
            device.queue.submit([encoder.finish()])
            hook("filter")
            encoder = device.create_command_encoder()
        staging = self.counters.ensure(self.readback.header_bytes + 64)
        header_bytes = self.readback.encode(encoder, self.filter, staging)
        if self.profile and hook is None:
            nq = 2 * len(self.stage_names)
            encoder.resolve_query_set(self.queries, 0, nq, self.query_buf, 0)
            encoder.copy_buffer_to_buffer(self.query_buf, 0, self.query_readback.ensure(8 * nq),
                                          0, 8 * nq)
        device.queue.submit([encoder.finish()])
        header = self.counters.read(header_bytes)
        stats.bytes_read += header_bytes
        if self.profile and hook is None:
            ts = self.query_readback.read(8 * len(self.stage_names) * 2, np.uint64)
            ts = ts.astype(np.float64)
            for i, name in enumerate(self.stage_names):
                stats.gpu_ms[name] = stats.gpu_ms.get(name, 0.0) + (ts[2 * i + 1] - ts[2 * i]) * 1e-6
        return header

    def read_records(self, header: np.ndarray, stats: Stats, view_index: int, encode: str,
                     edge_start: np.ndarray) -> np.ndarray | None:
        """The records of the frame, or None when nothing survived the filter."""
        survivors = int(header[0])
        stats.self_interference_pixels += int(header[1])
        stats.unidentified_pixels += int(header[2])
        if survivors == 0:
            return None
        source, nbytes = self.readback.source(self.filter, header, survivors, stats)
        device = self.gpu.device
        encoder = device.create_command_encoder()
        encoder.copy_buffer_to_buffer(source, 0, self.records.ensure(nbytes), 0, nbytes)
        device.queue.submit([encoder.finish()])
        data = self.records.read(nbytes)
        stats.bytes_read += nbytes
        return self.readback.decode(data, view_index, encode, edge_start)

"""The self-interference filter (paper 4.3.1.2) as a compute pass, with its two outputs.

``full`` writes the filtered image; ``compact`` appends the surviving records to a buffer through
an atomic counter, so that only the records are read back; ``packed`` writes the image in the
compact record layout, as level 0 of the mip-map reduction. All count what they blank.

WebGPU's occlusion queries count the samples of render passes; this filter is a compute pass, so
its atomic survivor counter plays the part of the paper's occlusion query (4.3.2.3): when it is 0,
nothing else is read back.
"""

from __future__ import annotations

import numpy as np
import wgpu

from ..gpu.buffers import GrowableBuffer, Targets
from ..gpu.device import Gpu, shader_source

COUNTERS_BYTES = 16
RECORD_BYTES = 16
WORKGROUP = 8


class FilterPass:
    """Filter self-interference and unidentified pixels; write the image or compact records.

    counters : (4,) uint32 buffer: survivors, self-interference blanked, unidentified blanked,
        overflow
    out : the filtered image ((H*W, 4) uint32) or the compact records ((K, 4) uint32)
    """

    ENTRY = {"full": "filter_full", "compact": "filter_compact", "packed": "filter_packed"}

    def __init__(self, gpu: Gpu, output: str) -> None:
        if output not in self.ENTRY:
            raise ValueError(f"unknown filter output {output!r}")
        self.gpu, self.output = gpu, output
        device = gpu.device
        module = device.create_shader_module(label="filter", code=shader_source("filter"))
        self.pipeline = device.create_compute_pipeline(
            label=f"filter ({output})", layout="auto",
            compute={"module": module, "entry_point": self.ENTRY[output]})
        usage = wgpu.BufferUsage
        self.counters = device.create_buffer(
            label="counters", size=COUNTERS_BYTES,
            usage=usage.STORAGE | usage.COPY_SRC | usage.COPY_DST)
        self.params = device.create_buffer(label="filter params", size=16,
                                           usage=usage.UNIFORM | usage.COPY_DST)
        self.out = GrowableBuffer(device, f"filtered ({output})",
                                  usage.STORAGE | usage.COPY_SRC)
        self._bind_group: wgpu.GPUBindGroup | None = None
        self._bind_key: tuple | None = None
        self._zeros = np.zeros(4, dtype=np.uint32)

    def _bind(self, targets: Targets) -> wgpu.GPUBindGroup:
        self.out.ensure(targets.pixels * RECORD_BYTES)
        key = (id(targets), self.out.generation)
        if key != self._bind_key:
            self.gpu.device.queue.write_buffer(
                self.params, 0, np.array([targets.width, targets.height, targets.pixels, 0],
                                         dtype=np.uint32))
            self._bind_group = self.gpu.device.create_bind_group(
                layout=self.pipeline.get_bind_group_layout(0),
                entries=[
                    {"binding": 0, "resource": targets.records_view},
                    {"binding": 1, "resource": {"buffer": self.counters}},
                    {"binding": 2, "resource": {"buffer": self.out.buffer}},
                    {"binding": 3, "resource": {"buffer": self.params}},
                ])
            self._bind_key = key
        return self._bind_group

    def encode(self, encoder: wgpu.GPUCommandEncoder, targets: Targets,
               timestamp_writes: dict | None = None) -> None:
        bind_group = self._bind(targets)
        self.gpu.device.queue.write_buffer(self.counters, 0, self._zeros)
        kwargs = {"timestamp_writes": timestamp_writes} if timestamp_writes else {}
        cpass = encoder.begin_compute_pass(**kwargs)
        cpass.set_pipeline(self.pipeline)
        cpass.set_bind_group(0, bind_group)
        cpass.dispatch_workgroups(-(-targets.width // WORKGROUP), -(-targets.height // WORKGROUP))
        cpass.end()

"""Pass 8 of the whole-scene strategy: the self-interference filter (paper 4.3.1.2) as a compute
pass, with its three outputs.

``full`` writes the filtered image; ``compact`` appends the surviving records to a buffer through
an atomic counter, so that only the records are read back; ``packed`` writes the image in the
compact record layout, as level 0 of the mip-map reduction. All count what they blank.

WebGPU's occlusion queries count the samples of render passes; this filter is a compute pass, so
its atomic survivor counter plays the part of the paper's occlusion query (4.3.2.3): when it is 0,
nothing else is read back.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np
import wgpu

from ..gpu.bindings import Stage
from ..gpu.buffers import GrowableBuffer, Targets
from ..gpu.device import Gpu
from ..gpu.structs import Struct
from ..gpu.table import PassInfo

if TYPE_CHECKING:
    from .encoding import SceneFrame

PARAMS = Struct("FilterParams", [
    ("width", "u32", "pixels per row of the records target"),
    ("height", "u32", "rows of the records target"),
    ("capacity", "u32", "records the compact output holds"),
], uniform=True, doc="The filter's parameters, written by the host once per resolution.")

COUNTERS = Struct("FilterCounters", [
    ("survivors", "u32", "records that survived the filter"),
    ("self_interference", "u32", "pixels blanked as self-interference (r == g)"),
    ("unidentified", "u32", "pixels blanked as unidentified (r != 0, g == 0)"),
    ("overflow", "u32", "survivors that did not fit the compact output (never: it holds all)"),
], doc="The filter's counters: atomics on the GPU, the first words of every readback.")
"""The filter's counters as the host reads them. WGSL counts them with atomics, which a struct
the host writes cannot hold: the shader sees ``array<atomic<u32>, COUNTER_WORDS>`` and the index
constants of :data:`COUNTER_INDEX`, generated from this declaration."""

COUNTERS_BYTES = COUNTERS.size
RECORD_BYTES = 16
"""Bytes of one record (a ``vec4u``)."""
WORKGROUP = 8
"""Side of the square workgroups of the filter and the reduction (``@workgroup_size(8, 8)``)."""

COUNTER_INDEX = {f"COUNT_{f.name.upper()}": COUNTERS.offset(f.name) // 4 for f in COUNTERS.fields}
"""WGSL constants: the index of each counter in the atomic array."""


def read_counters(header: np.ndarray) -> np.void:
    """The counters at the start of a readback's header ((words,) uint32), by name."""
    return header[:COUNTERS.size // 4].view(COUNTERS.dtype)[0]


class FilterPass:
    """Pass 8: filter self-interference and unidentified pixels; write the image or compact
    records.

    Parameters
    ----------
    gpu : Gpu
    output : {"full", "compact", "packed"}
        Which entry point of ``wholescene_filter.wgsl`` runs (what the readback mode reads).

    Attributes
    ----------
    counters : wgpu.GPUBuffer
        :data:`COUNTERS`, zeroed before every frame.
    out : GrowableBuffer
        The filtered image ((H*W, 4) uint32) or the compact records ((K, 4) uint32).
    """

    SHADER: ClassVar[str] = "wholescene_filter"
    """Its shader, ``shaders/wholescene_filter.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "8", "filter", "blank self-interference and unidentified pixels; count the survivors",
        when="every view")
    ENTRY: ClassVar[dict[str, str]] = {
        "full": "filter_full", "compact": "filter_compact", "packed": "filter_packed"}

    def __init__(self, gpu: Gpu, output: str) -> None:
        if output not in self.ENTRY:
            raise ValueError(f"unknown filter output {output!r}")
        self.gpu, self.output = gpu, output
        device = gpu.device
        consts = {**COUNTER_INDEX, "COUNTER_WORDS": COUNTERS.size // 4,
                  "WORKGROUP_SIDE": WORKGROUP}
        self.stage = Stage(gpu, self.SHADER, self.ENTRY[output], label=f"{self.INFO.title} "
                           f"({output})", structs=(PARAMS,), consts=consts)
        self.pipeline = self.stage.pipeline
        usage = wgpu.BufferUsage
        self.counters = device.create_buffer(
            label="counters", size=COUNTERS.size,
            usage=usage.STORAGE | usage.COPY_SRC | usage.COPY_DST)
        self.params = PARAMS.zeros()
        self.params_buffer = device.create_buffer(label="filter params", size=PARAMS.size,
                                                  usage=usage.UNIFORM | usage.COPY_DST)
        self.out = GrowableBuffer(device, f"filtered ({output})", usage.STORAGE | usage.COPY_SRC)
        self._params_for: Targets | None = None
        self._zeros = COUNTERS.zeros()

    def _bind(self, targets: Targets) -> wgpu.GPUBindGroup:
        self.out.ensure(targets.pixels * RECORD_BYTES)
        if targets is not self._params_for:
            self.params["width"], self.params["height"] = targets.width, targets.height
            self.params["capacity"] = targets.pixels
            self.gpu.device.queue.write_buffer(self.params_buffer, 0, self.params)
            self._params_for = targets
        return self.stage.group(records=targets.records_view, counters=self.counters,
                                out_records=self.out, params=self.params_buffer)

    def encode(self, frame: SceneFrame) -> None:
        """Zero the counters and filter the frame's records target."""
        targets = frame.targets
        bind_group = self._bind(targets)
        self.gpu.device.queue.write_buffer(self.counters, 0, self._zeros)
        cpass = frame.encoder.begin_compute_pass(label=self.INFO.title,
                                                 **frame.profiler.writes(self.INFO.title))
        cpass.set_pipeline(self.pipeline)
        cpass.set_bind_group(0, bind_group)
        cpass.dispatch_workgroups(-(-targets.width // WORKGROUP), -(-targets.height // WORKGROUP))
        cpass.end()


__all__ = ["COUNTERS", "COUNTERS_BYTES", "FilterPass", "PARAMS", "RECORD_BYTES", "WORKGROUP",
           "read_counters"]

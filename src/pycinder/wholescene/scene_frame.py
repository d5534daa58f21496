"""One frame of the whole-scene strategy through one view: the frame encoder that the strategy
and the debug capture share.

    passes 1-7 (grouped into render steps) -> pass 8, self-interference filter
    -> the readback mode's passes (pass 9, mip-map reduction) -> header (the filter's counters
    first; nothing else when nothing survived) -> records

The passes are objects (:class:`~pycinder.wholescene.raycast.RaycastPasses`,
:class:`~pycinder.wholescene.filter.FilterPass`, :class:`~pycinder.wholescene.reduce.MipReduce`),
each encoding itself onto a :class:`~pycinder.wholescene.encoding.SceneFrame`;
:class:`WholeSceneFrame` walks them in order and times them with the one
:class:`~pycinder.gpu.bindings.Profiler` that the focused strategy also uses. Normally each render
step replays a render bundle recorded once per topology, and everything goes in one submission, the
timestamps travelling with the header. With a hook, every pass gets its own render pass and
submission and the hook runs after each, so the debug capture can read the depth, stencil and
colour buffers between passes (the paper's Figures 9 to 13).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import wgpu

from ..gpu.bindings import Profiler
from ..gpu.buffers import Readback, SceneBuffers, Targets
from ..gpu.device import Gpu
from ..gpu.table import PassInfo
from ..result import Stats
from .encoding import SceneFrame
from .filter import FilterPass, read_counters
from .raycast import RaycastPasses
from .readback import ReadbackMode
from .reduce import MipReduce

Hook = Callable[[str], None]
"""Called with ``"pass N"`` after pass N (``"pass 7"`` after passes 5-7, which run body by body)
and with ``"filter"`` after the filter."""


PASS_INFOS: tuple[PassInfo, ...] = (*RaycastPasses.INFOS, FilterPass.INFO, MipReduce.INFO)
"""The whole-scene strategy's passes in the order they run (the pass table is generated from
them): Appendix A's passes 1-7, the self-interference filter, the mip-map reduction."""


class WholeSceneFrame:
    """Runs passes 1-9 and the readback of one view of the whole-scene strategy.

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
        Time each render step, the filter and the readback mode's passes.
    """

    def __init__(self, gpu: Gpu, raycast: RaycastPasses, filter_pass: FilterPass,
                 readback: ReadbackMode, targets: Targets, buffers: SceneBuffers,
                 profile: bool = False) -> None:
        self.gpu, self.raycast, self.filter, self.readback = gpu, raycast, filter_pass, readback
        self.targets, self.buffers = targets, buffers
        self.counters = Readback(gpu.device, "counters readback")
        self.records = Readback(gpu.device, "records readback")
        self.profiler = Profiler(gpu, profile)
        self._untimed = Profiler(gpu, False)

    @property
    def passes(self) -> tuple:
        """The passes of a frame after passes 1-7, in order: the filter, then the readback
        mode's."""
        return (self.filter, *self.readback.passes)

    def run(self, stats: Stats, hook: Hook | None = None) -> np.ndarray:
        """Run the passes and the copy of the header; returns the header (the filter's counters
        first) as uint32 words, and adds the passes' GPU times to ``stats.gpu_ms`` when
        profiling."""
        device = self.gpu.device
        profiler = self.profiler if hook is None else self._untimed
        profiler.begin(len(self.raycast.plan) + len(self.passes))
        encoder = device.create_command_encoder()
        if hook is None:
            self.raycast.encode(self._frame(encoder, profiler))
        else:
            self.raycast.encode_each(device, self.buffers, self.targets, hook)
        for k, stage in enumerate(self.passes):
            stage.encode(self._frame(encoder, profiler))
            if hook is not None and k == 0:
                device.queue.submit([encoder.finish()])
                hook("filter")
                encoder = device.create_command_encoder()
        header_bytes = self.readback.header_bytes
        staging = self.counters.ensure(header_bytes + profiler.nbytes)
        self.readback.copy_header(encoder, self.filter, staging)
        profiler.resolve(encoder, staging, header_bytes)
        device.queue.submit([encoder.finish()])
        words = self.counters.read(header_bytes + profiler.nbytes)
        stats.bytes_read += header_bytes
        for name, ms in profiler.times(words[header_bytes // 4:]).items():
            stats.gpu_ms[name] = stats.gpu_ms.get(name, 0.0) + ms
        return words[:header_bytes // 4]

    def _frame(self, encoder: wgpu.GPUCommandEncoder, profiler: Profiler) -> SceneFrame:
        return SceneFrame(encoder, profiler, self.targets, self.buffers, self.filter.out)

    def read_records(self, header: np.ndarray, stats: Stats, view_index: int, encode: str,
                     edge_start: np.ndarray) -> np.ndarray | None:
        """The records of the frame (a structured array, see :mod:`pycinder.records`), or None
        when nothing survived the filter."""
        counters = read_counters(header)
        survivors = int(counters["survivors"])
        stats.self_interference_pixels += int(counters["self_interference"])
        stats.unidentified_pixels += int(counters["unidentified"])
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


__all__ = ["PASS_INFOS", "Hook", "SceneFrame", "WholeSceneFrame"]

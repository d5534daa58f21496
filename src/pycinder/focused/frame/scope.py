"""Compute passes of a frame, shared by consecutive dispatches."""

from __future__ import annotations

import wgpu

from ...gpu.bindings import Profiler


class ComputeScope:
    """Compute dispatches of a round. Consecutive dispatches share one compute pass (each
    dispatch is its own usage scope, so later ones see earlier ones' writes, indirect arguments
    included), saving a pass's fixed cost; when profiling, each pass gets its own timed one.

    Parameters
    ----------
    encoder : wgpu.GPUCommandEncoder
    profiler : Profiler
    label : str
        Added to each compute pass's label ("round 2").
    """

    def __init__(self, encoder: wgpu.GPUCommandEncoder, profiler: Profiler, label: str) -> None:
        self.encoder, self.profiler, self.label = encoder, profiler, label
        self.current: wgpu.GPUComputePassEncoder | None = None

    def begin(self, name: str) -> wgpu.GPUComputePassEncoder:
        """The compute pass in which pass ``name``'s dispatches are recorded."""
        if self.current is not None and not self.profiler.enabled:
            return self.current
        self.end()
        self.current = self.encoder.begin_compute_pass(label=f"{name}, {self.label}",
                                                       **self.profiler.writes(name))
        return self.current

    def end(self) -> None:
        """End the open compute pass (before a render pass, or at the end of the round)."""
        if self.current is not None:
            self.current.end()
            self.current = None


__all__ = ["ComputeScope"]

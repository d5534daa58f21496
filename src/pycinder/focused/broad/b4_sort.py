"""Passes B4 and B5 of the broad phase (``shaders/broad_sort.wgsl``): a bitonic sort of the
sort elements, as one workgroup-local dispatch for blocks of
:data:`~pycinder.focused.broad.broad_common.SORT_BLOCK`, then per merge the steps of
:data:`~pycinder.focused.broad.broad_common.SORT_BLOCK` and over globally and the rest locally (45
dispatches for 100,000 bodies)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np
import wgpu

from ...gpu.bindings import PARAM_STRIDE, dispatch
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .broad_common import PARAMS, SORT_BLOCK, SORT_THREADS, BroadBuffers, BroadFrame, BroadPass

SORT_STEP = Struct("SortStep", [
    ("k", "u32", "merge size (B4: the first merge size)"),
    ("j", "u32", "compare distance (B4: the last merge size)"),
], uniform=True, doc="One dispatch of the sort, in its own parameter block.")

_STEP_BINDING = (SORT_STEP.size + 15) // 16 * 16


def sort_steps(count: int) -> list[tuple[str, int, int]]:
    """The bitonic sort of ``count`` elements (a power of two, at least :data:`SORT_BLOCK`) as
    dispatches: ``("local", k0, k1)`` sorts merges ``k0..k1`` within blocks (their steps below
    :data:`SORT_BLOCK`), ``("step", k, j)`` is one global compare-exchange step."""
    steps = [("local", 2, SORT_BLOCK)]
    k = 2 * SORT_BLOCK
    while k <= count:
        j = k // 2
        while j >= SORT_BLOCK:
            steps.append(("step", k, j))
            j //= 2
        steps.append(("local", k, k))
        k *= 2
    return steps


def step_blocks(steps: Sequence[tuple[str, int, int]]) -> np.ndarray:
    """The sort's :data:`SORT_STEP` blocks, one per dispatch, :data:`PARAM_STRIDE` bytes
    apart: (len(steps),) structured."""
    blocks = SORT_STEP.zeros(len(steps), stride=PARAM_STRIDE)
    blocks["k"] = [k for _, k, _ in steps]
    blocks["j"] = [j for _, _, j in steps]
    return blocks


class _SortPass(BroadPass):
    SHADER = "broad_sort"
    STRUCTS: ClassVar[tuple[Struct, ...]] = (PARAMS, SORT_STEP)

    def encode(self, cpass: wgpu.GPUComputePassEncoder, buffers: BroadBuffers,
               frame: BroadFrame, step: int) -> None:
        """Dispatch ``frame.steps[step]`` (its :data:`SORT_STEP` is block ``step``)."""
        block = (buffers.steps.buffer, step * PARAM_STRIDE, _STEP_BINDING)
        group = self.stage.group(f"step {step}", params=buffers.params_binding, step=block,
                                 elements=buffers.elements)
        dispatch(cpass, self.stage, group, self.workgroups(frame))

    def workgroups(self, frame: BroadFrame) -> int:
        raise NotImplementedError


class LocalSort(_SortPass):
    """B4: one workgroup per block of :data:`SORT_BLOCK` elements sorts, in workgroup memory,
    the merges ``k`` to ``j`` of its block (every step of each below :data:`SORT_BLOCK`): the
    whole network up to blocks of :data:`SORT_BLOCK` first, then the end of every merge."""

    INFO = PassInfo("B4", "local sort", "bitonic merges within blocks of 512 elements, in "
                    "workgroup memory", when="once, then per merge")
    ENTRY = "sort_local"

    def workgroups(self, frame: BroadFrame) -> int:
        return frame.count // SORT_BLOCK


class MergeStep(_SortPass):
    """B5: one compare-exchange per thread, step ``j`` of merge ``k`` across the whole array,
    for ``j`` of :data:`SORT_BLOCK` and over."""

    INFO = PassInfo("B5", "merge step", "one global compare-exchange step of a bitonic merge",
                    when="per merge over 512, per step of 512 and over")
    ENTRY = "sort_step"

    def workgroups(self, frame: BroadFrame) -> int:
        return frame.count // 2 // SORT_THREADS


__all__ = ["LocalSort", "MergeStep", "SORT_STEP", "sort_steps", "step_blocks"]

"""The GPU broad phase: its passes (B1-B8) encoded in order, in one submission, and the pairs
read back (see :mod:`pycinder.focused.broad`)."""

from __future__ import annotations

import time

from dataclasses import dataclass

import numpy as np
import wgpu

from ...gpu.bindings import PARAM_STRIDE
from ...gpu.buffers import DEFAULT_TIMEOUT, Readback
from ...gpu import native
from ...gpu.device import Gpu, get_gpu
from .b1_boxes import Columns, GridSetup, WorldBoxes
from .broad_common import (COUNTS, FIRST_PAIRS, GRID, ORIGIN_PAD_SCALE, PARAMS, PARAMS_BINDING,
    READBACK, SORT_BLOCK, BroadBuffers, BroadFrame)
from .broad_gpu_host import checked, finish_sweeps, packed, ranks
from .b4_sort import LocalSort, MergeStep, sort_steps, step_blocks
from .b6_sweep import Gather, Sweep, WideSweep

_SETUP_FIELDS = ("cell_size", "wide_from", "wide_count")
"""The grid's set-up, as :data:`READBACK` ends with it (contiguous in both)."""


@dataclass
class BroadPhaseStats:
    """What the last call of :meth:`GpuBroadPhase.pairs` did.

    Attributes
    ----------
    pairs : int
        Pairs found.
    submissions, maps : int
        Command buffers submitted and staging buffers mapped (1 and 1 in the common case).
    reruns : int
        Sweeps run again because the pairs buffer had to grow.
    waited_ms : float
        Milliseconds the host waited for the GPU (the passes and the maps).
    bytes_read : int
    axis : int
        The sweep axis.
    cell_size : tuple of float
        Size of the grid's cells on the two other axes (the next two after ``axis``).
    wide_bodies : int
        Bodies kept out of the grid for their width (each tested against every other).
    unfinished : int
        Bodies whose sweep ran out of its budget of steps and was finished on the host.
    """

    pairs: int = 0
    submissions: int = 0
    maps: int = 0
    reruns: int = 0
    bytes_read: int = 0
    axis: int = 0
    cell_size: tuple[float, float] = (0.0, 0.0)
    wide_bodies: int = 0
    unfinished: int = 0
    waited_ms: float = 0.0


class GpuBroadPhase:
    """Candidate pairs of bodies whose world boxes overlap, found on the GPU.

    Pipelines (one object per pass: :attr:`passes`) and buffers (:attr:`buffers`) are made once;
    buffers grow when a call needs more and are reused.

    Parameters
    ----------
    gpu : Gpu, optional
        The device (default: pycinder's).
    timeout : float
        Seconds a call may wait for the GPU.
    """

    def __init__(self, gpu: Gpu | None = None, *, timeout: float = DEFAULT_TIMEOUT) -> None:
        self.gpu = gpu = gpu or get_gpu()
        self.timeout = float(timeout)
        self.world_boxes, self.grid_setup, self.columns = (WorldBoxes(gpu), GridSetup(gpu),
                                                           Columns(gpu))
        self.local_sort, self.merge_step = LocalSort(gpu), MergeStep(gpu)
        self.gather, self.sweep, self.wide_sweep = Gather(gpu), Sweep(gpu), WideSweep(gpu)
        self.passes = (self.world_boxes, self.grid_setup, self.columns, self.local_sort,
                       self.merge_step, self.gather, self.sweep, self.wide_sweep)
        """The passes, in the order of their numbers (B1-B8)."""
        self.buffers = BroadBuffers.create(gpu.device)
        self.readback = Readback(gpu.device, "broad phase readback")
        self.readback_more = Readback(gpu.device, "broad phase pairs")
        self.params = PARAMS.zeros()
        """The frame's parameters (host copy)."""
        self.capacity = FIRST_PAIRS
        """Pairs the pairs buffer holds (grown when a call finds more)."""
        self.recent = 0
        """Pairs the last call found (the next call's first readback copies a quarter more)."""
        self.sorted_count = 0
        """Sort elements whose sort steps the steps buffer holds."""
        self.stats = BroadPhaseStats()

    def pairs(self, local_lo: np.ndarray, local_hi: np.ndarray, radius: np.ndarray,
              transforms: np.ndarray, within: np.ndarray | None = None,
              groups: np.ndarray | None = None) -> np.ndarray:
        """The pairs of bodies whose world boxes overlap (touching counts).

        Parameters
        ----------
        local_lo, local_hi : (N, 3) float
            Body-space bounding boxes.
        radius : (N,) float
            Radius of each body's bounding sphere about the centre of its box.
        transforms : (N, 4, 4) float
            World-from-body matrices.
        within : (N,) int, optional
            Only pairs of bodies with the same key (the scenes of a batch).
        groups : (N,) int, optional
            Only pairs of bodies in different groups.

        Returns
        -------
        (K, 2) int64
            Pairs ``(i, j)`` with ``i < j``, sorted: those of
            :func:`~pycinder.focused.broad.broad_gpu_host.reference_pairs`, and pairs whose boxes
            are within the padding (see :mod:`pycinder.focused.broad`).

        Raises
        ------
        ValueError
            Inputs of the wrong shape, not finite, beyond
            :data:`~pycinder.focused.broad.broad_common.COORDINATE_LIMIT`, an empty local box or a
            negative radius (naming the body).
        GpuMemoryError
            More pairs (or bodies) than one buffer of this device holds.
        GpuTimeoutError
            The GPU did not finish within ``timeout``.
        """
        lo, hi, r, t = checked(local_lo, local_hi, radius, transforms)
        n = len(r)
        within_keys, group_keys = ranks(within, "within", n), ranks(groups, "groups", n)
        if n < 2:
            self.stats = BroadPhaseStats()
            return np.zeros((0, 2), dtype=np.int64)
        bodies, axis, origin = packed(lo, hi, r, t, within_keys, group_keys)
        count = max(SORT_BLOCK, 1 << (n - 1).bit_length())
        frame = BroadFrame(n=n, count=count, steps=tuple(sort_steps(count)))
        p = self.params
        p["n"], p["count"], p["axis"] = n, count, axis
        p["use_groups"] = groups is not None
        p["base_pad"] = ORIGIN_PAD_SCALE * float(np.abs(origin).max())
        with self.gpu.lock:  # the device, and this object's buffers and stats
            self.stats = BroadPhaseStats(axis=axis)
            found = self._run(frame, bodies)
            key = found[:, 0].astype(np.int64) * n + found[:, 1]
            if self.stats.unfinished:
                key = np.unique(key)  # the host's pairs of unfinished sweeps repeat some
            else:
                key.sort()
            self.stats.pairs = len(key)
        return np.stack(np.divmod(key, n), axis=1)

    # -- GPU work -------------------------------------------------------------------------------

    def _upload(self, frame: BroadFrame, bodies: np.ndarray) -> None:
        """Grow the buffers to the frame and write its parameters and bodies."""
        b, n = self.buffers, frame.n
        self.params["capacity"] = self.capacity
        b.params.ensure(PARAMS_BINDING)
        b.params.write(self.params)
        if b.steps.ensure(PARAM_STRIDE * len(frame.steps)) or frame.count != self.sorted_count:
            b.steps.write(step_blocks(frame.steps))  # the same for every frame of one count
            self.sorted_count = frame.count
        b.bodies.ensure(bodies.nbytes)
        b.bodies.write(bodies)
        for buf in (b.boxes_lo, b.boxes_hi, b.sorted_lo, b.sorted_hi):
            buf.ensure(16 * n)
        b.sorted_body.ensure(4 * n)
        b.unfinished.ensure(4 * n)
        b.elements.ensure(16 * frame.count)
        b.pairs.ensure(8 * self.capacity)

    def _encode(self, frame: BroadFrame, sweep_only: bool = False) -> wgpu.GPUCommandEncoder:
        """A command encoder with every pass of the frame in order (B1-B8; with ``sweep_only``,
        B7 and B8 alone, over the boxes a previous submission sorted)."""
        b = self.buffers
        encoder = native.encoder(self.gpu.device, "broad phase")
        encoder.clear_buffer(b.counts)
        if not sweep_only:
            encoder.clear_buffer(b.grid)
        cpass = encoder.begin_compute_pass(label="broad phase")
        if not sweep_only:
            self.world_boxes.encode(cpass, b, frame)
            self.grid_setup.encode(cpass, b, frame)
            self.columns.encode(cpass, b, frame)
            for s, (kind, _, _) in enumerate(frame.steps):
                sort = self.local_sort if kind == "local" else self.merge_step
                sort.encode(cpass, b, frame, s)
            self.gather.encode(cpass, b, frame)
        self.sweep.encode(cpass, b, frame)
        self.wide_sweep.encode(cpass, b, frame)
        cpass.end()
        return encoder

    def _run(self, frame: BroadFrame, bodies: np.ndarray) -> np.ndarray:
        """Encode every pass, submit, read the pairs (sweeping again while the pairs buffer
        overflows). Returns (K, 2) uint32 bodies, with repeats where sweeps were unfinished."""
        self._upload(frame, bodies)
        encoder = self._encode(frame)
        first = min(max(FIRST_PAIRS, self.recent * 5 // 4), self.capacity)
        while True:
            found, pairs = self._read(encoder, first, frame.n)
            if pairs is not None:
                break
            # More pairs than the buffer holds: grow it and sweep again (the sorted boxes are
            # still on the GPU), reading all of them this time.
            self.stats.reruns += 1
            self.capacity = found + found // 4 + FIRST_PAIRS
            self.buffers.pairs.ensure(8 * self.capacity)
            self.params["capacity"] = self.capacity
            self.buffers.params.write(self.params)
            encoder = self._encode(frame, sweep_only=True)
            first = found
        self.recent = found
        return pairs

    def _submit_copies(self, encoder: wgpu.GPUCommandEncoder | None, staging: Readback,
                       parts: list[tuple[wgpu.GPUBuffer, int, int]], waiting: str) -> np.ndarray:
        """Copy ``(buffer, offset, nbytes)`` parts one after the other into ``staging``, submit
        (``encoder``, or a new one) and map them; returns the words (uint32)."""
        encoder = encoder or native.encoder(self.gpu.device, "broad phase readback")
        nbytes = sum(size for _, _, size in parts)
        target, at = staging.ensure(nbytes), 0
        for buf, offset, size in parts:
            if size:
                encoder.copy_buffer_to_buffer(buf, offset, target, at, size)
            at += size
        self.gpu.device.queue.submit([encoder.finish()])
        t0 = time.perf_counter()
        data = staging.read(nbytes, timeout=self.timeout, waiting_for=waiting)
        self.stats.waited_ms += (time.perf_counter() - t0) * 1e3
        self.stats.submissions += 1
        self.stats.maps += 1
        self.stats.bytes_read += nbytes
        return data

    def _read(self, encoder: wgpu.GPUCommandEncoder, first: int,
              n: int) -> tuple[int, np.ndarray | None]:
        """Copy the counts, the grid's set-up and the first ``first`` pairs, submit ``encoder``
        and map them; read the rest (when the buffer held them) with a second copy. Returns the
        pair count and the pairs, (count, 2) uint32 (None when the buffer did not hold them)."""
        b, waiting = self.buffers, f"the broad phase of {n} bodies"
        setup = GRID.offset(_SETUP_FIELDS[0])
        assert READBACK.offset(_SETUP_FIELDS[0]) == COUNTS.size
        data = self._submit_copies(encoder, self.readback, [
            (b.counts, 0, COUNTS.size), (b.grid, setup, READBACK.size - COUNTS.size),
            (b.pairs.buffer, 0, 8 * first)], waiting)
        head = data[:READBACK.size // 4].view(READBACK.dtype)[0]
        if head["wide_overflow"]:
            raise RuntimeError(f"the broad phase listed {int(head['wide_listed'])} wide bodies, "
                               f"more than the {int(head['wide_count'])} it counted")
        count, unfinished = int(head["pairs"]), int(head["unfinished"])
        self.stats.cell_size = tuple(float(x) for x in head["cell_size"])
        self.stats.wide_bodies = int(head["wide_count"])
        self.stats.unfinished = unfinished
        if count > self.capacity:
            return count, None  # the caller grows the buffer
        start = READBACK.size // 4
        pairs = data[start:start + 2 * min(count, first)].reshape(-1, 2)
        if count > first:
            rest = count - first
            more = self._submit_copies(None, self.readback_more,
                                       [(b.pairs.buffer, 8 * first, 8 * rest)],
                                       f"{rest} pairs of {waiting}")
            pairs = np.concatenate([pairs, more.reshape(-1, 2)])
        if unfinished:
            pairs = np.concatenate([pairs, self._finish(unfinished, n, waiting)])
        return count, pairs

    def _finish(self, unfinished: int, n: int, waiting: str) -> np.ndarray:
        """The pairs of the boxes whose sweep ran out of its budget, found on the host from the
        GPU's boxes (all of each box's pairs: duplicates of those the GPU found are removed
        later). Returns (K, 2) uint32 bodies."""
        b = self.buffers
        data = self._submit_copies(None, self.readback_more, [
            (b.unfinished.buffer, 0, 4 * unfinished), (b.sorted_lo.buffer, 0, 16 * n),
            (b.sorted_hi.buffer, 0, 16 * n), (b.sorted_body.buffer, 0, 4 * n)],
            f"the boxes of {waiting}")
        which, lo, hi, body = np.split(data, np.cumsum([unfinished, 4 * n, 4 * n]))
        return finish_sweeps(which.astype(np.int64), lo.view(np.float32).reshape(n, 4),
                             hi.view(np.float32).reshape(n, 4), body,
                             bool(self.params["use_groups"]))


__all__ = ["BroadPhaseStats", "GpuBroadPhase"]

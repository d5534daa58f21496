"""The broad phase on the GPU: world boxes, a bitonic sort and a sweep, in one submission.

The GPU equivalent of :func:`pycinder.broadphase.world_boxes` followed by
:func:`pycinder.broadphase.sweep_and_prune` (and the focused strategy's filter to pairs of bodies in
different groups). Its passes (``shaders/broadphase.wgsl``), all in one command buffer:

    world boxes   one thread per body: the box, in float32, grown to be conservative; the range
                  of centres along each axis and a histogram of widths across the sweep axis
                  (atomics, reduced per workgroup first)
    grid set-up   one thread: the widest boxes (at most 32) are "wide"; the grid's cells across
                  the sweep axis are 1/16 wider than the widest of the others
    columns       one thread per body: its sort element (within key, column, start on the sweep
                  axis, body); the column is the grid cell holding the box's centre, or a column
                  of its own (last) for wide boxes
    sort          bitonic sort of the elements: one workgroup-local dispatch for blocks of 512,
                  then per merge the steps of 512 and over globally and the rest locally (45
                  dispatches for 100k bodies)
    gather        the boxes in sorted order; the list of wide boxes
    sweep         one thread per sorted box that is not wide: in its own and the 8 neighbouring
                  columns (a binary search each), the boxes after it in (start, body) order that
                  start before it ends and have its within key are tested on all axes and groups;
                  pairs are appended through an atomic counter
    wide boxes    one thread per sorted box: tested against every wide box of its within key

Boxes that are not wide and overlap have centres at most the widest of them apart, so they lie in
the same or neighbouring columns; of each such pair, the box that starts first finds the other, so
every pair is found once. A sweep along the whole axis would test, in a dense 3D scene, every box
against the O(N^(2/3)) boxes beside it along the axis; within columns it tests a few. Keeping the
widest boxes out of the grid keeps one floor (or a few) from making the cells as wide as the
scene.

llvmpipe (lavapipe, and Mesa's OpenGL on the CPU) silently stops an invocation's loops after 65535
steps in all. No pass loops that long: the wide boxes are tested by one thread per box rather
than one per wide box, and a sweep that meets more than 4096 boxes stops, is listed, and is
finished on the host from the GPU's boxes (a second round trip).

One readback maps the pair count and the first pairs (as many as the last call found, and a
quarter more). More pairs are read by a second copy; more pairs than the pairs buffer holds make it
grow and the sweep run again, so nothing is dropped. The sweep axis is the one along which the
bodies' translations spread most (computed on the host; any axis gives the same pairs).

Conservative boxes
------------------
The boxes are computed in float32 from the transforms less a common origin (the midpoint of the
translations' range, subtracted in float64), so that far-off scenes (1e6 from the origin) keep their
precision. Along world axis ``k`` of body ``i``, with ``m`` the linear part and ``t`` the
translation less the origin, every bound is moved outward by

    pad[i, k] = 2**-19 * (|t[k]| + sum_j |m[k, j]| * (max(|lo_j|, |hi_j|) + radius))
                + 2**-40 * max(|origin|)

The first term is about twice the worst rounding error of the float32 evaluation (input rounding,
the products and sums of a row, and WGSL's ``sqrt``, which may be off by several ulps), all
bounded by the row's sum of magnitudes; the second covers the float64 reference's own rounding at
the origin's magnitude. So every pair the float64 reference finds is found. A pair the reference
does not find may be reported when its boxes are apart by at most ``2 * (pad[a] + pad[b])`` along
every axis (the padding, and the rounding it covers): about 8e-6 of the bodies' coordinates
measured from the origin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import wgpu

from ..broadphase import sweep_and_prune, world_boxes
from ..gpu.buffers import DEFAULT_TIMEOUT, GrowableBuffer, Readback
from ..gpu.device import Gpu, get_gpu
from ..layout import ROW, WORKGROUP
from .bindings import Stage

PAD_SCALE = 2.0 ** -19
"""Padding per unit of a row's sum of magnitudes (``PAD_SCALE`` in ``broadphase.wgsl``)."""
ORIGIN_PAD_SCALE = 2.0 ** -40
"""Padding per unit of the origin's largest coordinate (the float64 reference's rounding)."""
SORT_THREADS = 256
SORT_BLOCK = 512
"""Sort elements per workgroup of the local sort (``broadphase.wgsl``)."""
PARAM_STRIDE = 256
"""Bytes between uniform blocks (the uniform offset alignment)."""
BODY_WORDS = 24
"""32-bit words of one ``Body`` (``broadphase.wgsl``)."""
FIRST_PAIRS = 4096
"""Fewest pairs the pairs buffer holds and the first readback copies."""
GRID_WORDS = 304
"""Words of the grid buffer: centre ranges, the grid's set-up, the width histogram
(``broadphase.wgsl``)."""
GRID_SETUP = 12
"""Word of the grid buffer where the set-up starts (cell sizes, wide threshold, wide count)."""
COORDINATE_LIMIT = 1e18
"""Largest box, radius or transform entry (translations from the scene's centre): their float32
products stay far from overflow."""
HOST_CHUNK = 1 << 22
"""Box tests per NumPy step when the host finishes unfinished sweeps."""
MAX_KEY = 0xFFFFFFFE
"""Largest within key or group rank (0xFFFFFFFF marks the sort's padding)."""

_U = wgpu.BufferUsage


def _grid(workgroups: int) -> tuple[int, int]:
    """Workgroup grid (x, y) for ``workgroups`` laid out in rows of :data:`ROW`."""
    return min(workgroups, ROW), -(-workgroups // ROW)


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


def reference_pairs(local_lo: np.ndarray, local_hi: np.ndarray, radius: np.ndarray,
                    transforms: np.ndarray, within: np.ndarray | None = None,
                    groups: np.ndarray | None = None) -> np.ndarray:
    """The NumPy broad phase that :class:`GpuBroadPhase` reproduces (same arguments): world
    boxes, sweep and prune, then the pairs of different groups.

    Returns
    -------
    (K, 2) int64
        Sorted pairs ``(i, j)``, ``i < j``.
    """
    lo, hi = world_boxes(local_lo, local_hi, radius, transforms)
    return sweep_and_prune(lo, hi, within, groups)


def in_range(local_lo: np.ndarray, local_hi: np.ndarray, radius: np.ndarray,
             transforms: np.ndarray) -> bool:
    """Whether :meth:`GpuBroadPhase.pairs` takes these bodies: every box, radius and transform
    entry (translations from the scene's centre) within :data:`COORDINATE_LIMIT`. (The rest of
    pycinder takes bodies up to 1e30 units; the NumPy broad phase serves those.)"""
    translation = transforms[:, :3, 3]
    origin = 0.5 * (translation.min(axis=0) + translation.max(axis=0))
    largest = max(float(np.abs(transforms[:, :3, :3]).max(initial=0.0)),
                  float(np.abs(translation - origin).max(initial=0.0)),
                  float(np.abs(local_lo).max(initial=0.0)), float(np.abs(local_hi).max(initial=0.0)),
                  float(np.abs(radius).max(initial=0.0)))
    return largest <= COORDINATE_LIMIT


def _ranks(keys: np.ndarray | None, name: str, n: int) -> np.ndarray:
    """Integer keys as uint32 ranks that keep equality (0 where none are given)."""
    if keys is None:
        return np.zeros(n, dtype=np.uint32)
    k = np.asarray(keys)
    if k.shape != (n,) or not (np.issubdtype(k.dtype, np.integer) or k.dtype == bool):
        raise ValueError(f"{name} must be ({n},) integers, one per body; got {k.dtype} "
                         f"{k.shape}")
    if n == 0:
        return np.zeros(0, dtype=np.uint32)
    k = k.astype(np.int64)
    low = int(k.min())
    if int(k.max()) - low <= MAX_KEY:
        return (k - low).astype(np.uint32)
    return np.unique(k, return_inverse=True)[1].reshape(-1).astype(np.uint32)


def _checked(local_lo: np.ndarray, local_hi: np.ndarray, radius: np.ndarray,
             transforms: np.ndarray) -> tuple[np.ndarray, ...]:
    """The inputs as float64 arrays of agreeing shapes; a clear error naming the first bad body
    otherwise (values that are not finite are looked for by :func:`_packed`)."""
    lo = np.asarray(local_lo, dtype=np.float64)
    hi = np.asarray(local_hi, dtype=np.float64)
    r = np.asarray(radius, dtype=np.float64)
    t = np.asarray(transforms, dtype=np.float64)
    n = len(r) if r.ndim == 1 else -1
    for name, a, shape in (("radius", r, (n,)), ("local_lo", lo, (n, 3)),
                           ("local_hi", hi, (n, 3)), ("transforms", t, (n, 4, 4))):
        if n < 0 or a.shape != shape:
            raise ValueError(f"{name} must have shape {shape if n >= 0 else '(N,)'}, got "
                             f"{a.shape}")
    negative = r < 0
    if negative.any():
        raise ValueError(f"radius of body {int(np.flatnonzero(negative)[0])} is negative")
    empty = (lo > hi).any(axis=1)
    if empty.any():
        raise ValueError(f"local box of body {int(np.flatnonzero(empty)[0])} is empty "
                         "(local_lo above local_hi)")
    return lo, hi, r, t


def _packed(lo: np.ndarray, hi: np.ndarray, r: np.ndarray, t: np.ndarray,
            within_keys: np.ndarray, group_keys: np.ndarray) -> tuple[np.ndarray, int, np.ndarray]:
    """The bodies as ``broadphase.wgsl`` reads them, the sweep axis and the origin.

    Returns
    -------
    words : (N, BODY_WORDS) float32
        Transform rows (translation less the origin, subtracted in float64), local box, radius,
        keys (as uint32 bits).
    axis : int
        The axis along which the translations spread most.
    origin : (3,) float64
        The midpoint of the translations' range.
    """
    n = len(r)
    translation = t[:, :3, 3].copy()
    origin = 0.5 * (translation.min(axis=0) + translation.max(axis=0))
    words = np.zeros((n, BODY_WORDS), dtype=np.float32)
    words[:, :12] = t[:, :3, :].reshape(n, 12)
    words[:, 3:12:4] = translation - origin
    words[:, 12:15], words[:, 15] = lo, r
    words[:, 16:19] = hi
    keys = words[:, 20:22].view(np.uint32)
    keys[:, 0], keys[:, 1] = within_keys, group_keys
    bad = ~(np.abs(words[:, :19]) <= COORDINATE_LIMIT).all(axis=1)  # NaN too
    if bad.any():
        for name, a in (("transforms", t), ("local_lo", lo), ("local_hi", hi), ("radius", r)):
            finite = np.isfinite(a).reshape(n, -1).all(axis=1)
            if not finite.all():
                raise ValueError(f"{name} of body {int(np.flatnonzero(~finite)[0])} is not "
                                 "finite")
        raise ValueError(f"box or transform of body {int(np.flatnonzero(bad)[0])} has "
                         f"coordinates beyond {COORDINATE_LIMIT:g} (from the scene's centre): "
                         "too large for the float32 broad phase")
    axis = int(np.argmax(translation.var(axis=0)))
    return words, axis, origin


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


class GpuBroadPhase:
    """Candidate pairs of bodies whose world boxes overlap, found on the GPU.

    Pipelines and buffers are made once; buffers grow when a call needs more and are reused.

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
        device = gpu.device
        self.world = Stage(gpu, "broadphase", "world_boxes", label="broad phase: world boxes")
        self.grid_setup = Stage(gpu, "broadphase", "grid_setup", label="broad phase: grid")
        self.columns = Stage(gpu, "broadphase", "columns", label="broad phase: columns")
        self.sort_local = Stage(gpu, "broadphase", "sort_local", label="broad phase: local sort")
        self.sort_step = Stage(gpu, "broadphase", "sort_step", label="broad phase: sort step")
        self.gather = Stage(gpu, "broadphase", "gather", label="broad phase: gather")
        self.sweep = Stage(gpu, "broadphase", "sweep", label="broad phase: sweep")
        self.wide_sweep = Stage(gpu, "broadphase", "wide_sweep", label="broad phase: wide boxes")

        def grow(label: str, usage: int = _U.STORAGE) -> GrowableBuffer:
            return GrowableBuffer(device, label, usage)

        self.params = grow("broad phase parameters", _U.UNIFORM | _U.COPY_DST)
        self.bodies = grow("broad phase bodies", _U.STORAGE | _U.COPY_DST)
        self.boxes_lo, self.boxes_hi = grow("world box minima"), grow("world box maxima")
        self.elements = grow("sort elements")
        readable = _U.STORAGE | _U.COPY_SRC
        self.sorted_lo = grow("sorted minima", readable)
        self.sorted_hi = grow("sorted maxima", readable)
        self.sorted_body = grow("sorted bodies", readable)
        self.unfinished = grow("unfinished sweeps", readable)
        self.pairs_buffer = grow("candidate pairs", _U.STORAGE | _U.COPY_SRC)
        self.counter = device.create_buffer(label="pair counter", size=16,
                                            usage=_U.STORAGE | _U.COPY_SRC | _U.COPY_DST)
        self.grid = device.create_buffer(label="broad phase grid", size=4 * GRID_WORDS,
                                         usage=_U.STORAGE | _U.COPY_SRC | _U.COPY_DST)
        self.readback = Readback(device, "broad phase readback")
        self.readback_more = Readback(device, "broad phase pairs")
        self.capacity = FIRST_PAIRS
        self.recent = 0
        self.use_groups = False
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
            Pairs ``(i, j)`` with ``i < j``, sorted: those of :func:`reference_pairs`, and pairs
            whose boxes are within the padding (see the module's doc).

        Raises
        ------
        ValueError
            Inputs of the wrong shape, not finite, beyond :data:`COORDINATE_LIMIT`, an empty
            local box or a negative radius (naming the body).
        GpuMemoryError
            More pairs (or bodies) than one buffer of this device holds.
        GpuTimeoutError
            The GPU did not finish within ``timeout``.
        """
        lo, hi, r, t = _checked(local_lo, local_hi, radius, transforms)
        n = len(r)
        within_keys, group_keys = _ranks(within, "within", n), _ranks(groups, "groups", n)
        if n < 2:
            self.stats = BroadPhaseStats()
            return np.zeros((0, 2), dtype=np.int64)
        words, axis, origin = _packed(lo, hi, r, t, within_keys, group_keys)
        base_pad = ORIGIN_PAD_SCALE * float(np.abs(origin).max())
        with self.gpu.lock:  # the device, and this object's buffers and stats
            self.stats = BroadPhaseStats(axis=axis)
            self.use_groups = groups is not None
            found = self._run(words, n, axis, base_pad)
            key = found[:, 0].astype(np.int64) * n + found[:, 1]
            if self.stats.unfinished:
                key = np.unique(key)  # the host's pairs of unfinished sweeps repeat some
            else:
                key.sort()
            self.stats.pairs = len(key)
        return np.stack(np.divmod(key, n), axis=1)

    # -- GPU work -------------------------------------------------------------------------------

    def _run(self, words: np.ndarray, n: int, axis: int, base_pad: float) -> np.ndarray:
        """Encode every pass, submit, read the pairs (sweeping again while the pairs buffer
        overflows). Returns (K, 2) uint32 bodies, with repeats where sweeps were unfinished."""
        count = max(SORT_BLOCK, 1 << (n - 1).bit_length())
        steps = sort_steps(count)
        self.params.ensure(PARAM_STRIDE * (1 + len(steps)))
        block = np.zeros((1 + len(steps), PARAM_STRIDE // 4), dtype=np.uint32)
        block[0, :5] = (n, count, axis, self.capacity, int(self.use_groups))
        block[0, 5] = np.float32(base_pad).view(np.uint32)
        for s, (_, k, j) in enumerate(steps, start=1):
            block[s, :2] = (k, j)
        self.params.write(block)
        self.bodies.ensure(words.nbytes)
        self.bodies.write(words)
        for buf in (self.boxes_lo, self.boxes_hi, self.sorted_lo, self.sorted_hi):
            buf.ensure(16 * n)
        self.sorted_body.ensure(4 * n)
        self.unfinished.ensure(4 * n)
        self.elements.ensure(16 * count)
        self.pairs_buffer.ensure(8 * self.capacity)

        encoder = self.gpu.device.create_command_encoder(label="broad phase")
        encoder.clear_buffer(self.counter)
        encoder.clear_buffer(self.grid)
        cpass = encoder.begin_compute_pass(label="broad phase")
        params = (self.params.buffer, 0, 32)
        self._dispatch(cpass, self.world, self.world.group(
            params=params, bodies=self.bodies, boxes_lo=self.boxes_lo, boxes_hi=self.boxes_hi,
            grid=self.grid), -(-n // WORKGROUP))
        self._dispatch(cpass, self.grid_setup, self.grid_setup.group(params=params, grid=self.grid),
                       1)
        self._dispatch(cpass, self.columns, self.columns.group(
            params=params, boxes_lo=self.boxes_lo, boxes_hi=self.boxes_hi,
            elements=self.elements, grid=self.grid), -(-count // WORKGROUP))
        for s, (kind, k, j) in enumerate(steps, start=1):
            step = (self.params.buffer, s * PARAM_STRIDE, 16)
            if kind == "local":
                self._dispatch(cpass, self.sort_local, self.sort_local.group(
                    f"step {s}", params=params, step=step, elements=self.elements),
                    count // SORT_BLOCK)
            else:
                self._dispatch(cpass, self.sort_step, self.sort_step.group(
                    f"step {s}", params=params, step=step, elements=self.elements),
                    count // 2 // SORT_THREADS)
        self._dispatch(cpass, self.gather, self.gather.group(
            params=params, elements=self.elements, boxes_lo=self.boxes_lo,
            boxes_hi=self.boxes_hi, sorted_lo=self.sorted_lo, sorted_hi=self.sorted_hi,
            sorted_body=self.sorted_body, counter=self.counter, grid=self.grid),
            -(-n // WORKGROUP))
        self._encode_sweep(cpass, n)
        cpass.end()
        first = min(max(FIRST_PAIRS, self.recent * 5 // 4), self.capacity)
        while True:
            total = self._read(encoder, first, n)
            found = total["count"]
            if found <= self.capacity:
                break
            # More pairs than the buffer holds: grow it and sweep again (the sorted boxes are
            # still on the GPU), reading all of them this time.
            self.stats.reruns += 1
            self.capacity = found + found // 4 + FIRST_PAIRS
            self.pairs_buffer.ensure(8 * self.capacity)
            block[0, 3] = self.capacity
            self.params.write(block[:1])
            encoder = self.gpu.device.create_command_encoder(label="broad phase sweep")
            encoder.clear_buffer(self.counter)
            cpass = encoder.begin_compute_pass(label="broad phase sweep")
            self._encode_sweep(cpass, n)
            cpass.end()
            first = found
        self.recent = found
        return total["pairs"]

    def _encode_sweep(self, cpass: wgpu.GPUComputePassEncoder, n: int) -> None:
        common = dict(params=(self.params.buffer, 0, 32), sorted_lo=self.sorted_lo,
                      sorted_hi=self.sorted_hi, sorted_body=self.sorted_body,
                      counter=self.counter, pairs=self.pairs_buffer, elements=self.elements)
        self._dispatch(cpass, self.sweep, self.sweep.group(
            **common, unfinished=self.unfinished), -(-n // WORKGROUP))
        self._dispatch(cpass, self.wide_sweep, self.wide_sweep.group(**common, grid=self.grid),
                       -(-n // WORKGROUP))

    @staticmethod
    def _dispatch(cpass: wgpu.GPUComputePassEncoder, stage: Stage, group: wgpu.GPUBindGroup,
                  workgroups: int) -> None:
        cpass.set_pipeline(stage.pipeline)
        cpass.set_bind_group(0, group)
        cpass.dispatch_workgroups(*_grid(workgroups))

    def _read(self, encoder: wgpu.GPUCommandEncoder, first: int, n: int) -> dict:
        """Copy the count and the first ``first`` pairs, submit ``encoder`` and map them; read the
        rest (when the buffer held them) with a second copy. Returns the count and the pairs,
        (count, 2) uint32 (None when the buffer did not hold them)."""
        device = self.gpu.device
        head = 32
        staging = self.readback.ensure(head + 8 * first)
        encoder.copy_buffer_to_buffer(self.counter, 0, staging, 0, 16)
        encoder.copy_buffer_to_buffer(self.grid, 4 * GRID_SETUP, staging, 16, 16)
        if first:
            encoder.copy_buffer_to_buffer(self.pairs_buffer.buffer, 0, staging, head, 8 * first)
        device.queue.submit([encoder.finish()])
        self.stats.submissions += 1
        nbytes = head + 8 * first
        waiting = f"the broad phase of {n} bodies"
        data = self.readback.read(nbytes, timeout=self.timeout, waiting_for=waiting)
        self.stats.maps += 1
        self.stats.bytes_read += nbytes
        count, unfinished = int(data[0]), int(data[2])
        if data[3]:
            raise RuntimeError(f"the broad phase listed {int(data[1])} wide bodies, more than "
                               f"the {int(data[7])} it counted")
        self.stats.cell_size = tuple(float(x) for x in data[4:6].view(np.float32))
        self.stats.wide_bodies = int(data[7])
        self.stats.unfinished = unfinished
        if count > self.capacity:
            return {"count": count, "pairs": None}  # the caller grows the buffer
        pairs = data[head // 4:head // 4 + 2 * min(count, first)].reshape(-1, 2)
        if count > first:
            rest = count - first
            encoder = device.create_command_encoder(label="broad phase pairs")
            staging = self.readback_more.ensure(8 * rest)
            encoder.copy_buffer_to_buffer(self.pairs_buffer.buffer, 8 * first, staging, 0,
                                          8 * rest)
            device.queue.submit([encoder.finish()])
            more = self.readback_more.read(8 * rest, timeout=self.timeout,
                                           waiting_for=f"{rest} pairs of {waiting}")
            self.stats.submissions += 1
            self.stats.maps += 1
            self.stats.bytes_read += 8 * rest
            pairs = np.concatenate([pairs, more.reshape(-1, 2)])
        if unfinished:
            pairs = np.concatenate([pairs, self._finish(unfinished, n, waiting)])
        return {"count": count, "pairs": pairs}

    def _finish(self, unfinished: int, n: int, waiting: str) -> np.ndarray:
        """The pairs of the boxes whose sweep ran out of its budget, found on the host from the
        GPU's boxes (all of each box's pairs: duplicates of those the GPU found are removed
        later). Returns (K, 2) uint32 bodies."""
        device = self.gpu.device
        parts = [(self.unfinished, 4 * unfinished), (self.sorted_lo, 16 * n),
                 (self.sorted_hi, 16 * n), (self.sorted_body, 4 * n)]
        staging = self.readback_more.ensure(sum(size for _, size in parts))
        encoder = device.create_command_encoder(label="broad phase boxes")
        offset = 0
        for buf, size in parts:
            encoder.copy_buffer_to_buffer(buf.buffer, 0, staging, offset, size)
            offset += size
        device.queue.submit([encoder.finish()])
        data = self.readback_more.read(offset, timeout=self.timeout,
                                       waiting_for=f"the boxes of {waiting}")
        self.stats.submissions += 1
        self.stats.maps += 1
        self.stats.bytes_read += offset
        which = data[:unfinished].astype(np.int64)
        lo = data[unfinished:unfinished + 4 * n].view(np.float32).reshape(n, 4)
        hi = data[unfinished + 4 * n:unfinished + 8 * n].view(np.float32).reshape(n, 4)
        body = data[unfinished + 8 * n:]
        within, group = lo[:, 3].view(np.uint32), hi[:, 3].view(np.uint32)
        found = []
        step = max(1, HOST_CHUNK // n)
        for start in range(0, unfinished, step):
            p = which[start:start + step]
            meet = (lo[None, :, :3] <= hi[p, None, :3]).all(axis=2) \
                & (lo[p, None, :3] <= hi[None, :, :3]).all(axis=2) \
                & (within[None, :] == within[p, None])
            if self.use_groups:
                meet &= group[None, :] != group[p, None]
            meet[np.arange(len(p)), p] = False
            i, j = np.nonzero(meet)
            a, b = body[p[i]], body[j]
            found.append(np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1))
        return np.concatenate(found)


__all__ = ["BroadPhaseStats", "GpuBroadPhase", "reference_pairs", "sort_steps"]

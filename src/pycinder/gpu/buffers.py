"""GPU resources that a :class:`~pycinder.Detector` creates once and reuses every frame.

* :class:`SceneBuffers` holds a packed scene. Buffers grow (to the next power of two) when a larger
  scene arrives and are otherwise reused; a new topology re-uploads faces and edges, and an
  animation frame re-uploads only the vertex ranges of bodies whose vertices changed.
* :class:`Targets` holds the render targets of one resolution.
* :class:`Readback` is a mappable staging buffer.
"""

from __future__ import annotations

import numpy as np
import wgpu

from ..errors import GpuMemoryError, GpuTimeoutError
from ..request import DEFAULT_TIMEOUT
from ..scene.pack import PackedScene
from . import native
from .watch import wait_for, watch_of

STORAGE = wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_DST
_READ_NOSYNC = "READ_NOSYNC"
"""wgpu-py's map mode for reading without its extra flushing submission (see Readback.start)."""
RECORD_FORMAT = "rgba32uint"


def _capacity(nbytes: int, limit: int) -> int:
    return min(max(256, 1 << (max(int(nbytes), 1) - 1).bit_length()), limit)


class GrowableBuffer:
    """A GPU buffer that is replaced by a larger one only when the data outgrows it.

    A request beyond the device's buffer limit raises :class:`~pycinder.errors.GpuMemoryError`
    before anything is allocated, so the buffer held so far stays valid.
    """

    def __init__(self, device: wgpu.GPUDevice, label: str, usage: int) -> None:
        self.device, self.label, self.usage = device, label, usage
        self.buffer: wgpu.GPUBuffer | None = None
        self.generation = 0
        self.limit = int(device.limits["max-buffer-size"])
        if usage & wgpu.BufferUsage.STORAGE:
            self.limit = min(self.limit, int(device.limits["max-storage-buffer-binding-size"]))
        self.limit -= self.limit % 4

    def ensure(self, nbytes: int) -> bool:
        """Make room for ``nbytes``; True when the buffer was (re)created."""
        if self.buffer is not None and self.buffer.size >= nbytes:
            return False
        if nbytes > self.limit:
            raise GpuMemoryError(
                f"the {self.label} buffer would need {nbytes / 2**20:.1f} MiB, more than this "
                f"device's limit of {self.limit / 2**20:.1f} MiB for one buffer")
        self.buffer = None  # free the old one before the new one is made
        self.buffer = self.device.create_buffer(label=self.label,
                                                size=_capacity(nbytes, self.limit),
                                                usage=self.usage)
        self.generation += 1
        return True

    def write(self, data: np.ndarray, offset: int = 0) -> None:
        data = np.ascontiguousarray(data)
        if data.nbytes:
            self.device.queue.write_buffer(self.buffer, offset, data)


class SceneBuffers:
    """The packed scene on the GPU, for the whole-scene strategy's passes 1-7: each storage
    buffer under the name ``wholescene_raycast.wgsl`` binds it by (:attr:`NAMES`), and the index
    buffer. (The view's own constants, the ``Frame`` block, belong to the passes:
    :class:`~pycinder.wholescene.raycast.RaycastPasses`.)"""

    NAMES = ("positions", "vertex_body", "clip_from_body", "edges", "vertex_normals",
             "edge_normals", "world_from_body")

    def __init__(self, device: wgpu.GPUDevice) -> None:
        self.device = device
        self.storage = {n: GrowableBuffer(device, n, STORAGE) for n in self.NAMES}
        self.index = GrowableBuffer(device, "indices",
                                    wgpu.BufferUsage.INDEX | wgpu.BufferUsage.COPY_DST)
        self.scene: PackedScene | None = None
        self._uploaded_positions: np.ndarray | None = None
        self.uploaded_vertex_bytes = 0
        """Bytes of vertex data uploaded by the last :meth:`upload` (for stats and tests)."""

    @property
    def generation(self) -> tuple[int, ...]:
        """Changes whenever a buffer is recreated, so that bind groups and bundles are rebuilt."""
        return tuple(b.generation for b in self.storage.values()) + (self.index.generation,)

    def upload(self, scene: PackedScene) -> None:
        """Upload ``scene``, skipping what the GPU already holds.

        The topology (indices, edges) is uploaded when it differs from the last scene; vertex
        positions only for bodies whose vertices changed, and normals (when the scene carries
        them) whenever any body's vertices changed, so they are never stale.
        """
        same_topology = self.scene is not None and self.scene.topology_ids == scene.topology_ids \
            and np.array_equal(self.scene.vertex_start, scene.vertex_start)
        s = self.storage
        if not same_topology:
            s["positions"].ensure(scene.positions.nbytes)
            s["vertex_body"].ensure(scene.vertex_body.nbytes)
            s["edges"].ensure(scene.edges.nbytes)
            self.index.ensure(scene.indices.nbytes)
            s["positions"].write(scene.positions)
            s["vertex_body"].write(scene.vertex_body)
            s["edges"].write(scene.edges)
            self.index.write(scene.indices)
            self.uploaded_vertex_bytes = scene.positions.nbytes
        elif self.scene.shape_ids != scene.shape_ids:
            self.uploaded_vertex_bytes = self._upload_changed_vertices(scene)
        else:
            self.uploaded_vertex_bytes = 0
        if not same_topology or self.scene.shape_ids != scene.shape_ids \
                or self.scene.normals != scene.normals:
            s["vertex_normals"].ensure(scene.vertex_normals.nbytes)
            s["edge_normals"].ensure(scene.edge_normals.nbytes)
            s["vertex_normals"].write(scene.vertex_normals)
            s["edge_normals"].write(scene.edge_normals)
        self._uploaded_positions = scene.positions
        self.scene = scene

    def _upload_changed_vertices(self, scene: PackedScene) -> int:
        old = self._uploaded_positions
        changed = (old != scene.positions).any(axis=1)
        if not changed.any():
            return 0
        starts = scene.vertex_start
        bodies = np.unique(np.searchsorted(starts, np.flatnonzero(changed), side="right") - 1)
        total = 0
        for b in bodies:
            lo, hi = int(starts[b]), int(starts[b + 1])
            self.storage["positions"].write(scene.positions[lo:hi], offset=lo * 12)
            total += (hi - lo) * 12
        return total

    def upload_transforms(self, clip_from_body: np.ndarray, world_from_body: np.ndarray) -> None:
        """clip_from_body, world_from_body : (N, 4, 4) float, row-major as NumPy holds them."""
        for name, m in (("clip_from_body", clip_from_body), ("world_from_body", world_from_body)):
            # WGSL matrices are column-major: upload the transpose.
            data = np.ascontiguousarray(np.transpose(m, (0, 2, 1)), dtype=np.float32)
            self.storage[name].ensure(data.nbytes)
            self.storage[name].write(data)


class Targets:
    """Render targets of one resolution.

    records : rgba32uint colour target (see ``result.py`` for the channels)
    depth_stencil : the depth buffer of pass 1 and the stencil counts of passes 2-7
    edge_owner : copy of ``records`` after pass 1, read by the prevent mode
    """

    def __init__(self, device: wgpu.GPUDevice, width: int, height: int, depth_format: str) -> None:
        self.width, self.height = width, height
        tex = wgpu.TextureUsage
        size = (width, height, 1)
        self.records = device.create_texture(
            label="records", size=size, format=RECORD_FORMAT,
            usage=tex.RENDER_ATTACHMENT | tex.TEXTURE_BINDING | tex.COPY_SRC)
        self.depth_stencil = device.create_texture(
            label="depth-stencil", size=size, format=depth_format,
            usage=tex.RENDER_ATTACHMENT)
        self.edge_owner = device.create_texture(
            label="edge owner", size=size, format=RECORD_FORMAT,
            usage=tex.TEXTURE_BINDING | tex.COPY_DST)
        self.records_view = self.records.create_view()
        self.depth_stencil_view = self.depth_stencil.create_view()
        self.edge_owner_view = self.edge_owner.create_view()

    @property
    def pixels(self) -> int:
        return self.width * self.height


class Readback:
    """A MAP_READ staging buffer, grown on demand and reused."""

    def __init__(self, device: wgpu.GPUDevice, label: str) -> None:
        self.buf = GrowableBuffer(device, label, wgpu.BufferUsage.MAP_READ | wgpu.BufferUsage.COPY_DST)

    def ensure(self, nbytes: int) -> wgpu.GPUBuffer:
        self.buf.ensure(nbytes)
        return self.buf.buffer

    def read(self, nbytes: int, dtype: np.dtype = np.uint32, *,
             timeout: float = DEFAULT_TIMEOUT, waiting_for: str = "") -> np.ndarray:
        """Map, copy out the first ``nbytes``, unmap; wait at most ``timeout`` seconds.

        Raises
        ------
        GpuTimeoutError
            The GPU did not finish the submitted work in time (the buffer stays pending: the
            resources that waited must be recreated).
        """
        if nbytes == 0:
            return np.zeros(0, dtype=dtype)
        return self.wait(self.start(nbytes), nbytes, dtype, timeout=timeout,
                         waiting_for=waiting_for)

    def start(self, nbytes: int) -> object:
        """Ask for the first ``nbytes`` to be mapped once the GPU has written them; returns what
        :meth:`wait` takes (a :class:`~pycinder.gpu.native.PendingMap`, or wgpu-py's promise
        where the map cannot go through wgpu-native's C function).

        The staging buffer is only ever written by copy commands of a command buffer already
        submitted, so the empty submission wgpu-py makes before mapping for reading (for data
        written by ``queue.write_buffer`` and not yet flushed) is skipped: it costs a round trip
        of its own (see the benchmarks' README, "Measurements behind the constants")."""
        buffer = self.buf.buffer
        pending = native.map_read(self.buf.device, buffer, nbytes)
        if pending is not None:
            return pending
        try:  # pragma: no cover - another wgpu-py backend
            return buffer.map_async(_READ_NOSYNC, 0, nbytes)
        except (KeyError, ValueError, TypeError):  # pragma: no cover - a wgpu-py without it
            return buffer.map_async(wgpu.MapMode.READ, 0, nbytes)

    @staticmethod
    def ready(pending: object) -> bool:
        """Whether a mapping asked for with :meth:`start` is done (reading will not wait)."""
        return wait_for(pending, 0.0)

    def wait(self, pending: object, nbytes: int, dtype: np.dtype = np.uint32, *,
             timeout: float = DEFAULT_TIMEOUT, waiting_for: str = "") -> np.ndarray:
        """Wait at most ``timeout`` seconds for a mapping asked for with :meth:`start`, copy out
        the first ``nbytes`` and unmap."""
        if not wait_for(pending, timeout):
            if isinstance(pending, native.PendingMap):
                pending.abandon()
            raise timeout_error(self.buf.device, waiting_for or self.buf.label, timeout)
        if isinstance(pending, native.PendingMap):
            return pending.read(dtype)
        pending.sync_wait()  # pragma: no cover - another wgpu-py backend
        b = self.buf.buffer
        try:
            data = np.frombuffer(b.read_mapped(0, nbytes), dtype=dtype).copy()
        finally:
            b.unmap()
        return data


def timeout_error(device: wgpu.GPUDevice, what: str, timeout: float) -> GpuTimeoutError:
    """The error of a wait for ``what`` on ``device`` that passed its ``timeout``: with whether
    the device was lost, the passes its last submission held and whether the GPU started and
    finished it (:meth:`~pycinder.gpu.watch.DeviceWatch.explain`; each question waits at most
    :data:`~pycinder.gpu.watch.PROGRESS_DEADLINE` seconds)."""
    watch = watch_of(device)
    if watch is None:
        return GpuTimeoutError(f"the GPU did not finish {what} within {timeout:g} s (the device "
                               "may be lost or overloaded: it is not watched)")
    try:
        found = watch.explain()
    except Exception as exc:  # the diagnosis must not hide the timeout
        return GpuTimeoutError(f"the GPU did not finish {what} within {timeout:g} s (what the "
                               f"device did could not be found: {exc})")
    return GpuTimeoutError(f"the GPU did not finish {what} within {timeout:g} s: "
                           f"{found.sentence}", device_lost=found.lost is not None,
                           progress=found.progress)

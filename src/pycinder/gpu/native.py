"""The commands a frame records many times, straight through wgpu-native's C functions.

wgpu-py wraps each C function of wgpu-native in Python: checking arguments, building descriptor
structs and capturing errors around the call. A compute dispatch (``set_pipeline``,
``set_bind_group``, ``dispatch_workgroups``) costs about 20 µs of host CPU that way, and the C
functions themselves about a fifth of it (``python -m benchmarks.hostfloor`` from a checkout). A
frame makes dozens, so :class:`Encoder` records compute passes, render passes of one colour
attachment, buffer clears and copies with the C functions themselves, on the command encoder
wgpu-py made; everything else (other render passes, timed passes, ``finish``, which raises the
encoder's validation errors) stays wgpu-py's.

* Objects (pipelines, bind groups, buffers) are wgpu-py's: their handles are read from them, and
  wgpu-py still owns and releases them. A compute pass made here is released when it ends.
* Errors: a command recorded wrongly makes wgpu-core mark the encoder invalid, and wgpu-py's
  ``finish`` raises the error, as it does for commands recorded through wgpu-py.
* The device watch (:mod:`pycinder.gpu.watch`) still notes the label of every pass.
* Where the device is not wgpu-native's (another wgpu-py backend), :func:`encoder` hands back
  wgpu-py's own command encoder, whose methods these are.

The C functions are looked up through :data:`LIB` at each call, so that the benchmarks can count
them (:func:`counting`).
"""

from __future__ import annotations

import contextlib
import itertools
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
import wgpu

try:  # pragma: no cover - wgpu-py's only desktop backend
    from wgpu.backends.wgpu_native import GPUCommandBuffer as _CommandBuffer
    from wgpu.backends.wgpu_native import ffi as _ffi
    from wgpu.backends.wgpu_native import lib as _lib
except ImportError:  # pragma: no cover
    _CommandBuffer = _ffi = _lib = None

WHOLE_SIZE = 0xFFFF_FFFF_FFFF_FFFF
"""``WGPU_WHOLE_SIZE``: a clear to the end of the buffer."""
_LABELS_KEPT = 512
"""Pass descriptors kept (one per label, and attachment for a render pass; a frame's repeat)."""


class _Lib:
    """wgpu-native's C functions (the module's :data:`LIB`; :func:`counting` swaps it)."""

    def __init__(self, lib: Any) -> None:
        self.lib = lib

    def __getattr__(self, name: str) -> Any:
        fn = getattr(self.lib, name)
        setattr(self, name, fn)  # looked up once
        return fn


LIB = _Lib(_lib) if _lib is not None else None
"""The C functions this module calls."""


NULL = _ffi.NULL if _ffi is not None else None
"""The C null pointer."""


def pointer(array: Any) -> Any:
    """A C pointer to a NumPy array's data (valid while the array lives)."""
    return _ffi.cast("void *", array.ctypes.data)


def command_buffer(handle: Any, device: wgpu.GPUDevice, label: str = "") -> Any:
    """wgpu-py's command buffer of a C handle (wgpu-py releases it), to submit with wgpu-py's
    ``queue.submit``."""
    return _CommandBuffer(label, handle, device)


def available(device: Any) -> bool:
    """Whether ``device`` is wgpu-native's (its objects have C handles)."""
    return LIB is not None and type(device).__module__.startswith("wgpu.backends.wgpu_native")


def encoder(device: wgpu.GPUDevice, label: str = "") -> Any:
    """A command encoder of ``device`` that records compute passes, render passes of one colour
    attachment, clears and copies through the C functions (:class:`Encoder`), or wgpu-py's own
    where :func:`available` is False."""
    wrapped = device.create_command_encoder(label=label)
    return Encoder(wrapped) if available(device) else wrapped


class Encoder:
    """wgpu-py's command encoder ``wrapped``, with compute passes, render passes of one colour
    attachment, ``clear_buffer`` and ``copy_buffer_to_buffer`` recorded through the C
    functions; every other method is ``wrapped``'s."""

    __slots__ = ("wrapped", "_handle", "_labels", "_log")

    def __init__(self, wrapped: wgpu.GPUCommandEncoder) -> None:
        self.wrapped = wrapped
        self._handle = wrapped._internal
        self._labels: list[str] | None = getattr(wrapped, "_pycinder_labels", None)
        self._log: Recording | None = None

    def __getattr__(self, name: str) -> Any:
        if self._log is not None:  # a call through wgpu-py is not recorded: nothing replays it
            self._log.complete = False
        return getattr(self.wrapped, name)

    def record(self) -> Recording:
        """Start noting the commands recorded through the C functions (they are recorded as
        ever) in a :class:`Recording`, until :meth:`stop`."""
        self._log = Recording()
        return self._log

    def stop(self) -> None:
        """Stop noting commands (see :meth:`record`)."""
        self._log = None

    def replay(self, recording: Recording) -> None:
        """Record a :class:`Recording`'s commands again, as they were noted."""
        recording.replay(self)

    def begin_compute_pass(self, *, label: str = "",
                           timestamp_writes: Any = None) -> Any:
        """A compute pass (:class:`ComputePass`); a timed one (``timestamp_writes``) is
        wgpu-py's."""
        if timestamp_writes is not None:
            return self.__getattr__("begin_compute_pass")(label=label,
                                                          timestamp_writes=timestamp_writes)
        label = label or "compute pass"
        if self._labels is not None:
            self._labels.append(label)
        kept = _pass_descriptor(label)
        if self._log is not None:
            self._log.add(_BEGIN, "wgpuCommandEncoderBeginComputePass", (kept[0], label), kept)
        return ComputePass(LIB.wgpuCommandEncoderBeginComputePass(self._handle, kept[0]),
                           self._log)

    def begin_render_pass(self, *, label: str = "", color_attachments: Any,
                          **options: Any) -> Any:
        """A render pass of one colour attachment (view, ``load_op``, ``store_op``, optionally
        ``clear_value``) and nothing else (:class:`RenderPass`); any other is wgpu-py's."""
        if options or len(color_attachments) != 1 or not _plain(color_attachments[0]):
            return self.__getattr__("begin_render_pass")(
                label=label, color_attachments=color_attachments, **options)
        label = label or "render pass"
        if self._labels is not None:
            self._labels.append(label)
        kept = _render_pass_descriptor(label, color_attachments[0])
        if self._log is not None:
            self._log.add(_BEGIN, "wgpuCommandEncoderBeginRenderPass", (kept[0], label), kept)
        return RenderPass(LIB.wgpuCommandEncoderBeginRenderPass(self._handle, kept[0]),
                          self._log)

    def clear_buffer(self, buffer: wgpu.GPUBuffer, offset: int = 0,
                     size: int | None = None) -> None:
        args = (buffer._internal, int(offset), WHOLE_SIZE if size is None else int(size))
        if self._log is not None:
            self._log.add(_ENCODER, "wgpuCommandEncoderClearBuffer", args, buffer)
        LIB.wgpuCommandEncoderClearBuffer(self._handle, *args)

    def copy_buffer_to_buffer(self, source: wgpu.GPUBuffer, source_offset: int,
                              destination: wgpu.GPUBuffer, destination_offset: int,
                              size: int) -> None:
        args = (source._internal, int(source_offset), destination._internal,
                int(destination_offset), int(size))
        if self._log is not None:
            self._log.add(_ENCODER, "wgpuCommandEncoderCopyBufferToBuffer", args, source,
                          destination)
        LIB.wgpuCommandEncoderCopyBufferToBuffer(self._handle, *args)

    def finish(self, **kwargs: Any) -> wgpu.GPUCommandBuffer:
        """wgpu-py's ``finish``: it raises what was recorded wrongly."""
        return self.wrapped.finish(**kwargs)


class _Pass:
    """What compute and render passes recorded through the C functions share: a pipeline, a
    bind group (no dynamic offsets), and :meth:`end`, which releases the pass. ``_KIND`` names
    the C functions ("Compute" or "Render")."""

    __slots__ = ("_handle", "_log")
    _KIND = ""
    _C: tuple[str, str, str, str] = ("", "", "", "")

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._C = tuple(f"wgpu{cls._KIND}PassEncoder{name}"  # type: ignore[assignment]
                       for name in ("SetPipeline", "SetBindGroup", "End", "Release"))

    def __init__(self, handle: Any, log: Recording | None = None) -> None:
        self._handle = handle
        self._log = log

    def _call(self, name: str, args: tuple, *objects: Any) -> None:
        """C function ``name`` on this pass (noted when the encoder records, with the
        ``objects`` whose handles ``args`` hold)."""
        if self._log is not None:
            self._log.add(_PASS, name, args, *objects)
        getattr(LIB, name)(self._handle, *args)

    def set_pipeline(self, pipeline: Any) -> None:
        self._call(self._C[0], (pipeline._internal,), pipeline)

    def set_bind_group(self, index: int, group: wgpu.GPUBindGroup) -> None:
        self._call(self._C[1], (index, group._internal, 0, _ffi.NULL), group)

    def end(self) -> None:
        handle, self._handle = self._handle, None
        if self._log is not None:
            self._log.add(_END, self._C[2], (self._C[3],))
        getattr(LIB, self._C[2])(handle)
        getattr(LIB, self._C[3])(handle)


class ComputePass(_Pass):
    """A compute pass recorded through the C functions (the methods wgpu-py's pass has, as a
    frame uses them); released by :meth:`end`."""

    __slots__ = ()
    _KIND = "Compute"

    def dispatch_workgroups(self, x: int, y: int = 1, z: int = 1) -> None:
        self._call("wgpuComputePassEncoderDispatchWorkgroups", (int(x), int(y), int(z)))

    def dispatch_workgroups_indirect(self, buffer: wgpu.GPUBuffer, offset: int) -> None:
        self._call("wgpuComputePassEncoderDispatchWorkgroupsIndirect",
                   (buffer._internal, int(offset)), buffer)


class RenderPass(_Pass):
    """A render pass recorded through the C functions (the methods wgpu-py's pass has, as a
    frame uses them); released by :meth:`end`."""

    __slots__ = ()
    _KIND = "Render"

    def draw(self, vertices: int, instances: int = 1, first_vertex: int = 0,
             first_instance: int = 0) -> None:
        self._call("wgpuRenderPassEncoderDraw",
                   (int(vertices), int(instances), int(first_vertex), int(first_instance)))

    def draw_indirect(self, buffer: wgpu.GPUBuffer, offset: int) -> None:
        self._call("wgpuRenderPassEncoderDrawIndirect", (buffer._internal, int(offset)), buffer)

    def execute_bundles(self, bundles: list) -> None:
        handles = _ffi.new("WGPURenderBundle[]", [b._internal for b in bundles])
        self._call("wgpuRenderPassEncoderExecuteBundles", (len(bundles), handles), handles,
                   *bundles)


_PASS, _ENCODER, _BEGIN, _END = range(4)
"""What a noted command is recorded on (see :class:`Recording`)."""


class Recording:
    """Commands noted while an :class:`Encoder` recorded them (:meth:`Encoder.record`), to record
    again on another encoder with no Python between the C calls but this loop's: the passes of
    a frame's round whose buffers and pipelines are those of an earlier round (its sizes are
    read from its parameters, written anew each frame).

    It holds the objects whose handles its commands name (buffers, bind groups, pipelines,
    views, descriptors), so none is released while it may be replayed. A recording that saw a
    command recorded through wgpu-py (a timed pass, a render pass that is not plain, any other
    method) is not :attr:`complete` and must not be replayed.
    """

    __slots__ = ("ops", "keep", "complete")

    def __init__(self) -> None:
        self.ops: list[tuple[int, Any, tuple]] = []
        self.keep: list[Any] = []
        self.complete = True

    def add(self, kind: int, name: str, args: tuple, *objects: Any) -> None:
        self.ops.append((kind, name, args))
        self.keep.extend(objects)

    def replay(self, encoder: Encoder) -> None:
        """Record the noted commands on ``encoder`` (the watch notes each pass's label)."""
        if not self.complete:
            raise RuntimeError("a recording with commands recorded through wgpu-py cannot be "
                               "replayed")
        handle, labels, lib, current = encoder._handle, encoder._labels, LIB, None
        for kind, name, args in self.ops:
            if kind == _PASS:
                getattr(lib, name)(current, *args)
            elif kind == _ENCODER:
                getattr(lib, name)(handle, *args)
            elif kind == _BEGIN:
                if labels is not None:
                    labels.append(args[1])
                current = getattr(lib, name)(handle, args[0])
            else:
                getattr(lib, name)(current)
                getattr(lib, args[0])(current)
                current = None


class PendingMap:
    """A buffer's first ``nbytes`` asked to be mapped for reading through the C function
    (:func:`map_read`); wgpu-py's poll thread polls the device until the map is answered, and
    the answer sets :attr:`event`.

    Attributes
    ----------
    buffer : wgpu.GPUBuffer
    nbytes : int
    event : threading.Event
        Set once the map was answered (:attr:`status` says how).
    status : int or None
        ``WGPUMapAsyncStatus`` (1: success).
    """

    __slots__ = ("buffer", "nbytes", "key", "event", "status", "token")

    def __init__(self, buffer: wgpu.GPUBuffer, nbytes: int, key: int) -> None:
        self.buffer, self.nbytes, self.key = buffer, nbytes, key
        self.event = threading.Event()
        self.status: int | None = None
        self.token: Any = None

    def ready(self) -> bool:
        """Whether the map was answered (reading will not wait)."""
        return self.event.is_set()

    def wait(self, timeout: float) -> bool:
        """Wait at most ``timeout`` seconds for the answer; False when it has not come."""
        return self.event.wait(timeout)

    def abandon(self) -> None:
        """Give up on the answer (after a wait passed its deadline): the poll thread stops
        polling for it. A map that came is undone; one that comes later is ignored and leaves
        the buffer mapped, as a timeout leaves it pending: whoever timed out makes its buffers
        again (the detector is reset), and the device they belong to may be gone by then."""
        if _maps.pop(self.key, None) is not None:
            self.token.set_done()
            return
        # The answer took it first: it is set at once (the poll thread may be setting it now).
        self.event.wait(1.0)
        if self.status == _MAP_SUCCESS:
            self.status = None
            LIB.wgpuBufferUnmap(self.buffer._internal)

    def read(self, dtype: Any) -> np.ndarray:
        """Copy out the mapped bytes as ``dtype`` and unmap (after :meth:`wait` said True).

        Raises
        ------
        RuntimeError
            The map failed (a lost device, a destroyed buffer).
        """
        handle = self.buffer._internal
        if self.status != _MAP_SUCCESS:
            raise RuntimeError(f"could not map the {self.buffer.label or 'staging'} buffer "
                               f"(status {self.status})")
        try:
            data = LIB.wgpuBufferGetConstMappedRange(handle, 0, self.nbytes)
            return np.frombuffer(_ffi.buffer(data, self.nbytes), dtype=dtype).copy()
        finally:
            LIB.wgpuBufferUnmap(handle)


_MAP_SUCCESS = _lib.WGPUMapAsyncStatus_Success if _lib is not None else 1
_maps: dict[int, PendingMap] = {}
"""Maps asked for and not yet answered, by key (the callback's user data)."""
_map_keys = itertools.count(1)


def _map_answered(status: int, message: Any, key: Any, _unused: Any) -> None:
    """wgpu-native's answer to a map (on the thread that polled the device)."""
    key = int(_ffi.cast("uintptr_t", key))
    pending = _maps.pop(key, None)
    if pending is not None:
        pending.status = int(status)
        if pending.token is not None:
            pending.token.set_done()
        pending.event.set()


_map_callback: list[Any] = []
"""The C callback of every map (made on the first, once the device parsed its C types)."""


def map_read(device: wgpu.GPUDevice, buffer: wgpu.GPUBuffer, nbytes: int) -> PendingMap | None:
    """Ask for the first ``nbytes`` of a MAP_READ ``buffer`` to be mapped once the GPU has
    written them (without the empty submission wgpu-py makes before mapping for reading); None
    where this module cannot (another backend, or a wgpu-py without its poll thread): map with
    wgpu-py then."""
    poller = getattr(device, "_poller", None)
    if not available(device) or poller is None:
        return None
    # wgpu-py's checks of a map's range: a range wgpu-native refuses would abort the process
    # when read.
    if not 0 < nbytes <= buffer.size or nbytes % 4:
        raise ValueError(f"cannot map {nbytes} bytes of the {buffer.label or 'staging'} buffer "
                         f"({buffer.size} bytes): a multiple of 4, at least 4, within it")
    key = next(_map_keys)
    pending = PendingMap(buffer, nbytes, key)
    _maps[key] = pending
    info = _ffi.new("WGPUBufferMapCallbackInfo *")
    info.mode = _lib.WGPUCallbackMode_AllowProcessEvents
    if not _map_callback:
        _map_callback.append(_ffi.callback(
            "void(WGPUMapAsyncStatus, WGPUStringView, void *, void *)", _map_answered))
    info.callback = _map_callback[0]
    info.userdata1 = _ffi.cast("void *", key)
    LIB.wgpuBufferMapAsync(buffer._internal, _lib.WGPUMapMode_Read, 0, nbytes, info[0])
    # The poll thread polls until the answer. Woken after the map is asked for, so that its
    # blocking poll does not hold the device while the map is asked for; an answer that came
    # meanwhile (another map's polling) ends the token at once.
    pending.token = poller.get_token()
    if pending.event.is_set():
        pending.token.set_done()
    return pending


_descriptors: dict[Any, tuple] = {}
"""Pass descriptors made, by label (compute) or by label and attachment (render), each with the
C objects and views it points to (kept alive with it, so that a view's id stays its own)."""


def _kept(key: Any, make: Any) -> tuple:
    """The descriptor kept under ``key``, made by ``make()`` the first time: a tuple, the
    descriptor first, then what it points to (hold the whole tuple while the descriptor is
    used); at most :data:`_LABELS_KEPT` are kept."""
    found = _descriptors.get(key)
    if found is None:
        if len(_descriptors) >= _LABELS_KEPT:
            _descriptors.clear()
        found = _descriptors[key] = make()
    return found


def _labelled(ctype: str, label: str) -> tuple[Any, Any]:
    """A new pass descriptor of ``ctype`` named ``label``, untimed, and its label's bytes."""
    text = _ffi.new("char []", label.encode())
    desc = _ffi.new(ctype)
    desc.label.data = text
    desc.label.length = len(text) - 1
    desc.timestampWrites = _ffi.NULL
    return desc, text


def _pass_descriptor(label: str) -> tuple:
    """The compute pass descriptor of ``label`` (made once; see :func:`_kept`)."""
    return _kept(label, lambda: _labelled("WGPUComputePassDescriptor *", label))


_LOAD = {"load": "WGPULoadOp_Load", "clear": "WGPULoadOp_Clear"}
_STORE = {"store": "WGPUStoreOp_Store", "discard": "WGPUStoreOp_Discard"}


def _plain(attachment: dict) -> bool:
    """Whether a colour attachment is one :func:`_render_pass_descriptor` makes: a view, known
    load and store operations, and a clear value of four numbers if any."""
    clear = attachment.get("clear_value", (0, 0, 0, 0))
    return (set(attachment) <= {"view", "load_op", "store_op", "clear_value"}
            and attachment.get("load_op") in _LOAD and attachment.get("store_op") in _STORE
            and isinstance(clear, (tuple, list)) and len(clear) == 4)


def _render_pass_descriptor(label: str, attachment: dict) -> tuple:
    """The render pass descriptor of ``label`` and one colour attachment (made once per label,
    view and operations; see :func:`_kept`)."""
    view = attachment["view"]
    clear = tuple(attachment.get("clear_value", (0, 0, 0, 0)))
    load, store = attachment["load_op"], attachment["store_op"]

    def make() -> tuple:
        colour = _ffi.new("WGPURenderPassColorAttachment *")
        colour.view = view._internal
        colour.depthSlice = _lib.WGPU_DEPTH_SLICE_UNDEFINED
        colour.resolveTarget = _ffi.NULL
        colour.loadOp = getattr(_lib, _LOAD[load])
        colour.storeOp = getattr(_lib, _STORE[store])
        colour.clearValue.r, colour.clearValue.g, colour.clearValue.b, colour.clearValue.a = clear
        desc, text = _labelled("WGPURenderPassDescriptor *", label)
        desc.colorAttachmentCount = 1
        desc.colorAttachments = colour
        desc.depthStencilAttachment = _ffi.NULL
        desc.occlusionQuerySet = _ffi.NULL
        return desc, colour, text, view

    return _kept(("render", label, id(view), load, store, clear), make)


@contextlib.contextmanager
def counting() -> Iterator[dict[str, int]]:
    """Count the C functions this module calls while the block runs, by name."""
    global LIB
    counts: dict[str, int] = {}
    real = LIB

    class Counted:
        def __getattr__(self, name: str) -> Any:
            fn = getattr(real, name)

            def call(*args: Any) -> Any:
                counts[name] = counts.get(name, 0) + 1
                return fn(*args)

            return call

    LIB = Counted()
    try:
        yield counts
    finally:
        LIB = real


__all__ = ["LIB", "NULL", "ComputePass", "Encoder", "PendingMap", "Recording", "RenderPass",
           "available", "command_buffer", "counting", "encoder", "map_read", "pointer"]

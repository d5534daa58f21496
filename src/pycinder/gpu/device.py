"""Adapter and device choice, limits, and errors worded for users."""

from __future__ import annotations

import os
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources

import wgpu

from .cffi_types import preparse
from .watch import install, watch_of

INSTALL_HINT = (
    "pycinder needs a WebGPU adapter (Vulkan, Metal, D3D12 or OpenGL). On a machine without a GPU, "
    "install a software driver: on Debian/Ubuntu `apt-get install mesa-vulkan-drivers` (lavapipe)."
)


STORAGE_BUFFERS_NEEDED = 11
"""Storage buffers the focused crossing test (pass F6) binds at once."""


class NoAdapterError(RuntimeError):
    """No WebGPU adapter could be found."""


class ForkedProcessError(RuntimeError):
    """The GPU cannot be used in this process: it was forked (``os.fork``, or ``multiprocessing``
    with the "fork" start method) after its parent used the GPU, and the driver is not known to
    work there (or did not answer), or a :class:`~pycinder.Detector` made before the fork was
    used after it."""


FORK_HINT = (
    "start the worker processes with the 'spawn' or 'forkserver' method instead "
    "(multiprocessing.get_context('spawn'), or "
    "concurrent.futures.ProcessPoolExecutor(mp_context=...)), or fork before the parent's first "
    "query")

FORK_PROBE_SECONDS = 10.0
"""How long a forked child's first device may take to answer a round trip before pycinder
decides that the driver does not work after a fork (lavapipe answers in well under a second)."""

FORK_SAFE_DRIVERS = (("vulkan", "llvmpipe"),)
"""The drivers known to work in a process forked after its parent used them, as (backend,
start of the adapter's device name), lower case: Mesa's lavapipe (its Vulkan driver on the CPU).
A forked child whose parent used any other driver is refused before it calls the driver at all:
NVIDIA's Vulkan driver aborts the child's process as soon as it asks for an adapter, and
llvmpipe's OpenGL never finishes a draw there."""


@dataclass(frozen=True)
class Gpu:
    """The device pycinder renders with, and what it can do."""

    adapter: wgpu.GPUAdapter
    device: wgpu.GPUDevice
    depth_format: str
    timestamps: bool
    lock: threading.RLock = field(default_factory=threading.RLock, compare=False, repr=False)
    """Held by every query on this device: wgpu's OpenGL backend aborts the process when two
    threads use one device at once (Vulkan does not), so queries from several threads, on one
    detector or several, take turns."""

    @property
    def max_binding(self) -> int:
        """Largest storage buffer one binding may hold, in bytes."""
        return int(self.device.limits["max-storage-buffer-binding-size"])

    @property
    def backend(self) -> str:
        return str(self.adapter.info["backend_type"])

    @property
    def max_resolution(self) -> int:
        return int(self.device.limits["max-texture-dimension-2d"])

    @property
    def description(self) -> str:
        info = self.adapter.info
        return f"{info['device']} ({info['backend_type']}, {info['adapter_type']})"

    @property
    def cpu_adapter(self) -> bool:
        """Whether the adapter runs on the CPU: its type says so, or it is Mesa's llvmpipe
        (lavapipe on Vulkan; on OpenGL the type may be unknown)."""
        info = self.adapter.info
        return (str(info.get("adapter_type", "")).lower() == "cpu"
                or str(info.get("device", "")).lower().startswith("llvmpipe"))


class _Fork:
    """What this process knows of forks: how many it has gone through (a detector made before one
    belongs to the parent's device), and whether the first device of a forked child must still
    prove that it answers."""

    generation = 0
    probe_pending = False
    failure: str | None = None
    adapter: dict | None = None
    """The info of the last adapter this process asked wgpu for (a forked child reads its
    parent's: copied memory, no call to the driver)."""
    inherited: list[object] = []
    """The parent's device, instance and detectors (and a device that failed the probe), kept
    from the garbage collector: releasing them in the child would ask the parent's driver state,
    which the child has only a copy of."""


def fork_generation() -> int:
    """How many forks this process descends from since pycinder was imported (0 in the process
    that imported it): a GPU object made under another number belongs to a parent's device."""
    return _Fork.generation


def survives_fork(info: Mapping[str, object]) -> bool:
    """Whether the driver of an adapter whose ``info`` this is (``adapter.info``) is known to
    work in a process forked after its parent used it (:data:`FORK_SAFE_DRIVERS`)."""
    backend = str(info.get("backend_type", "")).lower()
    name = str(info.get("device", "")).lower()
    return any(backend == b and name.startswith(d) for b, d in FORK_SAFE_DRIVERS)


def _after_fork_in_child() -> None:
    """Forget the parent's device and wgpu instance. Where the parent used the GPU through a
    driver known to work after a fork (:func:`survives_fork`), the child makes a device of its
    own at its first query (its first round trip under a deadline, see :func:`get_gpu`); where
    it used any other, every later call that would reach the driver raises
    :class:`ForkedProcessError` before it does. Only Python objects are read here."""
    inherited = _Fork.failure, _Fork.probe_pending  # from this process's own parent
    used = bool(_get_gpu.cache_info().currsize)
    if used:
        keep_from_parent(_get_gpu())
    _get_gpu.cache_clear()
    _Fork.generation += 1
    _Fork.failure = None
    _Fork.probe_pending = False
    try:  # wgpu-py keeps one native instance per process; the child needs one of its own
        from wgpu.backends.wgpu_native import _helpers

        if getattr(_helpers, "_the_instance", None) is not None:
            used = True
            keep_from_parent(_helpers._the_instance)
            _helpers._the_instance = None
    except ImportError:  # pragma: no cover - another wgpu backend
        pass
    default = _forget_default_device()
    if default is not None:
        used = True
        _Fork.adapter = _Fork.adapter or dict(getattr(default.adapter, "info", None) or {})
    if not used:
        # The parent never reached the driver itself; what it inherited from its own parent (a
        # driver's state in its memory) holds here too, and a fork of a fresh process is fresh.
        _Fork.failure, _Fork.probe_pending = inherited
        return
    if _Fork.adapter is not None and survives_fork(_Fork.adapter):
        _Fork.probe_pending = True
        return
    driver = "an unknown driver" if not _Fork.adapter else (
        f"{_Fork.adapter.get('device', '?')} ({_Fork.adapter.get('backend_type', '?')})")
    _Fork.failure = (
        f"this process was forked after its parent used the GPU ({driver}), and that driver is "
        "not known to work in a forked child (NVIDIA's Vulkan driver aborts the process there): "
        f"pycinder does not call it here; {FORK_HINT}")


def _refuse_if_forked() -> None:
    """Raise :class:`ForkedProcessError` where this process may not call the GPU driver (see
    :func:`_after_fork_in_child`): before any call that reaches it."""
    if _Fork.failure is not None:
        raise ForkedProcessError(_Fork.failure)


def _forget_default_device() -> wgpu.GPUDevice | None:
    """After a fork: wgpu's default device (shared with pygfx, see
    :func:`share_default_device`) is the parent's too. The child drops it (returned, None where
    there was none), and pycinder makes a device of its own there (the default device's
    configuration was used up by the parent)."""
    global _share_default
    helper = getattr(getattr(wgpu, "utils", None), "device", None)
    helper = getattr(helper, "helper", None)
    device = getattr(helper, "_the_device", None)
    if device is not None:
        keep_from_parent(device)
        helper._the_device = None
    _share_default = False
    return device


os.register_at_fork(after_in_child=_after_fork_in_child)


def _probe_after_fork(gpu: Gpu) -> None:
    """Raise :class:`ForkedProcessError` unless ``gpu`` draws and reads back a triangle within
    :data:`FORK_PROBE_SECONDS` (run on a thread of its own: a driver that cannot work after a fork
    blocks inside its native submit, where no deadline reaches)."""
    done = threading.Event()
    errors: list[BaseException] = []

    def round_trip() -> None:
        try:
            _draw_and_read(gpu.device)
        except BaseException as exc:  # reported on the caller's thread
            errors.append(exc)
        finally:
            done.set()

    threading.Thread(target=round_trip, name="pycinder-fork-probe", daemon=True).start()
    if not done.wait(FORK_PROBE_SECONDS):
        why = f"it did not answer within {FORK_PROBE_SECONDS:g} s"
    elif errors:
        why = f"it failed: {errors[0]}"
    else:
        return
    _Fork.failure = (
        f"this process was forked after its parent used the GPU, and the {gpu.backend} driver "
        f"({gpu.description}) does not work in the forked child ({why}); {FORK_HINT}")
    keep_from_parent(gpu)  # a device whose work may still be stuck: never released
    raise ForkedProcessError(_Fork.failure)


def keep_from_parent(obj: object) -> None:
    """Keep ``obj``, a GPU object of a parent process's device, from being released here (see
    :attr:`_Fork.inherited`)."""
    _Fork.inherited.append(obj)  # the one place that adds to it


_PROBE_SHADER = """
@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let p = array<vec2<f32>, 3>(vec2(-1.0, -1.0), vec2(3.0, -1.0), vec2(-1.0, 3.0));
    return vec4<f32>(p[i], 0.0, 1.0);
}
@fragment fn fs() -> @location(0) vec4<f32> { return vec4<f32>(1.0, 0.0, 0.0, 1.0); }
"""


def _draw_and_read(device: wgpu.GPUDevice) -> None:
    """Draw a triangle over a 4 x 4 target, copy it to a buffer and read it back: the work a
    query asks of the rasterizer, which a driver that cannot work after a fork never finishes
    (a copy alone may)."""
    size = 4
    target = device.create_texture(
        size=(size, size, 1), format="rgba8unorm",
        usage=wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC)
    out = device.create_buffer(size=256 * size,
                               usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ)
    module = device.create_shader_module(code=_PROBE_SHADER)
    pipeline = device.create_render_pipeline(
        layout="auto", vertex={"module": module, "entry_point": "vs"},
        fragment={"module": module, "entry_point": "fs",
                  "targets": [{"format": "rgba8unorm"}]},
        primitive={"topology": "triangle-list"})
    encoder = device.create_command_encoder()
    rp = encoder.begin_render_pass(color_attachments=[{
        "view": target.create_view(), "load_op": "clear", "store_op": "store",
        "clear_value": (0, 0, 0, 0)}])
    rp.set_pipeline(pipeline)
    rp.draw(3)
    rp.end()
    encoder.copy_texture_to_buffer({"texture": target},
                                   {"buffer": out, "bytes_per_row": 256},
                                   (size, size, 1))
    device.queue.submit([encoder.finish()])
    out.map_sync(wgpu.MapMode.READ)
    try:
        first = bytes(out.read_mapped(0, 4))
    finally:
        out.unmap()
    if first != bytes((255, 0, 0, 255)):
        raise RuntimeError(f"a triangle drawn on the GPU came back as {first!r}")


def check_not_forked(generation: int, what: str) -> None:
    """Raise :class:`ForkedProcessError` when ``what`` (made when :func:`fork_generation` was
    ``generation``) belongs to a parent process's device."""
    if generation != _Fork.generation:
        raise ForkedProcessError(
            f"{what} was made in a parent process, before this process was forked; its GPU "
            "device is the parent's and cannot be used here. Make a new one in this process "
            f"(pycinder.find_collisions and CollisionManager do), or {FORK_HINT}")


def _request_adapter() -> wgpu.GPUAdapter:
    """The adapter pycinder renders on (its info noted for a forked child, see
    :func:`_after_fork_in_child`).

    Raises
    ------
    ForkedProcessError
        In a forked child that may not call its parent's driver: before the call.
    NoAdapterError
    """
    _refuse_if_forked()
    preparse()  # the first GPU call: wgpu-py's C types in one parse, not one by one
    power = os.environ.get("PYCINDER_POWER_PREFERENCE", "high-performance")
    try:
        adapter = wgpu.gpu.request_adapter_sync(power_preference=power)
    except Exception as exc:  # wgpu raises different types per backend and version
        raise NoAdapterError(f"no WebGPU adapter found ({exc}). {INSTALL_HINT}") from exc
    if adapter is None:
        raise NoAdapterError(f"no WebGPU adapter found. {INSTALL_HINT}")
    _Fork.adapter = dict(adapter.info)
    return adapter


WANTED_FEATURES = ("depth32float-stencil8", "timestamp-query")
"""Used when the adapter has them: a 32-bit float depth buffer gives the scene strategy's depth
comparisons the most precision; timestamps let ``profile=True`` time each pass."""


def _limits(adapter: wgpu.GPUAdapter) -> dict[str, int]:
    storage = adapter.limits["max-storage-buffers-per-shader-stage"]
    if storage < STORAGE_BUFFERS_NEEDED:
        info = adapter.info
        raise NoAdapterError(
            f"the WebGPU adapter {info['device']} ({info['backend_type']}) offers "
            f"{storage} storage buffers per shader stage; pycinder needs "
            f"{STORAGE_BUFFERS_NEEDED}. {INSTALL_HINT}")
    return {"max-texture-dimension-2d": adapter.limits["max-texture-dimension-2d"],
            "max-storage-buffer-binding-size": adapter.limits["max-storage-buffer-binding-size"],
            "max-buffer-size": adapter.limits["max-buffer-size"],
            "max-storage-buffers-per-shader-stage": STORAGE_BUFFERS_NEEDED}


def _suits(device: wgpu.GPUDevice, limits: dict[str, int]) -> bool:
    return all(device.limits[k] >= v for k, v in limits.items())


_share_default = False


def share_default_device() -> None:
    """Make pycinder render on wgpu's default device (``wgpu.get_default_device()``, the device
    pygfx renders with), so that both can use each other's buffers.

    Call it before either library creates that device: it adds pycinder's needs (features and
    limits) to the device's configuration. Without it pycinder uses a device of its own, so that
    importing pygfx later still works (pygfx configures the default device when imported).
    """
    global _share_default
    adapter = _request_adapter()
    wanted = {f for f in WANTED_FEATURES if f in adapter.features}
    wgpu.preconfigure_default_device("pycinder", adapter=adapter, required_features=wanted,
                                     required_limits=_limits(adapter))
    _share_default = True
    _get_gpu.cache_clear()


def fit_default_device_to_adapter(caller: str) -> wgpu.GPUAdapter:
    """Before pygfx makes wgpu's default device: drop pygfx's request for ``float32-filterable``
    where the adapter lacks it (OpenGL adapters, llvmpipe's among them), since pycinder's pictures
    never filter float textures. Does nothing once the default device exists.

    Parameters
    ----------
    caller : str
        Who asks, for wgpu's record of the default device's configuration.

    Returns
    -------
    wgpu.GPUAdapter
        The adapter the default device will be made on.
    """
    adapter = _request_adapter()
    if "float32-filterable" not in adapter.features:
        try:
            wgpu.preconfigure_default_device(caller, required_features={"!float32-filterable"})
        except RuntimeError:  # the default device exists already: its configuration stands
            pass
    return adapter


def get_gpu() -> Gpu:
    """The device pycinder renders with, created on first use (see :func:`share_default_device`).

    Set ``WGPU_BACKEND_TYPE`` (Vulkan, Metal, D3D12, OpenGL) to choose a backend.

    In a process forked after its parent used the GPU, the first device is new: where the
    parent's driver is known to work after a fork (:func:`survives_fork`) it must answer a round
    trip within :data:`FORK_PROBE_SECONDS`; with any other driver no device is made.

    Raises
    ------
    NoAdapterError
        No adapter, or one without what pycinder needs.
    ForkedProcessError
        This process was forked after its parent used the GPU, and its driver is not known to
        work after a fork (:func:`survives_fork`: raised before the driver is called), or it did
        not answer the round trip.
    """
    _refuse_if_forked()
    gpu = _get_gpu()
    if _Fork.probe_pending:
        _Fork.probe_pending = False
        try:
            _probe_after_fork(gpu)
        except ForkedProcessError:
            _get_gpu.cache_clear()
            raise
    return gpu


@lru_cache(maxsize=1)
def _get_gpu() -> Gpu:
    _refuse_if_forked()
    if _share_default:
        device = wgpu.get_default_device()
        _Fork.adapter = dict(device.adapter.info)
        limits = _limits(device.adapter)
        if not _suits(device, limits):
            raise RuntimeError(
                "wgpu's default device was created before pycinder could configure it; call "
                "pycinder.share_default_device() before anything creates it")
    else:
        adapter = _request_adapter()
        limits = _limits(adapter)
        wanted = [f for f in WANTED_FEATURES if f in adapter.features]
        device = adapter.request_device_sync(required_features=wanted, required_limits=limits)
    depth_format = "depth32float-stencil8" if "depth32float-stencil8" in device.features \
        else "depth24plus-stencil8"
    install(device)
    return Gpu(device.adapter, device, depth_format, "timestamp-query" in device.features,
               lock=_next_lock or threading.RLock())


_renewing = threading.Lock()
_next_lock: threading.RLock | None = None
"""The lock the next :class:`Gpu` made takes: the lost one's, while :func:`renew_gpu` runs."""


def device_lost(gpu: Gpu, exc: BaseException | None = None) -> str | None:
    """Why ``gpu``'s device was lost (``exc``, an error a call on it raised, may say so), or
    None while it is not known to be lost (see :mod:`pycinder.gpu.watch`)."""
    watch = watch_of(gpu.device)
    if watch is None:
        return None
    if exc is not None:
        watch.note_error(exc)
    return watch.probe_lost()


def renew_gpu(gpu: Gpu) -> Gpu:
    """A new device in place of ``gpu``'s lost one: the one :func:`get_gpu` gives from now on.
    Another detector may have renewed it already (then that device is given); the new
    :class:`Gpu` keeps ``gpu``'s lock, so that queries from every thread still take turns.

    Raises
    ------
    NoAdapterError
        No adapter answers any more.
    RuntimeError
        pycinder shares wgpu's default device (:func:`share_default_device`): it cannot make
        that device again.
    """
    with _renewing:
        if _get_gpu.cache_info().currsize:
            current = _get_gpu()
            if current.device is not gpu.device and device_lost(current) is None:
                return current
        if _share_default:
            raise RuntimeError("wgpu's default device was lost; pycinder shares it "
                               "(share_default_device) and cannot make it again")
        global _next_lock
        _next_lock = gpu.lock
        try:
            _get_gpu.cache_clear()
            return _get_gpu()
        finally:
            _next_lock = None


@lru_cache(maxsize=None)
def shader_source(name: str) -> str:
    """The WGSL source ``shaders/<name>.wgsl``, with ``//!include other.wgsl`` lines replaced by
    that file's source (WGSL has no includes of its own), and ``//!include layout`` by the
    constants generated from :mod:`pycinder.gpu.layout`."""
    text = resources.files("pycinder.shaders").joinpath(f"{name}.wgsl").read_text()
    lines = []
    for line in text.splitlines():
        if line.startswith("//!include "):
            included = line.split()[1].removesuffix(".wgsl")
            if included == "layout":
                from .layout import wgsl_prelude

                lines.append(wgsl_prelude())
            else:
                lines.append(shader_source(included))
        else:
            lines.append(line)
    return "\n".join(lines) + "\n"


def check_resolution(gpu: Gpu, width: int, height: int) -> None:
    """Raise ``ValueError`` when a render target of this size is over the device's limit."""
    for side in (width, height):
        if not isinstance(side, (int,)) or side < 1:
            raise ValueError(f"resolution must be a positive integer, got {side!r}")
        if side > gpu.max_resolution:
            raise ValueError(
                f"resolution {side} is over this device's texture limit of {gpu.max_resolution} "
                f"pixels ({gpu.description}); use a smaller resolution or several views"
            )

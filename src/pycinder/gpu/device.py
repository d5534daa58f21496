"""Adapter and device choice, limits, and errors worded for users."""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources

import wgpu

from .cffi_types import preparse

INSTALL_HINT = (
    "pycinder needs a WebGPU adapter (Vulkan, Metal, D3D12 or OpenGL). On a machine without a GPU, "
    "install a software driver: on Debian/Ubuntu `apt-get install mesa-vulkan-drivers` (lavapipe)."
)


STORAGE_BUFFERS_NEEDED = 11
"""Storage buffers the focused crossing test (pass F6) binds at once."""


class NoAdapterError(RuntimeError):
    """No WebGPU adapter could be found."""


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


def _request_adapter() -> wgpu.GPUAdapter:
    preparse()  # the first GPU call: wgpu-py's C types in one parse, not one by one
    power = os.environ.get("PYCINDER_POWER_PREFERENCE", "high-performance")
    try:
        adapter = wgpu.gpu.request_adapter_sync(power_preference=power)
    except Exception as exc:  # wgpu raises different types per backend and version
        raise NoAdapterError(f"no WebGPU adapter found ({exc}). {INSTALL_HINT}") from exc
    if adapter is None:
        raise NoAdapterError(f"no WebGPU adapter found. {INSTALL_HINT}")
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
    get_gpu.cache_clear()


@lru_cache(maxsize=1)
def get_gpu() -> Gpu:
    """The device pycinder renders with, created on first use (see :func:`share_default_device`).

    Set ``WGPU_BACKEND_TYPE`` (Vulkan, Metal, D3D12, OpenGL) to choose a backend.
    """
    if _share_default:
        device = wgpu.get_default_device()
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
    return Gpu(device.adapter, device, depth_format, "timestamp-query" in device.features)


@lru_cache(maxsize=None)
def shader_source(name: str) -> str:
    """The WGSL source ``shaders/<name>.wgsl``, with ``//!include other.wgsl`` lines replaced by
    that file's source (WGSL has no includes of its own), and ``//!include layout`` by the
    constants generated from :mod:`pycinder.layout`."""
    text = resources.files("pycinder.shaders").joinpath(f"{name}.wgsl").read_text()
    lines = []
    for line in text.splitlines():
        if line.startswith("//!include "):
            included = line.split()[1].removesuffix(".wgsl")
            if included == "layout":
                from ..layout import wgsl_prelude

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

"""Adapter and device choice, limits, and errors worded for users."""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import wgpu

INSTALL_HINT = (
    "pycinder needs a WebGPU adapter (Vulkan, Metal, D3D12 or OpenGL). On a machine without a GPU, "
    "install a software driver: on Debian/Ubuntu `apt-get install mesa-vulkan-drivers` (lavapipe)."
)


STORAGE_BUFFERS_NEEDED = 10
"""Storage buffers the focused edge test binds at once."""


class NoAdapterError(RuntimeError):
    """No WebGPU adapter could be found."""


@dataclass(frozen=True)
class Gpu:
    """The device pycinder renders with, and what it can do."""

    adapter: wgpu.GPUAdapter
    device: wgpu.GPUDevice
    depth_format: str
    timestamps: bool

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
    power = os.environ.get("PYCINDER_POWER_PREFERENCE", "high-performance")
    try:
        adapter = wgpu.gpu.request_adapter_sync(power_preference=power)
    except Exception as exc:  # wgpu raises different types per backend and version
        raise NoAdapterError(f"no WebGPU adapter found ({exc}). {INSTALL_HINT}") from exc
    if adapter is None:
        raise NoAdapterError(f"no WebGPU adapter found. {INSTALL_HINT}")
    return adapter


@lru_cache(maxsize=1)
def get_gpu() -> Gpu:
    """The shared adapter and device, created on first use.

    Set ``WGPU_BACKEND_TYPE`` (Vulkan, Metal, D3D12, OpenGL) to choose a backend.
    """
    adapter = _request_adapter()
    wanted = []
    # A 32-bit float depth buffer gives the ray-casting comparisons the most precision.
    depth_format = "depth24plus-stencil8"
    if "depth32float-stencil8" in adapter.features:
        wanted.append("depth32float-stencil8")
        depth_format = "depth32float-stencil8"
    timestamps = "timestamp-query" in adapter.features
    if timestamps:
        wanted.append("timestamp-query")
    storage = adapter.limits["max-storage-buffers-per-shader-stage"]
    if storage < STORAGE_BUFFERS_NEEDED:
        info = adapter.info
        raise NoAdapterError(
            f"the WebGPU adapter {info['device']} ({info['backend_type']}) offers "
            f"{storage} storage buffers per shader stage; pycinder needs "
            f"{STORAGE_BUFFERS_NEEDED}. {INSTALL_HINT}")
    limits = {"max-texture-dimension-2d": adapter.limits["max-texture-dimension-2d"],
              "max-storage-buffer-binding-size": adapter.limits["max-storage-buffer-binding-size"],
              "max-buffer-size": adapter.limits["max-buffer-size"],
              "max-storage-buffers-per-shader-stage": STORAGE_BUFFERS_NEEDED}
    device = adapter.request_device_sync(required_features=wanted, required_limits=limits)
    return Gpu(adapter, device, depth_format, timestamps)


@lru_cache(maxsize=None)
def shader_source(name: str) -> str:
    """The WGSL source ``shaders/<name>.wgsl``, with ``//!include other.wgsl`` lines replaced by
    that file's source (WGSL has no includes of its own)."""
    text = resources.files("pycinder.shaders").joinpath(f"{name}.wgsl").read_text()
    lines = []
    for line in text.splitlines():
        if line.startswith("//!include "):
            lines.append(shader_source(line.split()[1].removesuffix(".wgsl")))
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

"""wgpu-py's C types, parsed in one go before the first GPU call.

wgpu-py calls wgpu-native through cffi in ABI mode. The first time a process uses a C type by its
name (``ffi.new("WGPUComputePassDescriptor *")``), cffi parses the name after a typedef line for
every type of wgpu's header: 15 to 45 ms per type on a 2-core Xeon, 0.8 s in all for the 56 types
that making the device, a detector and its first query use, which was 44% of the time from
``import pycinder`` to a first answer. :func:`preparse` parses the types of :data:`TYPES` as the
parameters of one function type (16 ms) and puts each in cffi's cache of parsed names: the very
objects cffi would have made one by one (``tests/test_startup.py`` checks that they are).

The cache is cffi's private ``FFI._parsed_types`` (a dict from the name to the pair
``(ctype, whether the name is a function type)``, unchanged since cffi 1.0). :func:`preparse`
checks what it relies on first and does nothing where that does not hold; the types are then
parsed one by one, as without it.
"""

from __future__ import annotations

from typing import Any

TYPES = (
    # Adapter, device and their callbacks.
    "WGPUInstanceDescriptor *", "WGPURequestAdapterOptions *", "WGPURequestAdapterCallbackInfo *",
    "WGPUAdapterInfo *", "WGPULimits *", "WGPUNativeLimits *", "WGPUDeviceDescriptor *",
    "WGPUDeviceExtras *", "WGPUQueueDescriptor *", "WGPUFeatureName[]",
    "WGPURequestDeviceCallbackInfo *", "WGPUDeviceLostCallbackInfo *",
    "WGPUUncapturedErrorCallbackInfo *", "WGPUChainedStruct *", "WGPUChainedStruct * ",
    "void(WGPURequestAdapterStatus, WGPUAdapter, WGPUStringView, void *, void *)",
    "void(WGPURequestDeviceStatus, WGPUDevice, WGPUStringView, void *, void *)",
    "void(WGPUDevice const *, WGPUDeviceLostReason, WGPUStringView, void *, void *)",
    "void(WGPUDevice const *, WGPUErrorType, WGPUStringView, void *, void *)",
    # Shaders, pipelines and bind groups.
    "WGPUShaderModuleDescriptor *", "WGPUShaderSourceWGSL *", "WGPUComputePipelineDescriptor *",
    "WGPUComputeState *", "WGPURenderPipelineDescriptor *", "WGPUVertexState *",
    "WGPUPrimitiveState *", "WGPUPrimitiveStateExtras *", "WGPUMultisampleState *",
    "WGPUFragmentState *", "WGPUColorTargetState *", "WGPUColorTargetState[]",
    "WGPUDepthStencilState *", "WGPUStencilFaceState *", "WGPUPipelineLayoutDescriptor *",
    "WGPUBindGroupLayoutDescriptor *", "WGPUBindGroupLayoutEntry *",
    "WGPUBindGroupLayoutEntry[]", "WGPUBindGroupLayout[]", "WGPUBufferBindingLayout *",
    "WGPUTextureBindingLayout *", "WGPUBindGroupDescriptor *", "WGPUBindGroupEntry *",
    "WGPUBindGroupEntry[]",
    # Buffers, textures, queries and their mapping.
    "WGPUBufferDescriptor *", "WGPUBufferMapCallbackInfo *",
    "void(WGPUMapAsyncStatus, WGPUStringView, void *, void *)", "WGPUTextureDescriptor *",
    "WGPUTextureViewDescriptor *", "WGPUTextureFormat[]", "WGPUExtent3D *", "WGPUOrigin3D *",
    "WGPUTexelCopyTextureInfo *", "WGPUQuerySetDescriptor *",
    # Commands.
    "WGPUCommandEncoderDescriptor *", "WGPUCommandBufferDescriptor *", "WGPUCommandBuffer[]",
    "WGPUComputePassDescriptor *", "WGPUPassTimestampWrites *", "WGPURenderPassDescriptor *",
    "WGPURenderPassColorAttachment *", "WGPURenderPassColorAttachment[]",
    "WGPURenderPassDepthStencilAttachment *", "WGPUColor *", "WGPURenderBundleDescriptor *",
    "WGPURenderBundleEncoderDescriptor *", "WGPURenderBundle[]",
    # Plain C types.
    "char []", "uint8_t *", "uint8_t []", "uint32_t []", "intptr_t", "uintptr_t", "void *",
)
"""The C types wgpu-py names on pycinder's paths (device, focused and scene strategies,
profiling, the GPU broad phase, the manager), as wgpu-py 0.32 spells them."""


def _parameter(name: str) -> tuple[str, str]:
    """``name`` as a parameter of a function type, and how to get its type back from the
    parameter's: "array" (a pointer to the array), "function" (a pointer to the function) or
    "same"."""
    bare = name.strip()
    if bare.endswith("[]"):
        return f"{bare[:-2].strip()} (*)[]", "array"
    if bare.startswith("void("):
        return f"void(*){bare[4:]}", "function"
    return bare, "same"


def preparse(ffi: Any = None, names: tuple[str, ...] = TYPES) -> int:
    """Put every type of ``names`` in cffi's cache of parsed names with one parse.

    Parameters
    ----------
    ffi : cffi.FFI, optional
        Default: wgpu-native's.
    names : tuple of str
        C type names, spelled as the callers spell them (the cache is keyed by the text).

    Returns
    -------
    int
        Types added to the cache (0 when cffi's cache is not what this relies on, or a name is
        not one of this wgpu's types).
    """
    if ffi is None:
        from wgpu.backends.wgpu_native import ffi
    cache = getattr(ffi, "_parsed_types", None)
    lock = getattr(ffi, "_lock", None)
    if not isinstance(cache, dict) or lock is None:
        return 0
    wanted = [name for name in names if name not in cache]
    if not wanted:
        return 0
    parameters = [_parameter(name) for name in wanted]
    try:
        function = ffi.typeof("void(*)(" + ", ".join(p for p, _ in parameters) + ")")
        found = []
        for (_, how), ctype in zip(parameters, function.args, strict=True):
            found.append(ctype.item if how == "array" else ctype)
    except Exception:  # a name this wgpu does not declare, or a cffi that differs
        return 0
    with lock:
        for name, (_, how), ctype in zip(wanted, parameters, found):
            cache.setdefault(name, (ctype, how == "function"))
    return len(wanted)


__all__ = ["TYPES", "preparse"]

"""Pipelines whose resources are bound by name, and a profiler shared by the passes of a frame.

A shader declares its bindings once (``@group(0) @binding(N) var<...> name``); :class:`Stage`
reads those declarations, so a pass binds ``{"tiles": ..., "counters": ...}`` by the names the
WGSL uses and never repeats a binding number. Bind groups are cached and rebuilt only when a
buffer behind them was replaced. The structs a stage's host writes (its parameters) are declared
in Python (:class:`~pycinder.gpu.structs.Struct`) and generated into its source.
"""

from __future__ import annotations

import re
import weakref
from collections.abc import Mapping
from typing import Any, Union

import numpy as np
import wgpu

from .buffers import GrowableBuffer
from .device import Gpu, shader_source
from .layout import ROW
from .structs import Struct, declarations

Resource = Union[wgpu.GPUBuffer, GrowableBuffer, tuple, wgpu.GPUTextureView, wgpu.GPUSampler]
"""A buffer, a growable buffer (its current buffer), ``(buffer, offset, size)``, a texture view
or a sampler."""

_BINDING = re.compile(r"@group\(0\)\s*@binding\((\d+)\)\s*var(?:<[^>]*>)?\s+(\w+)")
_DECLARATION = re.compile(
    r"@group\(0\)\s*@binding\((\d+)\)\s*var(?:<([^>]*)>)?\s+\w+\s*:\s*([A-Za-z_0-9]+(?:<\w+>)?)")
_SAMPLE_TYPES = {"u32": "uint", "i32": "sint", "f32": "float"}

PARAM_STRIDE = 256
"""Bytes between parameter blocks of one uniform buffer (WebGPU's uniform offset alignment)."""


def workgroup_grid(n: int) -> tuple[int, int]:
    """Workgroup grid (x, y) for ``n`` workgroups laid out in rows of :data:`ROW` (under
    WebGPU's 65,535 per dimension); a shader finds its workgroup as ``wg.y * ROW + wg.x``."""
    return min(n, ROW), -(-n // ROW)


def binding_numbers(source: str) -> dict[str, int]:
    """Binding number of every ``@group(0)`` variable declared in a WGSL source, by name."""
    return {name: int(number) for number, name in _BINDING.findall(source)}


def _layout_entry(number: int, space: str, wgsl_type: str, visibility: int) -> dict[str, Any]:
    """The bind group layout entry of one ``@group(0)`` declaration."""
    space = space.replace(" ", "")
    entry: dict[str, Any] = {"binding": number, "visibility": visibility}
    if space == "uniform":
        entry["buffer"] = {"type": wgpu.BufferBindingType.uniform}
    elif space == "storage,read_write":  # vertex shaders cannot write storage
        entry["buffer"] = {"type": wgpu.BufferBindingType.storage}
        entry["visibility"] = visibility & ~wgpu.ShaderStage.VERTEX
    elif space.startswith("storage"):
        entry["buffer"] = {"type": wgpu.BufferBindingType.read_only_storage}
    elif wgsl_type.startswith("texture_2d<"):
        entry["texture"] = {"sample_type": _SAMPLE_TYPES[wgsl_type[11:-1]]}
    elif wgsl_type == "sampler":
        entry["sampler"] = {"type": wgpu.SamplerBindingType.filtering}
    else:
        raise ValueError(f"binding {number}: cannot declare a layout for {wgsl_type!r}")
    return entry


def declared_layout_entries(source: str, visibility: int) -> list[dict[str, Any]]:
    """Bind group layout entries of every ``@group(0)`` variable declared in a WGSL source, each
    visible to the stages ``visibility`` (a writable storage buffer to the non-vertex ones)."""
    return [_layout_entry(int(n), space, t, visibility)
            for n, space, t in _DECLARATION.findall(source)]


def const_declarations(consts: Mapping[str, int | float]) -> str:
    """WGSL ``const`` declarations of ``consts``: ``u32`` for an int (0 to 2**32 - 1), ``f32``
    for a float (written exactly: the value must be a float32)."""
    lines = []
    for name, value in consts.items():
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            if not 0 <= value < 2 ** 32:
                raise ValueError(f"const {name} = {value} is not a u32")
            lines.append(f"const {name}: u32 = {int(value)}u;")
        elif isinstance(value, (float, np.floating)) and np.isfinite(value) \
                and float(np.float32(value)) == value:
            lines.append(f"const {name}: f32 = {float(value)!r};")
        else:
            raise ValueError(f"const {name} = {value!r} is not a u32 or a float32")
    return "".join(f"{line}\n" for line in lines)


class Stage:
    """One pipeline (compute, or render with ``render=``) and its bind groups by name.

    Parameters
    ----------
    gpu : Gpu
    shader : str
        The WGSL file (``shaders/<shader>.wgsl``).
    entry : str
        Compute entry point (ignored for render pipelines).
    render : dict, optional
        ``primitive`` and ``fragment`` targets of a render pipeline whose vertex and fragment
        entry points are ``vs`` and ``fs``.
    label : str
        What profiles and errors call it.
    structs : sequence of Struct
        Structs the shader uses that are declared with the pass (its parameters): their WGSL
        declarations are generated in front of the shader's source. Every stage of one shader
        file gives the same ones.
    consts : dict of str to int or float, optional
        Constants declared in Python and shared with the shader: generated in front of its
        source as ``const NAME: u32`` (an int) or ``const NAME: f32`` (a float). Every stage of
        one shader file gives the same ones.
    layout : {"auto", "declared"}
        ``"auto"``: the pipeline's own bind group layout (of the bindings its entry points use).
        ``"declared"``: one layout of every binding the shader declares, shared by every stage of
        the shader (with the same structs and constants) that asks for it, so one bind group
        serves all their pipelines (as a render bundle that switches pipelines needs).

    Notes
    -----
    ``render`` may also give ``vertex`` and ``fragment`` (entry points; default ``vs`` and
    ``fs``) and ``depth_stencil`` (the pipeline's depth-stencil state).
    """

    _cache: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
    """Per device (held weakly: a device made after a reset never meets a dead one's objects
    through a reused id): shader modules and declared layouts by what makes them."""

    def __init__(self, gpu: Gpu, shader: str, entry: str = "", *, render: dict | None = None,
                 label: str = "", structs: tuple[Struct, ...] = (),
                 consts: Mapping[str, int | float] | None = None,
                 layout: str = "auto") -> None:
        self.device = gpu.device
        self.label = label or f"{shader}: {entry}"
        source = shader_source(shader)
        if structs:
            source = declarations(structs) + source
        generated = const_declarations(consts or {})
        source = generated + source
        self.numbers = binding_numbers(source)
        self._device_cache = self._cache.setdefault(self.device, {})
        key = ("module", shader, tuple(s.wgsl() for s in structs), generated)
        module = self._device_cache.get(key)
        if module is None:
            module = self._device_cache[key] = self.device.create_shader_module(label=shader,
                                                                                code=source)
        self.bind_layout: wgpu.GPUBindGroupLayout | None = None
        pipeline_layout: Any = "auto"
        if layout == "declared":
            self.bind_layout, pipeline_layout = self._declared_layout(key, source, render is None)
        elif layout != "auto":
            raise ValueError(f"unknown layout {layout!r}")
        if render is None:
            self.pipeline = self.device.create_compute_pipeline(
                label=self.label, layout=pipeline_layout,
                compute={"module": module, "entry_point": entry})
        else:
            extra = {"depth_stencil": render["depth_stencil"]} if "depth_stencil" in render else {}
            self.pipeline = self.device.create_render_pipeline(
                label=self.label, layout=pipeline_layout,
                vertex={"module": module, "entry_point": render.get("vertex", "vs")},
                primitive=render["primitive"],
                fragment={"module": module, "entry_point": render.get("fragment", "fs"),
                          "targets": render["targets"]}, **extra)
        if self.bind_layout is None:
            self.bind_layout = self.pipeline.get_bind_group_layout(0)
        self._groups: dict[str, tuple[tuple, wgpu.GPUBindGroup]] = {}

    def _declared_layout(self, key: tuple, source: str, compute: bool
                         ) -> tuple[wgpu.GPUBindGroupLayout, wgpu.GPUPipelineLayout]:
        """The bind group layout of every binding of ``source`` and its pipeline layout, made
        once per shader module and kind of pipeline."""
        key = ("layout", *key[1:], compute)
        cache = self._device_cache
        if key not in cache:
            stages = wgpu.ShaderStage
            visibility = stages.COMPUTE if compute else stages.VERTEX | stages.FRAGMENT
            bind_layout = self.device.create_bind_group_layout(
                label=self.label, entries=declared_layout_entries(source, visibility))
            cache[key] = (bind_layout, self.device.create_pipeline_layout(
                bind_group_layouts=[bind_layout]))
        return cache[key]

    def group(self, key: str = "", /, **resources: Resource) -> wgpu.GPUBindGroup:
        """The bind group of ``resources`` (buffers, texture views, samplers) by binding name
        (cached under ``key``).

        Every binding the pipeline uses must be given; names the shader does not declare are an
        error (a renamed binding is caught at once)."""
        resolved = tuple(r.buffer if type(r) is GrowableBuffer else r
                         for r in resources.values())
        cached = self._groups.get(key)
        # The cache holds the resources themselves (an id alone can be reused by a new buffer
        # once a grown one is freed), compared as a tuple: wgpu-py's objects by identity, a
        # binding's (buffer, offset, size) by its buffer's identity and its numbers.
        if cached is not None and cached[0] == resolved:
            return cached[1]
        unknown = set(resources) - set(self.numbers)
        if unknown:
            raise KeyError(f"{self.label} declares no binding {sorted(unknown)}")
        entries = []
        for name, resource in zip(resources, resolved):
            if isinstance(resource, tuple):
                buffer, offset, size = resource
                entry: Any = {"buffer": buffer, "offset": offset, "size": size}
            elif isinstance(resource, (wgpu.GPUTextureView, wgpu.GPUSampler)):
                entry = resource
            else:
                entry = {"buffer": resource}
            entries.append({"binding": self.numbers[name], "resource": entry})
        group = self.device.create_bind_group(layout=self.bind_layout, entries=entries)
        self._groups[key] = (resolved, group)
        return group


def dispatch(cpass: wgpu.GPUComputePassEncoder, stage: Stage, group: wgpu.GPUBindGroup,
             workgroups: int | None = None, *, indirect: tuple | None = None) -> None:
    """One dispatch of ``stage``: ``workgroups`` workgroups (laid out by
    :func:`workgroup_grid`), or the indirect arguments ``(buffer, offset)``."""
    cpass.set_pipeline(stage.pipeline)
    cpass.set_bind_group(0, group)
    if indirect is not None:
        cpass.dispatch_workgroups_indirect(*indirect)
    else:
        cpass.dispatch_workgroups(*workgroup_grid(workgroups))


class Profiler:
    """Timestamps of every timed pass of a frame, every round included.

    Only the queries written in the frame are resolved (resolving a query never written makes
    some drivers wait for it for ever), and their values travel in the frame's one readback.

    Parameters
    ----------
    gpu : Gpu
    enabled : bool
        Time passes (only where the adapter supports timestamp queries).
    """

    def __init__(self, gpu: Gpu, enabled: bool) -> None:
        self.device = gpu.device
        self.enabled = enabled and gpu.timestamps
        self.query_set: wgpu.GPUQuerySet | None = None
        self.capacity = 0
        self.names: list[str] = []
        self.resolved: wgpu.GPUBuffer | None = None

    def begin(self, passes: int) -> None:
        """Start a frame of at most ``passes`` timed passes."""
        self.names = []
        if not self.enabled or passes <= self.capacity:
            return
        self.capacity = max(passes, 2 * self.capacity, 16)
        self.query_set = self.device.create_query_set(type="timestamp", count=2 * self.capacity)
        self.resolved = self.device.create_buffer(
            label="timestamps", size=16 * self.capacity,
            usage=wgpu.BufferUsage.QUERY_RESOLVE | wgpu.BufferUsage.COPY_SRC)

    def writes(self, name: str) -> dict[str, Any]:
        """Keyword arguments of ``begin_*_pass`` that time a pass called ``name``."""
        if not self.enabled:
            return {}
        if len(self.names) >= self.capacity:
            raise RuntimeError("more timed passes than the profiler was begun with")
        i = 2 * len(self.names)
        self.names.append(name)
        return {"timestamp_writes": {"query_set": self.query_set,
                                     "beginning_of_pass_write_index": i,
                                     "end_of_pass_write_index": i + 1}}

    @property
    def nbytes(self) -> int:
        return 16 * len(self.names)

    def resolve(self, encoder: wgpu.GPUCommandEncoder, staging: wgpu.GPUBuffer,
                offset: int) -> None:
        """Resolve the written queries and copy them to ``staging`` at ``offset``."""
        if not self.names:
            return
        n = 2 * len(self.names)
        encoder.resolve_query_set(self.query_set, 0, n, self.resolved, 0)
        encoder.copy_buffer_to_buffer(self.resolved, 0, staging, offset, 8 * n)

    def times(self, words: np.ndarray, names: list[str] | None = None) -> dict[str, float]:
        """Milliseconds per pass name (summed over rounds) from the resolved words (uint32) of
        the passes ``names`` (default: this frame's)."""
        names = self.names if names is None else names
        if not names:
            return {}
        ts = words[:4 * len(names)].view(np.uint64).astype(np.float64).reshape(-1, 2)
        out: dict[str, float] = {}
        for name, (start, end) in zip(names, ts):
            out[name] = out.get(name, 0.0) + max(end - start, 0.0) * 1e-6
        return out


__all__ = ["PARAM_STRIDE", "Profiler", "Stage", "binding_numbers", "const_declarations", "dispatch",
           "workgroup_grid"]

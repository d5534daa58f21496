"""The floor of a query's host CPU through wgpu-py: what the least a GPU-resident query must do
costs the host, whatever pycinder does around it.

A GPU-resident query (issue "the GPU-resident query") uploads what changed, encodes one command
buffer, submits it once and maps one compact answer. This measures exactly that skeleton, with
nothing of pycinder's around it, on the device pycinder would use:

* ``queue.write_buffer`` of ``bodies`` transforms (N x 3 x 4 float32),
* one command encoder with one compute pass of ``dispatches`` dispatches of a trivial shader
  (each ``set_pipeline``, ``set_bind_group`` and ``dispatch_workgroups_indirect``: the calls a
  pass of a fixed frame makes), and optionally one render pass that replays a render bundle
  recorded once (``bundle``),
* a copy of the answer (``answer_bytes``) into a staging buffer, ``finish``, one ``submit``,
* ``map_async`` of the staging buffer, the wait (with a deadline, as pycinder waits), reading and
  ``unmap``;

through wgpu-py's methods, or (``direct``) with the passes, the copy and the map through
wgpu-native's C functions, as pycinder records its frames (:mod:`pycinder.gpu.native`).

Pipelines, bind groups, buffers and the bundle are made once, as the brief asks. The figure is
the same as :mod:`pycinder.benchmarks.hostcpu`'s: the CPU time of every Python thread of the
process (the calling thread and wgpu-py's poll thread), per query, median over batches. Run::

    python -m pycinder.benchmarks.hostfloor
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from .hostcpu import (count_wgpu_calls, cpu_by_group, cpu_ms, python_thread_clocks,
                      summarise_calls)

SHADER = """
struct Params { count: u32, pad0: u32, pad1: u32, pad2: u32 }
@group(0) @binding(0) var<storage, read> transforms: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> answer: array<atomic<u32>>;
@group(0) @binding(2) var<uniform> params: Params;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x < params.count) {
        let t = transforms[id.x * 3u];
        if (t.x != t.x) { atomicAdd(&answer[0], 1u); }   // a NaN: never, but not foldable
        atomicMax(&answer[1], id.x);
    }
}
"""

DRAW = """
@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    return vec4<f32>(f32(i & 1u), f32(i >> 1u), 0.5, 1.0);
}
@fragment fn fs() -> @location(0) vec4<u32> { return vec4<u32>(1u, 2u, 3u, 4u); }
"""

CONFIGS = ((2, 1, False, 64, True, False), (2, 1, False, 64, False, False),
           (2, 8, False, 64, True, False), (2, 32, False, 64, True, False),
           (2, 32, False, 64, False, False), (1000, 32, False, 64, True, False),
           (1000, 32, True, 64, True, False), (1000, 32, True, 65536, True, False),
           (2, 1, False, 64, True, True), (2, 8, False, 64, True, True),
           (2, 32, False, 64, True, True), (1000, 32, True, 65536, True, True))
"""(bodies, dispatches, bundle, answer bytes, watched, direct): a two-body query of the fewest
passes, fixed frames of 8 and 32 compute passes, then 1000 bodies' transforms, a render pass
replaying a bundle, and a 64 KiB answer; on pycinder's device (watched: every submission noted
and followed by a marker copy, :mod:`pycinder.gpu.watch`) or on a device of the same adapter
without it; through wgpu-py, or (direct) with the compute pass, the copy and the map recorded
through wgpu-native's C functions as pycinder records them (:mod:`pycinder.gpu.native`)."""


class Skeleton:
    """The objects a GPU-resident query keeps from one query to the next, made once.

    Parameters
    ----------
    device : wgpu.GPUDevice
    bodies : int
        Transforms uploaded per query.
    dispatches : int
        Compute dispatches per query (each with its own bind group, as a frame's passes have).
    bundle : bool
        Also one render pass replaying a render bundle recorded here.
    answer_bytes : int
        Bytes copied out and mapped per query.
    """

    def __init__(self, device: Any, bodies: int, dispatches: int, bundle: bool,
                 answer_bytes: int) -> None:
        import wgpu

        self.device, self.queue = device, device.queue
        usage = wgpu.BufferUsage
        self.transforms = np.zeros((bodies, 3, 4), np.float32)
        self.transforms[:, :3, :3] = np.eye(3)
        self.upload = device.create_buffer(size=max(self.transforms.nbytes, 16),
                                           usage=usage.STORAGE | usage.COPY_DST)
        self.answer = device.create_buffer(size=answer_bytes,
                                           usage=usage.STORAGE | usage.COPY_SRC | usage.COPY_DST)
        self.staging = device.create_buffer(size=answer_bytes,
                                            usage=usage.MAP_READ | usage.COPY_DST)
        self.answer_bytes = answer_bytes
        params = np.array([bodies, 0, 0, 0], np.uint32)
        self.params = device.create_buffer_with_data(data=params, usage=usage.UNIFORM)
        groups = np.array([max((bodies + 63) // 64, 1), 1, 1], np.uint32)
        self.indirect = device.create_buffer_with_data(data=groups, usage=usage.INDIRECT)
        module = device.create_shader_module(code=SHADER)
        self.pipeline = device.create_compute_pipeline(
            layout="auto", compute={"module": module, "entry_point": "main"})
        layout = self.pipeline.get_bind_group_layout(0)
        entries = [{"binding": 0, "resource": {"buffer": self.upload}},
                   {"binding": 1, "resource": {"buffer": self.answer}},
                   {"binding": 2, "resource": {"buffer": self.params}}]
        self.bind_groups = [device.create_bind_group(layout=layout, entries=entries)
                            for _ in range(dispatches)]
        self.render: tuple[Any, Any] | None = None
        if bundle:
            fmt = wgpu.TextureFormat.rgba32uint
            target = device.create_texture(size=(64, 64, 1), format=fmt,
                                           usage=wgpu.TextureUsage.RENDER_ATTACHMENT)
            draw = device.create_shader_module(code=DRAW)
            pipeline = device.create_render_pipeline(
                layout="auto", vertex={"module": draw, "entry_point": "vs"},
                fragment={"module": draw, "entry_point": "fs", "targets": [{"format": fmt}]},
                primitive={"topology": "triangle-strip"})
            recorder = device.create_render_bundle_encoder(color_formats=[fmt])
            recorder.set_pipeline(pipeline)
            recorder.draw(4)
            self.render = (target.create_view(), recorder.finish())

    def query(self, timeout: float = 10.0, direct: bool = False) -> np.ndarray:
        """One query: upload, encode, submit, map and read the answer (uint32); ``direct``:
        the compute pass, the copy and the map through wgpu-native's C functions, as pycinder
        records them (:mod:`pycinder.gpu.native`)."""
        import wgpu

        from ..gpu import native
        from ..gpu.watch import wait_for

        self.queue.write_buffer(self.upload, 0, self.transforms)
        encoder = native.encoder(self.device) if direct else self.device.create_command_encoder()
        compute = encoder.begin_compute_pass()
        for group in self.bind_groups:
            compute.set_pipeline(self.pipeline)
            compute.set_bind_group(0, group)
            compute.dispatch_workgroups_indirect(self.indirect, 0)
        compute.end()
        if self.render is not None:
            view, bundle = self.render
            draw = encoder.begin_render_pass(color_attachments=[{
                "view": view, "load_op": wgpu.LoadOp.clear, "store_op": wgpu.StoreOp.store,
                "clear_value": (0, 0, 0, 0)}])
            draw.execute_bundles([bundle])
            draw.end()
        encoder.copy_buffer_to_buffer(self.answer, 0, self.staging, 0, self.answer_bytes)
        self.queue.submit([encoder.finish()])
        pending = native.map_read(self.device, self.staging, self.answer_bytes) if direct \
            else None
        if pending is not None:
            if not wait_for(pending, timeout):
                pending.abandon()
                raise TimeoutError(f"the GPU did not answer within {timeout} s")
            return pending.read(np.uint32)
        promise = self.staging.map_async(wgpu.MapMode.READ, 0, self.answer_bytes)
        if not wait_for(promise, timeout):
            raise TimeoutError(f"the GPU did not answer within {timeout} s")
        promise.sync_wait()
        out = np.frombuffer(self.staging.read_mapped(0, self.answer_bytes), np.uint32).copy()
        self.staging.unmap()
        return out


_RAW: list[Any] = []


def _raw_device() -> Any:
    """A device of pycinder's adapter without :mod:`pycinder.gpu.watch` (made once)."""
    from ..gpu.device import get_gpu

    if not _RAW:
        _RAW.append(get_gpu().adapter.request_device_sync())
    return _RAW[0]


def measure(bodies: int, dispatches: int, bundle: bool, answer_bytes: int,
            watched: bool = True, direct: bool = False, *, batches: int = 9,
            per_batch: int = 20) -> dict[str, Any]:
    """Host CPU per query of a :class:`Skeleton` (median over ``batches`` of ``per_batch``
    queries' mean, after a warm-up), by thread group, with its wall time and wgpu-py calls
    (pycinder's device where ``watched``, else one of its adapter without the watch; through
    the C functions where ``direct``).

    Returns
    -------
    dict
        ``bodies``, ``dispatches``, ``bundle``, ``answer_bytes``, ``watched``, ``direct``,
        ``cpu_ms``, ``main_ms``, ``other_ms`` (Python threads other than the calling one:
        wgpu-py's poll thread), ``wall_ms``, ``calls`` (GPU API calls per query: wgpu-py's
        methods and the C functions called directly, the watch's own included) and
        ``direct_calls`` (the latter alone).
    """
    from ..gpu.device import get_gpu

    device = get_gpu().device if watched else _raw_device()
    skeleton = Skeleton(device, bodies, dispatches, bundle, answer_bytes)
    for _ in range(5):
        skeleton.query(direct=direct)
    cpu, main, other, wall = [], [], [], []
    for _ in range(batches):
        before, t0 = python_thread_clocks(), time.perf_counter()
        for _ in range(per_batch):
            skeleton.query(direct=direct)
        after, t1 = python_thread_clocks(), time.perf_counter()
        groups = cpu_by_group(before, after)
        cpu.append(cpu_ms(before, after) / per_batch)
        main.append(groups.get("main", 0.0) / per_batch)
        other.append(groups.get("other Python threads", 0.0) / per_batch)
        wall.append((t1 - t0) * 1e3 / per_batch)
    with count_wgpu_calls(device) as counts:
        skeleton.query(direct=direct)
    calls = summarise_calls(counts, 1)
    return {"bodies": bodies, "dispatches": dispatches, "bundle": bundle,
            "answer_bytes": answer_bytes, "watched": watched, "direct": direct,
            "cpu_ms": statistics.median(cpu),
            "main_ms": statistics.median(main), "other_ms": statistics.median(other),
            "wall_ms": statistics.median(wall), "calls": calls["wgpu_calls"],
            "direct_calls": calls["direct_calls"]}


def markdown_lines(rows: Sequence[dict[str, Any]], adapter: str) -> list[str]:
    """The rows as a Markdown table, with the adapter."""
    lines = [f"Adapter: {adapter}.", "",
             "| bodies | compute dispatches | render bundle | answer bytes | watched device | "
             "C functions direct | host CPU ms/query | calling thread ms | "
             "other Python threads ms | wall ms | GPU API calls (C direct) |",
             "|---:|---:|---|---:|---|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        yes = {True: "yes", False: "no"}
        lines.append(f"| {r['bodies']:,} | {r['dispatches']} | {yes[r['bundle']]} | "
                     f"{r['answer_bytes']:,} | {yes[r['watched']]} | {yes[r['direct']]} | "
                     f"{r['cpu_ms']:.3f} | {r['main_ms']:.3f} | {r['other_ms']:.3f} | "
                     f"{r['wall_ms']:.3f} | {r['calls']:g} ({r['direct_calls']:g}) |")
    return lines


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m pycinder.benchmarks.hostfloor",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--batches", type=int, default=9)
    parser.add_argument("--per-batch", type=int, default=20)
    args = parser.parse_args(argv)
    from ..gpu.device import get_gpu

    rows = [measure(*config, batches=args.batches, per_batch=args.per_batch)
            for config in CONFIGS]
    print("\n".join(markdown_lines(rows, get_gpu().description)))


if __name__ == "__main__":
    main()

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

A frame makes more kinds of commands than that: compute passes, render passes, clears, copies,
several writes, and with the GPU planner a second submission and map. A :class:`CommandShape`
counts them, kind by kind; the skeleton makes a query of any shape (its render passes draw
without a bundle, as a frame's do). ``--scenes`` measures, beside each of
:mod:`~benchmarks.hostcpu`'s scenes' host CPU, the floor of a query of the shape its
own queries have (:meth:`CommandShape.of_calls` of their counted calls), and the same in one
submission; ``--costs``, what one more command of each kind adds to the least query, and the
least CInDeR frame (:data:`MINIMAL_FRAME`).

Pipelines, bind groups, buffers and the bundle are made once, as pycinder makes its own. The
figure is the same as :mod:`benchmarks.hostcpu`'s: the CPU time of every Python thread
of the process (the calling thread and wgpu-py's poll thread), per query, median over batches.
Run::

    python -m benchmarks.hostfloor
    python -m benchmarks.hostfloor --scenes [SCENE ...] [--planners numpy gpu]
    python -m benchmarks.hostfloor --costs
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, replace
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


@dataclass(frozen=True)
class CommandShape:
    """What one query asks of the GPU API, kind by kind: a query of this shape has this floor
    (:func:`measure` with ``shape``), whatever the work of its passes.

    Attributes
    ----------
    submissions : int
        Command buffers submitted one after the other, each ending with a copy of the answer
        and its map, waited for before the next is encoded (as the GPU planner's plan is
        before the frame).
    compute_passes, dispatches : int
        Compute passes, and their dispatches (each a pipeline, a bind group and an indirect
        dispatch) shared out among them; the passes are split among the submissions in
        order.
    render_passes : int
        Render passes of one attachment, each a pipeline and a draw (in the last submission).
    clears, copies : int
        Buffer clears and buffer-to-buffer copies (besides each submission's answer), in the
        last submission.
    writes : int
        ``queue.write_buffer`` calls before the first submission (the transforms' first).
    """

    submissions: int = 1
    compute_passes: int = 1
    dispatches: int = 1
    render_passes: int = 0
    clears: int = 0
    copies: int = 0
    writes: int = 1

    def __post_init__(self) -> None:
        counts = vars(self)
        if any(n < 0 for n in counts.values()) or self.submissions < 1 or self.writes < 1 \
                or (self.dispatches and not self.compute_passes):
            raise ValueError(f"a query of {counts}: counts of at least 0, at least one submission "
                             "and one write, and a compute pass for any dispatch")

    @classmethod
    def of_calls(cls, by_method: Mapping[str, float]) -> CommandShape:
        """The shape of a query whose GPU API calls per query are ``by_method`` (as
        :func:`~benchmarks.hostcpu.summarise_calls` gives them: wgpu-py's methods,
        and ``"C name"`` for the C functions called directly). The device watch's own calls (a
        marker copy per submission, :mod:`pycinder.gpu.watch`) are left out: the skeleton's
        device makes them too. The calls must be those of a watched wgpu-native device's
        queries (the watch's marker written through the C functions), each submission with
        one map and a copy of its answer: ValueError otherwise. Counts are per query (an
        average over several queries is rounded)."""
        def n(*names: str) -> int:
            return round(sum(by_method.get(k, 0.0) for k in names))

        submissions = max(n("GPUQueue.submit"), 1)
        maps = n("C wgpuBufferMapAsync", *(k for k in by_method if k.startswith("GPUBuffer.map")))
        markers = n("C wgpuQueueWriteBuffer")
        # Each submission's marker copy is the watch's, and one copy is its answer's.
        copies = n("C wgpuCommandEncoderCopyBufferToBuffer",
                   "GPUCommandEncoder.copy_buffer_to_buffer") - 2 * submissions
        if maps != submissions or markers != submissions or copies < 0:
            raise ValueError(f"{submissions} submissions with {maps} maps, {markers} marker "
                             f"writes and {copies + 2 * submissions} copies: not the calls of "
                             "a watched wgpu-native device's queries, one map and one answer "
                             "copy a submission")
        return cls(submissions=submissions,
                   compute_passes=n("C wgpuCommandEncoderBeginComputePass",
                                    "GPUCommandEncoder.begin_compute_pass"),
                   dispatches=n("C wgpuComputePassEncoderDispatchWorkgroups",
                                "C wgpuComputePassEncoderDispatchWorkgroupsIndirect",
                                "GPUComputePassEncoder.dispatch_workgroups",
                                "GPUComputePassEncoder.dispatch_workgroups_indirect"),
                   render_passes=n("C wgpuCommandEncoderBeginRenderPass",
                                   "GPUCommandEncoder.begin_render_pass"),
                   clears=n("C wgpuCommandEncoderClearBuffer", "GPUCommandEncoder.clear_buffer"),
                   copies=copies, writes=max(n("GPUQueue.write_buffer"), 1))


class Skeleton:
    """The objects a GPU-resident query keeps from one query to the next, made once.

    Parameters
    ----------
    device : wgpu.GPUDevice
    bodies : int
        Transforms uploaded per query.
    dispatches : int
        Compute dispatches per query, in one compute pass (each with its own bind group, as a
        frame's passes have).
    bundle : bool
        Also one render pass replaying a render bundle recorded here.
    answer_bytes : int
        Bytes copied out and mapped per query.
    shape : CommandShape, optional
        Instead of ``dispatches`` and ``bundle``: a query of this shape (its render passes draw
        without a bundle, as a frame's do).
    """

    def __init__(self, device: Any, bodies: int, dispatches: int, bundle: bool,
                 answer_bytes: int, shape: CommandShape | None = None) -> None:
        import wgpu

        self.bundle = shape is None and bundle
        """The render pass replays a bundle (else each render pass draws)."""
        self.shape = shape or CommandShape(dispatches=dispatches, render_passes=int(bundle))
        self.device, self.queue = device, device.queue
        usage = wgpu.BufferUsage
        self.transforms = np.zeros((bodies, 3, 4), np.float32)
        self.transforms[:, :3, :3] = np.eye(3)
        self.upload = device.create_buffer(size=max(self.transforms.nbytes, 16),
                                           usage=usage.STORAGE | usage.COPY_DST)
        self.answer = device.create_buffer(size=answer_bytes,
                                           usage=usage.STORAGE | usage.COPY_SRC | usage.COPY_DST)
        self.stagings = [device.create_buffer(size=answer_bytes,
                                              usage=usage.MAP_READ | usage.COPY_DST)
                         for _ in range(self.shape.submissions)]
        """A staging buffer per submission, each mapped before the next is encoded."""
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
                            for _ in range(self.shape.dispatches)]
        self.render: tuple[Any, Any] | None = None
        if self.shape.render_passes:
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
            self.draw_pipeline = pipeline
        # What the shape's clears and copies work on (not the answer).
        self.scratch = [device.create_buffer(size=64, usage=usage.COPY_SRC | usage.COPY_DST)
                        for _ in range(2)]

    def query(self, timeout: float = 10.0, direct: bool = False) -> np.ndarray:
        """One query of :attr:`shape`: its writes, then each submission encoded, submitted and
        its answer mapped and read before the next; the last one's answer (uint32) is returned.
        ``direct``: the passes, clears, copies and maps through wgpu-native's C functions, as
        pycinder records them (:mod:`pycinder.gpu.native`)."""
        from pycinder.gpu import native

        shape = self.shape
        for _ in range(shape.writes):
            self.queue.write_buffer(self.upload, 0, self.transforms)
        # Dispatches shared out among the compute passes, the passes among the submissions.
        per_pass = np.array_split(np.arange(shape.dispatches), max(shape.compute_passes, 1))
        dealt = np.array_split(np.arange(shape.compute_passes), shape.submissions)
        answer = np.zeros(0, np.uint32)
        for k, passes in enumerate(dealt):
            encoder = native.encoder(self.device) if direct else \
                self.device.create_command_encoder()
            for p in passes.tolist():
                compute = encoder.begin_compute_pass()
                for d in per_pass[p].tolist():
                    compute.set_pipeline(self.pipeline)
                    compute.set_bind_group(0, self.bind_groups[d])
                    compute.dispatch_workgroups_indirect(self.indirect, 0)
                compute.end()
            if k == shape.submissions - 1:
                for _ in range(shape.render_passes):
                    self._render_pass(encoder)
                for _ in range(shape.clears):
                    encoder.clear_buffer(self.scratch[0], 0, 16)
                for _ in range(shape.copies):
                    encoder.copy_buffer_to_buffer(self.scratch[0], 0, self.scratch[1], 0, 16)
            staging = self.stagings[k]
            encoder.copy_buffer_to_buffer(self.answer, 0, staging, 0, self.answer_bytes)
            self.queue.submit([encoder.finish()])
            pending = native.map_read(self.device, staging, self.answer_bytes) if direct \
                else None
            answer = self._read(staging, timeout, pending)
        return answer

    def _render_pass(self, encoder: Any) -> None:
        """One render pass: the bundle replayed (:attr:`bundle`), else a pipeline and a draw."""
        view, bundle = self.render
        if self.bundle:
            draw = encoder.begin_render_pass(color_attachments=[{
                "view": view, "load_op": "clear", "store_op": "store",
                "clear_value": (0, 0, 0, 0)}])
            draw.execute_bundles([bundle])
        else:
            draw = encoder.begin_render_pass(color_attachments=[{
                "view": view, "load_op": "load", "store_op": "discard"}])
            draw.set_pipeline(self.draw_pipeline)
            draw.draw(4)
        draw.end()

    def _read(self, staging: Any, timeout: float, pending: Any = None) -> np.ndarray:
        """Wait at most ``timeout`` seconds for the answer copied into ``staging`` (its map
        asked for through the C functions: ``pending``; else mapped here through wgpu-py)."""
        import wgpu

        from pycinder.gpu.watch import wait_for

        if pending is not None:
            if not wait_for(pending, timeout):
                pending.abandon()
                raise TimeoutError(f"the GPU did not answer within {timeout} s")
            return pending.read(np.uint32)
        promise = staging.map_async(wgpu.MapMode.READ, 0, self.answer_bytes)
        if not wait_for(promise, timeout):
            raise TimeoutError(f"the GPU did not answer within {timeout} s")
        promise.sync_wait()
        out = np.frombuffer(staging.read_mapped(0, self.answer_bytes), np.uint32).copy()
        staging.unmap()
        return out


_RAW: list[Any] = []


def _raw_device() -> Any:
    """A device of pycinder's adapter without :mod:`pycinder.gpu.watch` (made once)."""
    from pycinder.gpu.device import get_gpu

    if not _RAW:
        _RAW.append(get_gpu().adapter.request_device_sync())
    return _RAW[0]


def measure(bodies: int, dispatches: int, bundle: bool, answer_bytes: int,
            watched: bool = True, direct: bool = False, *, batches: int = 9,
            per_batch: int = 20, shape: CommandShape | None = None) -> dict[str, Any]:
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
    from pycinder.gpu.device import get_gpu

    device = get_gpu().device if watched else _raw_device()
    skeleton = Skeleton(device, bodies, dispatches, bundle, answer_bytes, shape)
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
    return {"bodies": bodies, "dispatches": skeleton.shape.dispatches, "bundle": skeleton.bundle,
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


def scene_floors(names: Sequence[str] | None = None, planners: Sequence[str] = ("numpy", "gpu"),
                 *, repeats: int = 5, batches: int = 9, per_batch: int = 20
                 ) -> list[dict[str, Any]]:
    """Per scene of :data:`~benchmarks.hostcpu.CASES` (``names``, default all) and
    planner: its host CPU per query (:func:`benchmarks.hostcpu.measure`, ``repeats``
    batches), the shape of its GPU API calls (:meth:`CommandShape.of_calls`), and the floor of a
    query of that shape on pycinder's device through the C functions (:func:`measure`): as it
    is (``floor_ms``), and with every command in one submission (``one_submission_ms``).

    The floor's writes are of the transforms' size (a deforming scene's vertex uploads cost
    more than that), and its answer is the scene's per-pair flags' size."""
    from .hostcpu import CASES
    from .hostcpu import measure as measure_scene

    rows = []
    for name in names or list(CASES):
        for row in measure_scene(CASES[name], planners, repeats=repeats, stages=False):
            shape = CommandShape.of_calls(row["by_method"])
            answer = max(64, -(-4 * row["candidates"] // 16) * 16)
            floors = [measure(max(row["bodies"], 1), 0, False, answer, True, True,
                              batches=batches, per_batch=per_batch, shape=s)["cpu_ms"]
                      for s in (shape, replace(shape, submissions=1))]
            rows.append({**{k: row[k] for k in ("scene", "planner", "target_ms",
                                                 "host_cpu_ms", "wall_ms")},
                         "shape": asdict(shape), "floor_ms": floors[0],
                         "one_submission_ms": floors[1]})
    return rows


def scene_lines(rows: Sequence[dict[str, Any]], adapter: str) -> list[str]:
    """:func:`scene_floors`' rows as a Markdown table, with the adapter."""
    fields = ("submissions", "compute_passes", "dispatches", "render_passes", "clears",
              "copies", "writes")
    lines = [f"Adapter: {adapter}.", "",
             "| scene | planner | host CPU ms/query | target ms | floor of its commands ms | "
             "the same in one submission ms | above the floor ms | "
             + " | ".join(f.replace("_", " ") for f in fields) + " |",
             "|---|---|" + "---:|" * (5 + len(fields))]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['planner']} | {r['host_cpu_ms']:.2f} | "
                     f"{r['target_ms']:g} | {r['floor_ms']:.3f} | {r['one_submission_ms']:.3f} | "
                     f"{r['host_cpu_ms'] - r['floor_ms']:.2f} | "
                     + " | ".join(str(r["shape"][f]) for f in fields) + " |")
    return lines


MINIMAL_FRAME = CommandShape(compute_passes=3, dispatches=6, render_passes=1, clears=1)
"""The fewest commands a CInDeR frame of one round can make: a cull, the crossings drawn in one
render pass, the tests after it (three compute passes with six dispatches among them: the
passes' own and the indirect arguments between them), one clear of the per-pixel counts, one
submission and one map."""


def command_costs(*, repeats: int = 3, batches: int = 9, per_batch: int = 30
                  ) -> list[dict[str, Any]]:
    """The floor of the least query (one write, one compute pass of one dispatch, one
    submission, one map: :class:`CommandShape`'s defaults), then of the same with more of one
    kind of command, through the C functions on pycinder's device, and of
    :data:`MINIMAL_FRAME`: ``name``, ``shape``, ``cpu_ms`` and ``main_ms`` (the calling
    thread's), each the median over ``repeats`` rounds of :func:`measure` (the variants
    alternate within a round), and ``each_ms``: what one more command of that kind costs."""
    base = CommandShape()
    variants = [("the least query", base, 0),
                ("8 more dispatches in its pass", replace(base, dispatches=9), 8),
                ("8 more compute passes, a dispatch each",
                 replace(base, compute_passes=9, dispatches=9), 8),
                ("4 render passes, a draw each", replace(base, render_passes=4), 4),
                ("8 buffer clears", replace(base, clears=8), 8),
                ("8 buffer copies", replace(base, copies=8), 8),
                ("8 more writes", replace(base, writes=9), 8),
                ("a second submission and map (a pass and a dispatch in it)",
                 replace(base, submissions=2, compute_passes=2, dispatches=2), 1),
                ("the least CInDeR frame (MINIMAL_FRAME)", MINIMAL_FRAME, 0)]
    runs: dict[str, list[tuple[float, float]]] = {name: [] for name, _, _ in variants}
    for _ in range(repeats):
        for name, shape, _ in variants:
            r = measure(2, 0, False, 64, True, True, batches=batches, per_batch=per_batch,
                        shape=shape)
            runs[name].append((r["cpu_ms"], r["main_ms"]))
    rows = []
    for name, shape, more in variants:
        cpu = statistics.median(c for c, _ in runs[name])
        rows.append({"name": name, "shape": asdict(shape), "cpu_ms": cpu,
                     "main_ms": statistics.median(m for _, m in runs[name]),
                     "each_ms": (cpu - rows[0]["cpu_ms"]) / more if more else None})
    return rows


def cost_lines(rows: Sequence[dict[str, Any]], adapter: str) -> list[str]:
    """:func:`command_costs`' rows as a Markdown table, with the adapter."""
    lines = [f"Adapter: {adapter}.", "",
             "| query | host CPU ms/query | calling thread ms | each one more ms |",
             "|---|---:|---:|---:|"]
    for r in rows:
        each = f"{r['each_ms']:.4f}" if r["each_ms"] is not None else ""
        lines.append(f"| {r['name']} | {r['cpu_ms']:.3f} | {r['main_ms']:.3f} | {each} |")
    return lines


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.hostfloor",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--batches", type=int, default=9)
    parser.add_argument("--per-batch", type=int, default=20)
    instead = parser.add_mutually_exclusive_group()
    instead.add_argument("--scenes", nargs="*", default=None,
                         help="instead: the floor of each hostcpu scene's commands (no name: "
                              "every scene), beside the scene's host CPU")
    instead.add_argument("--costs", action="store_true",
                         help="instead: what each kind of command adds to the least query")
    parser.add_argument("--planners", nargs="*", default=["numpy", "gpu"],
                        help="with --scenes: the planners")
    args = parser.parse_args(argv)
    from pycinder.gpu.device import get_gpu

    if args.costs:
        rows = command_costs(batches=args.batches, per_batch=args.per_batch)
        print("\n".join(cost_lines(rows, get_gpu().description)))
        return

    if args.scenes is not None:
        rows = scene_floors(args.scenes, args.planners, batches=args.batches,
                            per_batch=args.per_batch)
        print("\n".join(scene_lines(rows, get_gpu().description)))
        return
    rows = [measure(*config, batches=args.batches, per_batch=args.per_batch)
            for config in CONFIGS]
    print("\n".join(markdown_lines(rows, get_gpu().description)))


if __name__ == "__main__":
    main()

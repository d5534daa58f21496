"""Host CPU per query, the way the GPU-resident query is measured: ``python -m benchmarks.hostcpu``
from a checkout (or ``pycinder bench hostcpu``).

What is measured, per scene and planner:

* **Host CPU per query**: the CPU time of every Python thread of the process, summed. Each
  thread of :func:`threading.enumerate` (the calling thread, pycinder's worker pool, wgpu-py's
  poll thread) is read on its own CPU clock (``time.pthread_getcpuclockid`` and
  ``time.clock_gettime``) before and after each query. The GPU driver's threads (lavapipe's
  rasteriser and compute threads, wgpu-native's own) are native threads, not Python threads, so
  they are not counted; a thread that waits (for a map, a lock, a worker) uses no CPU, so no wait
  is counted. What remains is the host work the query's own code makes the process do,
  including the CPU spent inside wgpu-py and wgpu-native on a Python thread (encoding, copying
  written buffers). The median over ``repeats`` batches of the batch's mean per query.
* **Frame wall**: the median wall time of one query (waiting for the GPU included).
* **wgpu-py calls per query**: calls of public methods of wgpu-py's API objects (every
  ``GPU...`` class of the backend in use: device, queue, buffers, encoders, passes, promises),
  counted only when the caller is outside wgpu-py, so a call wgpu-py makes for itself (the empty
  submission before some maps) is not one. Beside it, the native calls wgpu-py makes through its
  checked library functions (``_helpers.proxy_func``: one per ``wgpu...`` C function called that
  way), and the C functions pycinder calls itself (:mod:`pycinder.gpu.native`: its frames'
  passes, clears, copies and maps), counted as ``"C name"`` and, in the report, in brackets
  after the API calls they are part of. **Submissions** and **maps** are the calls of
  ``GPUQueue.submit`` and of ``GPUBuffer.map...`` or ``wgpuBufferMapAsync``. They are counted on
  queries of their own, after the timed ones (the counting wrappers cost time).
* **Stages**: where the host CPU goes, on further queries: the same clocks read at the entry and
  exit of the query's stages (:data:`STAGES`), each moment charged to the innermost stage
  running ("other": the query's code outside every stage, waits excluded as above).

"Prepared" scenes pass :class:`~pycinder.PreparedBodies` (checked once); the deforming bunnies
pass new vertex arrays every query, made before the query is timed: either given to the prepared
bodies (:meth:`~pycinder.PreparedBodies.update`, timed as part of the query) or passed as fresh
``(vertices, faces)`` pairs. ``--against SRC`` runs the same measurement on another checkout's
``src`` (this module loaded into its package) and on this one, alternating fresh processes.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import json
import statistics
import subprocess
import sys
import threading
import time
import types
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pycinder.util.environ import path_first

# -- clocks -------------------------------------------------------------------------------------


def python_thread_clocks() -> dict[int, tuple[str, int]]:
    """The CPU clock of every Python thread now: thread ident to (name, nanoseconds).

    A thread that ends while it is read is left out (its clock is gone with it)."""
    out: dict[int, tuple[str, int]] = {}
    for thread in threading.enumerate():
        ident = thread.ident
        if ident is None:
            continue
        try:
            out[ident] = (thread.name, time.clock_gettime_ns(time.pthread_getcpuclockid(ident)))
        except (OSError, ValueError):  # ended meanwhile
            continue
    return out


def cpu_ms(before: dict[int, tuple[str, int]], after: dict[int, tuple[str, int]]) -> float:
    """Milliseconds of CPU the Python threads used between two :func:`python_thread_clocks`
    readings (a thread started in between counts from zero; one that ended is not counted)."""
    return sum(ns - before.get(ident, ("", 0))[1] for ident, (_, ns) in after.items()) / 1e6


def thread_group(name: str) -> str:
    """The group a Python thread's CPU is reported under."""
    if name == "MainThread":
        return "main"
    if name.startswith("pycinder"):
        return "pycinder pool"
    return "other Python threads"


def cpu_by_group(before: dict[int, tuple[str, int]], after: dict[int, tuple[str, int]]
                 ) -> dict[str, float]:
    """:func:`cpu_ms` per :func:`thread_group`."""
    out: dict[str, float] = {}
    for ident, (name, ns) in after.items():
        group = thread_group(name)
        out[group] = out.get(group, 0.0) + (ns - before.get(ident, ("", 0))[1]) / 1e6
    return out


# -- wgpu-py calls ------------------------------------------------------------------------------


@contextlib.contextmanager
def count_wgpu_calls(device: Any) -> Iterator[dict[str, int]]:
    """Count, while the block runs, the wgpu-py API calls made from outside wgpu-py (as
    ``"Class.method"``: count) and, under ``"native"``, the C functions called through wgpu-py's
    checked library functions on the calling thread (not those of wgpu-py's poll thread, which
    polls the device while a map is pending). ``device``: a GPUDevice of the backend to
    count."""
    api = sys.modules[type(device).__module__]
    counts: dict[str, int] = {}
    patched: list[tuple[Any, str, Any]] = []
    wrapped: list[tuple[type, str, Any]] = []
    for cls in vars(api).values():
        if not (isinstance(cls, type) and cls.__name__.startswith("GPU")
                and cls.__module__ == api.__name__ and not issubclass(cls, BaseException)):
            continue
        for name in dir(cls):
            if name.startswith("_"):
                continue
            raw = next((k.__dict__[name] for k in cls.__mro__ if name in k.__dict__), None)
            if isinstance(raw, types.FunctionType):
                wrapped.append((cls, name, raw))
    for cls, name, raw in wrapped:
        patched.append((cls, name, cls.__dict__.get(name)))
        setattr(cls, name, _counted(raw, f"{cls.__name__}.{name}", counts))
    lib = getattr(api, "libf", None)
    native = [(n, f) for n, f in vars(lib).items() if n.startswith("wgpu")] if lib else []
    for name, fn in native:
        setattr(lib, name, _counted_native(fn, counts, threading.get_ident()))
    try:
        with _direct_calls() as direct:
            yield counts
        for name, n in direct.items():
            counts[f"C {name}"] = counts.get(f"C {name}", 0) + n
    finally:
        for cls, name, old in patched:
            if old is None:
                delattr(cls, name)
            else:
                setattr(cls, name, old)
        for name, fn in native:
            setattr(lib, name, fn)


def _direct_calls() -> contextlib.AbstractContextManager:
    """Counts of the C functions pycinder calls itself (:func:`pycinder.gpu.native.counting`);
    nothing in a checkout without them (measured with ``--against``)."""
    try:
        from pycinder.gpu import native
    except ImportError:
        return contextlib.nullcontext({})
    return native.counting()


def _counted(fn: Callable, key: str, counts: dict[str, int]) -> Callable:
    def call(*args: Any, **kwargs: Any) -> Any:
        if not sys._getframe(1).f_globals.get("__name__", "").startswith("wgpu"):
            counts[key] = counts.get(key, 0) + 1
        return fn(*args, **kwargs)

    return call


def _counted_native(fn: Callable, counts: dict[str, int], thread: int) -> Callable:
    def call(*args: Any) -> Any:
        if threading.get_ident() == thread:
            counts["native"] = counts.get("native", 0) + 1
        return fn(*args)

    return call


def summarise_calls(counts: dict[str, int], queries: int) -> dict[str, Any]:
    """Per query: GPU API calls (wgpu-py's methods and the C functions pycinder calls itself,
    ``"C name"``), the latter alone, native calls, submissions, maps, and the calls by method."""
    api = {k: v for k, v in counts.items() if k != "native"}
    direct = sum(v for k, v in api.items() if k.startswith("C "))
    maps = sum(v for k, v in api.items()
               if k.startswith("GPUBuffer.map") or k == "C wgpuBufferMapAsync")
    return {"wgpu_calls": sum(api.values()) / queries,
            "direct_calls": direct / queries,
            "native_calls": counts.get("native", 0) / queries,
            "submissions": sum(v for k, v in api.items() if k == "GPUQueue.submit") / queries,
            "maps": maps / queries,
            "by_method": {k: v / queries for k, v in sorted(api.items(), key=lambda kv: -kv[1])}}


# -- stages -------------------------------------------------------------------------------------

STAGES: tuple[tuple[str, str, str], ...] = (
    ("pycinder.scene.prepared", "PreparedBodies.update", "update (new vertices)"),
    ("pycinder.detector", "Detector._scene", "validate"),
    ("pycinder.scene.prepared", "PreparedBodies.copies", "validate"),
    ("pycinder.robot.model", "RobotModel.poses", "forward kinematics"),
    ("pycinder.robot.k2_pair_cull", "GpuPairCull.run", "kinematics and cull (K1, K2)"),
    ("pycinder.robot.cull", "GpuPairCull.run", "kinematics and cull (K1, K2)"),
    ("pycinder.scene.bodies", "ShapeCache.get_many", "shapes (check, hash, measure)"),
    ("pycinder.scene.topology", "TopologyCache.get", "topology lookup"),
    ("pycinder.scene.bodies", "Scene.world_boxes", "broad phase"),
    ("pycinder.focused.focused_strategy", "FocusedStrategy._candidates", "broad phase"),
    ("pycinder.focused.focused_strategy", "pair_tolerances", "pair tolerances"),
    ("pycinder.focused.focused_strategy", "plan_tiles", "tiles (plan)"),
    ("pycinder.focused.plan.plan_gpu", "GpuPlanner.plan", "tiles (plan)"),
    ("pycinder.focused.focused_strategy", "FocusedStrategy.pack", "pack and upload vertices"),
    ("pycinder.focused.frame.frames", "FocusedFrames.submit", "encode and submit"),
    ("pycinder.focused.frame.frames", "FocusedFrames.finish", "wait and read back"),
    ("pycinder.focused.focused_strategy", "FocusedStrategy._result", "decode"),
    # The same stages under the names of trees from before the modules were renamed, so that
    # ``--against`` an older tree charges them too.
    ("pycinder.focused.strategy", "FocusedStrategy._candidates", "broad phase"),
    ("pycinder.focused.strategy", "FocusedStrategy.tolerances", "pair tolerances"),
    ("pycinder.focused.strategy", "plan_tiles", "tiles (plan)"),
    ("pycinder.focused.plan.gpu", "GpuPlanner.plan", "tiles (plan)"),
    ("pycinder.focused.strategy", "FocusedStrategy.pack", "pack and upload vertices"),
    ("pycinder.focused.strategy", "FocusedStrategy._result", "decode"),
)
"""(module, attribute, stage): the functions whose calls are charged to a stage. A name a
checkout lacks is skipped."""


class StageClock:
    """Charges the Python threads' CPU to the stage running (see :data:`STAGES`)."""

    def __init__(self) -> None:
        self.ms: dict[str, float] = {}
        self._stack: list[str] = []
        self._current = "other"
        self._last = 0

    def _now(self) -> int:
        return sum(ns for _, ns in python_thread_clocks().values())

    def _charge(self) -> None:
        now = self._now()
        self.ms[self._current] = self.ms.get(self._current, 0.0) + (now - self._last) / 1e6
        self._last = now

    def start(self) -> None:
        self._stack, self._current, self._last = [], "other", self._now()

    def stop(self) -> None:
        self._charge()

    def wrap(self, fn: Callable, stage: str) -> Callable:
        clock = self

        def staged(*args: Any, **kwargs: Any) -> Any:
            clock._charge()
            clock._stack.append(clock._current)
            clock._current = stage
            try:
                return fn(*args, **kwargs)
            finally:
                clock._charge()
                clock._current = clock._stack.pop()

        return staged


@contextlib.contextmanager
def staged(clock: StageClock) -> Iterator[None]:
    """Every function of :data:`STAGES` wrapped by ``clock`` while the block runs."""
    undo = []
    for module_name, attribute, stage in STAGES:
        try:
            owner: Any = importlib.import_module(module_name)
        except ImportError:
            continue
        *path, name = attribute.split(".")
        for part in path:
            owner = getattr(owner, part, None)
        if owner is None or not hasattr(owner, name):
            continue
        old = owner.__dict__.get(name) if isinstance(owner, type) else getattr(owner, name)
        if old is None:
            continue
        new = clock.wrap(getattr(owner, name), stage)
        setattr(owner, name, staticmethod(new) if isinstance(old, staticmethod) else new)
        undo.append((owner, name, old))
    try:
        yield
    finally:
        for owner, name, old in reversed(undo):
            setattr(owner, name, old)


# -- scenes -------------------------------------------------------------------------------------


@dataclass
class Case:
    """A scene as a query loop: ``make(detector)`` returns ``next_input(k)`` (untimed: what
    query k is given), ``query(detector, given)`` (timed) and a dict of lists ``next_input``
    adds to (``"copy_ms"``: the CPU milliseconds of copying a deforming scene's new arrays, the
    reference its validation and upload are held to)."""

    name: str
    description: str
    target_ms: float
    make: Callable[[Any], tuple[Callable[[int], Any], Callable[[Any, Any], Any], dict]]


def _scene(name: str) -> Any:
    """Scene class ``name`` of :mod:`pycinder.testing.scenes`, or of
    ``pycinder.benchmarks.scenes`` in a tree from before the scenes moved (:func:`run_fresh`
    measures such a tree with this module)."""
    try:
        from pycinder.testing import scenes
    except ImportError:
        from pycinder.benchmarks import scenes  # type: ignore[no-redef]
    return getattr(scenes, name)


def _rigid(scene_of: Callable[[], Any]) -> Callable:
    def make(det: Any) -> tuple[Callable, Callable]:
        scene = scene_of().cached()
        prepared = det.prepare(scene.bodies(0)[0])
        return (lambda k: scene.frame(k % scene.frames)[1],
                lambda d, transforms: d.find_collisions(prepared, transforms), {})
    return make


def _bunnies(prepared: bool) -> Callable:
    def make(det: Any) -> tuple[Callable, Callable]:
        DeformingBunnies = _scene("DeformingBunnies")

        scene = DeformingBunnies(16).cached()
        bodies = det.prepare(scene.bodies(0)[0]) if prepared else None
        every = list(range(len(scene.faces)))
        extra: dict[str, list[float]] = {"copy_ms": []}

        def next_input(k: int) -> Any:
            vertices, transforms = scene.frame(k % scene.frames)
            before = python_thread_clocks()
            fresh = [v.copy() for v in vertices]  # new arrays every query
            extra["copy_ms"].append(cpu_ms(before, python_thread_clocks()))
            return fresh, transforms

        def query(d: Any, given: Any) -> Any:
            vertices, transforms = given
            if bodies is not None:
                bodies.update(every, vertices)
                return d.find_collisions(bodies, transforms)
            return d.find_collisions(list(zip(vertices, scene.faces)), transforms)

        return next_input, query, extra
    return make


def _two_small(prepared: bool) -> Callable:
    def make(det: Any) -> tuple[Callable, Callable]:
        import trimesh

        meshes = [trimesh.creation.box((1, 1, 1)),
                  trimesh.creation.icosphere(subdivisions=2, radius=0.4)]
        bodies = det.prepare(meshes) if prepared else meshes
        poses = np.tile(np.eye(4), (2, 1, 1))

        def next_input(k: int) -> np.ndarray:
            t = poses.copy()
            t[1, 0, 3] = 0.6 + 0.01 * (k % 5)  # touching
            return t

        return next_input, lambda d, transforms: d.find_collisions(bodies, transforms), {}
    return make


def _many() -> Any:
    ManyBodies = _scene("ManyBodies")

    return ManyBodies(1000)


def _stairs() -> Any:
    Stairs = _scene("Stairs")

    return Stairs(250)


CASES: dict[str, Case] = {c.name: c for c in (
    Case("many-1000", "1000 rigid bodies (ManyBodies), prepared", 1.0, _rigid(_many)),
    Case("stairs-250", "Stairs-250, prepared", 0.5, _rigid(_stairs)),
    Case("bunnies-update", "16 deforming bunnies: new vertex arrays every query, given to "
         "prepared bodies (PreparedBodies.update, timed)", 3.0, _bunnies(True)),
    Case("bunnies-fresh", "16 deforming bunnies: new (vertices, faces) arrays every query",
         3.0, _bunnies(False)),
    Case("two-small", "two small bodies touching (a box, a 320-triangle sphere), meshes as "
         "given", 0.3, _two_small(False)),
    Case("two-small-prepared", "the same two bodies, prepared", 0.3, _two_small(True)),
)}
PLANNERS = ("numpy", "gpu")


# -- measuring ----------------------------------------------------------------------------------


def measure(case: Case, planners: Sequence[str] = PLANNERS, *, repeats: int = 7,
            batch: int = 5, warmup: int = 3, stages: bool = True, counted: int = 2,
            records: str = "none") -> list[dict[str, Any]]:
    """One row per planner: host CPU per query, frame wall, wgpu-py calls, stages.

    The planners' detectors share the process and alternate batch by batch; each batch is
    ``batch`` queries, after ``warmup`` untimed ones per planner. ``records``: the detectors'
    (``"none"``, pairs only, is how the targets are stated; ``"found"`` is the default of
    :class:`~pycinder.Detector`)."""
    from pycinder.detector import Detector

    loops = {}
    for planner in planners:
        det = Detector(records=records, planner=planner)
        next_input, query, extra = case.make(det)
        for k in range(warmup):
            query(det, next_input(k))
        loops[planner] = (det, next_input, query, extra)
    cpu: dict[str, list[float]] = {p: [] for p in planners}
    wall: dict[str, list[float]] = {p: [] for p in planners}
    groups: dict[str, dict[str, float]] = {p: {} for p in planners}
    stats: dict[str, Any] = {}
    k = warmup
    for r in range(repeats):
        for planner in (planners if r % 2 == 0 else planners[::-1]):
            det, next_input, query, _ = loops[planner]
            spent = 0.0
            for _ in range(batch):
                given = next_input(k)
                k += 1
                before = python_thread_clocks()
                t0 = time.perf_counter()
                result = query(det, given)
                wall[planner].append((time.perf_counter() - t0) * 1e3)
                after = python_thread_clocks()
                spent += cpu_ms(before, after)
                for g, ms in cpu_by_group(before, after).items():
                    groups[planner][g] = groups[planner].get(g, 0.0) + ms
                stats[planner] = result.stats
            cpu[planner].append(spent / batch)
    rows = []
    for planner in planners:
        det, next_input, query, extra = loops[planner]
        with count_wgpu_calls(det.gpu.device) as counts:
            for _ in range(counted):
                query(det, next_input(k))
                k += 1
        row = {"scene": case.name, "description": case.description, "planner": planner,
               "records": records, "target_ms": case.target_ms,
               "host_cpu_ms": statistics.median(cpu[planner]),
               "host_cpu_ms_batches": cpu[planner], "wall_ms": statistics.median(wall[planner]),
               "queries": len(wall[planner]),
               "cpu_by_thread_ms": {g: ms / len(wall[planner])
                                    for g, ms in sorted(groups[planner].items())},
               **summarise_calls(counts, counted)}
        st = stats[planner]
        row.update(bodies=st.bodies, candidates=st.candidates, tiles=st.tiles, rounds=st.rounds)
        if extra.get("copy_ms"):
            row["copy_ms"] = statistics.median(extra["copy_ms"])
        if stages:
            row["stages_ms"], row["staged_total_ms"] = _stages(det, next_input, query, k,
                                                               repeats * batch)
            k += repeats * batch
        rows.append(row)
    return rows


def _stages(det: Any, next_input: Callable, query: Callable, k: int, n: int
            ) -> tuple[dict[str, float], float]:
    """Mean CPU ms per query by stage over ``n`` queries (see :class:`StageClock`)."""
    clock = StageClock()
    with staged(clock):
        for i in range(n):
            given = next_input(k + i)
            clock.start()
            query(det, given)
            clock.stop()
    per = {s: ms / n for s, ms in sorted(clock.ms.items(), key=lambda kv: -kv[1])}
    return per, sum(per.values())


def profile(case: Case, planner: str = "numpy", queries: int = 10, top: int = 20) -> str:
    """cProfile of the calling thread's CPU (``time.thread_time``) over ``queries`` queries, the
    ``top`` functions by own time."""
    import cProfile
    import io
    import pstats

    from pycinder.detector import Detector

    det = Detector(records="none", planner=planner)
    next_input, query, _ = case.make(det)
    for k in range(3):
        query(det, next_input(k))
    prof = cProfile.Profile(time.thread_time)
    for k in range(3, 3 + queries):
        given = next_input(k)
        prof.enable()
        query(det, given)
        prof.disable()
    out = io.StringIO()
    pstats.Stats(prof, stream=out).sort_stats("tottime").print_stats(top)
    return out.getvalue()


def run(names: Sequence[str] | None = None, planners: Sequence[str] = PLANNERS, *,
        repeats: int = 7, batch: int = 5, stages: bool = True,
        progress: Callable[[str], None] | None = None, records: str = "none"
        ) -> list[dict[str, Any]]:
    """Every named case (default: all of :data:`CASES`), in this process (``records``: see
    :func:`measure`)."""
    rows = []
    for name in names or list(CASES):
        if name not in CASES:
            raise ValueError(f"unknown scene {name!r}; choose from {', '.join(CASES)}")
        if progress:
            progress(f"hostcpu: {name}")
        rows += measure(CASES[name], planners, repeats=repeats, batch=batch, stages=stages,
                        records=records)
    return rows


def run_fresh(names: Sequence[str] | None = None, planners: Sequence[str] = PLANNERS, *,
              repeats: int = 7, batch: int = 5, stages: bool = True, src: str | None = None,
              records: str = "none") -> list[dict[str, Any]]:
    """:func:`run` in a fresh process, on the package under ``src`` (default: this one's), with
    this module loaded into it (so an older checkout is measured the same way)."""
    src = src or str(Path(__file__).resolve().parents[1] / "src")
    args = ["--json", "-", "--repeats", str(repeats), "--batch", str(batch),
            "--planners", *planners, "--scenes", *(names or list(CASES))]
    if records != "none":
        args += ["--records", records]
    if not stages:
        args.append("--no-stages")
    env = path_first(src)
    out = subprocess.run([sys.executable, "-c", _BOOT, src, str(Path(__file__).resolve()),
                          *args], capture_output=True, text=True, env=env, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"the host CPU measurement failed: {out.stderr.strip()[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


_BOOT = """import importlib.util, sys
sys.path.insert(0, sys.argv[1])
spec = importlib.util.spec_from_file_location("benchmarks.hostcpu", sys.argv[2])
module = importlib.util.module_from_spec(spec)
sys.modules[spec.name] = module
spec.loader.exec_module(module)
module.main(sys.argv[3:])
"""


def compare(against: str, names: Sequence[str] | None = None,
            planners: Sequence[str] = PLANNERS, *, rounds: int = 3, repeats: int = 5,
            batch: int = 5, progress: Callable[[str], None] | None = None,
            records: str = "none") -> dict[str, list[dict[str, Any]]]:
    """This checkout against the package under ``against`` (a ``src`` folder), in fresh
    processes alternating round by round; ``{"before": rows, "after": rows}``, a row's figures
    the median over the rounds' processes (each process's in ``..._runs``)."""
    runs: dict[str, list[list[dict[str, Any]]]] = {"before": [], "after": []}
    for r in range(rounds):
        for which, src in (("before", against), ("after", None)):
            if progress:
                progress(f"hostcpu: round {r + 1} of {rounds}, {which}")
            runs[which].append(run_fresh(names, planners, repeats=repeats, batch=batch,
                                         src=src, records=records))
    return {which: _merge(rows) for which, rows in runs.items()}


def _merge(runs: list[list[dict[str, Any]]]) -> list[dict[str, Any]]:
    merged = []
    for i, row in enumerate(runs[0]):
        out = dict(row)
        for key in ("host_cpu_ms", "wall_ms", "wgpu_calls", "direct_calls", "native_calls",
                    "copy_ms"):
            if key not in row:
                continue
            values = [rows[i][key] for rows in runs]
            out[key], out[f"{key}_runs"] = statistics.median(values), values
        if "stages_ms" in row:
            names = {s for rows in runs for s in rows[i]["stages_ms"]}
            out["stages_ms"] = {s: statistics.median([rows[i]["stages_ms"].get(s, 0.0)
                                                      for rows in runs]) for s in names}
        merged.append(out)
    return merged


# -- reporting ----------------------------------------------------------------------------------

HOW = ("Host CPU per query: the CPU time of every Python thread of the process (the calling "
       "thread, pycinder's worker pool, wgpu-py's poll thread), each read on its own CPU clock "
       "before and after each query, summed; the GPU driver's threads are not Python threads, "
       "and a thread that waits uses no CPU, so neither counts. The median over batches of the "
       "batch's mean; frame wall: the median query's wall time. GPU API calls: public methods "
       "of wgpu-py's objects called from outside wgpu-py, and the C functions of wgpu-native "
       "pycinder calls itself (`pycinder.gpu.native`; in brackets), per query; native calls: "
       "the C functions wgpu-py calls for its methods on the calling thread. Stages: the same "
       "clocks read at the entry and exit of the query's stages, each moment charged to the "
       "innermost "
       "(`benchmarks.hostcpu.STAGES`). The targets are those of the GPU-resident "
       "query.")
"""What the host CPU table measures, in a paragraph of the report."""


def _ms(x: float) -> str:
    return f"{x:.1f}" if x >= 10 else f"{x:.2f}"


def markdown_lines(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The table of :func:`run`'s rows, then each row's stages, as Markdown lines."""
    out = [("| scene | planner | host CPU ms/query | target | met | frame wall ms | "
            "GPU API calls/query (C direct) | native calls/query | submissions | maps | "
            "candidates | tiles |"), "|" + "---|" * 12]
    for r in rows:
        out.append(f"| {r['scene']} | {r['planner']} | {_ms(r['host_cpu_ms'])} | "
                   f"{r['target_ms']:g} | {'yes' if r['host_cpu_ms'] <= r['target_ms'] else 'no'}"
                   f" | {_ms(r['wall_ms'])} | {r['wgpu_calls']:.0f} "
                   f"({r.get('direct_calls', 0):.0f}) | {r['native_calls']:.0f} | "
                   f"{r['submissions']:g} | {r['maps']:g} | {r['candidates']} | {r['tiles']} |")
    staged_rows = [r for r in rows if r.get("stages_ms")]
    if staged_rows:
        names = sorted({s for r in staged_rows for s in r["stages_ms"]},
                       key=lambda s: -max(r["stages_ms"].get(s, 0.0) for r in staged_rows))
        out += ["", "Host CPU ms per query by stage (see `STAGES`):", "",
                "| stage | " + " | ".join(f"{r['scene']} {r['planner']}" for r in staged_rows)
                + " |", "|---|" + "---|" * len(staged_rows)]
        for s in names:
            out.append(f"| {s} | " + " | ".join(_ms(r["stages_ms"].get(s, 0.0))
                                                for r in staged_rows) + " |")
    return out


UPLOAD_STAGES = ("update (new vertices)", "validate", "shapes (check, hash, measure)",
                 "topology lookup", "pack and upload vertices")
"""The stages a query with new vertex arrays pays for them: what :func:`validation_lines` holds
to the cost of copying the arrays."""


def validation_lines(rows: Sequence[dict[str, Any]],
                     before: Sequence[dict[str, Any]] | None = None) -> list[str]:
    """Validating and uploading new vertex arrays against copying them, per deforming scene
    (and the same ``before``, when given), as Markdown lines."""
    pairs = [(r, b) for r, b in zip(rows, before or [None] * len(rows))
             if r.get("copy_ms") and r.get("stages_ms")]
    if not pairs:
        return []
    out = ["| scene | planner | copying the new arrays | " + " | ".join(UPLOAD_STAGES)
           + " | validation and upload | " + ("before |" if before else ""),
           "|" + "---|" * (4 + len(UPLOAD_STAGES) + (1 if before else 0))]
    for r, b in pairs:
        spent = sum(r["stages_ms"].get(s, 0.0) for s in UPLOAD_STAGES)
        cells = [r["scene"], r["planner"], _ms(r["copy_ms"])]
        cells += [_ms(r["stages_ms"].get(s, 0.0)) for s in UPLOAD_STAGES] + [_ms(spent)]
        if b is not None:
            cells.append(_ms(sum(b["stages_ms"].get(s, 0.0) for s in UPLOAD_STAGES)))
        out.append("| " + " | ".join(cells) + " |")
    return out


def comparison_lines(result: dict[str, list[dict[str, Any]]]) -> list[str]:
    """Before and after (:func:`compare`) side by side, as Markdown lines."""
    out = [("| scene | planner | host CPU ms before | after | frame wall ms before | after | "
            "GPU API calls before | after |"), "|" + "---|" * 8]
    for b, a in zip(result["before"], result["after"]):
        out.append(f"| {a['scene']} | {a['planner']} | {_ms(b['host_cpu_ms'])} | "
                   f"{_ms(a['host_cpu_ms'])} | {_ms(b['wall_ms'])} | {_ms(a['wall_ms'])} | "
                   f"{b['wgpu_calls']:.0f} | {a['wgpu_calls']:.0f} |")
    return out


SWEEP_SIZES = (60, 250, 1000, 2000)
"""Bodies of the ManyBodies scenes :func:`planner_sweep` measures."""


def planner_sweep(sizes: Sequence[int] = SWEEP_SIZES, *, repeats: int = 5, batch: int = 3
                  ) -> list[dict[str, Any]]:
    """Frame wall time and host CPU of both planners on prepared ManyBodies scenes of ``sizes``
    bodies (alternating batch by batch, :func:`measure`): what ``planner="auto"`` chooses by.

    Returns
    -------
    list of dict
        :func:`measure`'s rows (no stages), with ``bodies`` and ``candidates``.
    """
    ManyBodies = _scene("ManyBodies")

    rows: list[dict[str, Any]] = []
    for n in sizes:
        case = Case(f"many-{n}", f"{n} rigid bodies (ManyBodies), prepared", 0.0,
                    _rigid(lambda n=n: ManyBodies(n)))
        rows += measure(case, PLANNERS, repeats=repeats, batch=batch, stages=False, counted=1)
    return rows


def sweep_lines(rows: Sequence[dict[str, Any]]) -> list[str]:
    """:func:`planner_sweep`'s rows as a Markdown table, the planners side by side."""
    out = ["| bodies | candidate pairs | tiles | frame wall ms, numpy | gpu | host CPU ms, numpy "
           "| gpu |", "|---:|---:|---:|---:|---:|---:|---:|"]
    by = {(r["scene"], r["planner"]): r for r in rows}
    for scene in dict.fromkeys(r["scene"] for r in rows):
        n, g = by[(scene, "numpy")], by[(scene, "gpu")]
        out.append(f"| {n['bodies']:,} | {n['candidates']:,} | {n['tiles']:,} | "
                   f"{_ms(n['wall_ms'])} | {_ms(g['wall_ms'])} | {_ms(n['host_cpu_ms'])} | "
                   f"{_ms(g['host_cpu_ms'])} |")
    return out


def robot_configurations(name: str = "panda", batch: int = 1024, batches: int = 5,
                         seed: int = 3, samples: int = 0) -> dict[str, Any]:
    """Host CPU per configuration of ``Robot.check`` (:mod:`pycinder.testing.robots`' robot
    ``name`` with its table (and tray); the allowed-collision matrix it loads with, or with
    ``samples``, MoveIt's from that many random configurations, the robot benchmark's way: for
    the Panda from 300, 85 pairs to check a configuration instead of 121), summed over
    the process's Python threads, in ``batches`` timed checks of ``batch`` configurations each
    (one query each), after two untimed checks of as many. Returns the median microseconds per
    configuration, the wall milliseconds per configuration, and the host CPU microseconds per
    configuration by stage (``stages_us``, :data:`STAGES`, over one more check)."""
    import warnings

    from pycinder.testing.robots import with_environment

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # open meshes, yourdfpy's notes on the table's URDF
        robot, env = with_environment(name, samples, seed)
        q = robot.random_configurations(batch * (batches + 1), seed=seed)
        for _ in range(2):  # the second plans after the first's overflow: buffers grow once
            robot.check(q[:batch], environment=env, batch=batch)
        cpu, wall = [], []
        for k in range(1, batches + 1):
            before, t0 = python_thread_clocks(), time.perf_counter()
            robot.check(q[k * batch:(k + 1) * batch], environment=env, batch=batch)
            wall.append((time.perf_counter() - t0) * 1e3 / batch)
            cpu.append(cpu_ms(before, python_thread_clocks()) * 1e3 / batch)
        clock = StageClock()
        with staged(clock):
            clock.start()
            robot.check(q[:batch], environment=env, batch=batch)
            clock.stop()
    stages = {s: ms * 1e3 / batch for s, ms in sorted(clock.ms.items(), key=lambda kv: -kv[1])}
    return {"robot": name, "batch": batch, "samples": samples,
            "host_cpu_us": statistics.median(cpu),
            "wall_ms": statistics.median(wall), "stages_us": stages}


def main(argv: Sequence[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python -m benchmarks.hostcpu",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--scenes", nargs="*", default=list(CASES), choices=list(CASES))
    p.add_argument("--planners", nargs="*", default=list(PLANNERS), choices=list(PLANNERS))
    p.add_argument("--repeats", type=int, default=7, help="timed batches per scene and planner")
    p.add_argument("--batch", type=int, default=5, help="queries per batch")
    p.add_argument("--no-stages", action="store_true", help="leave out the stage breakdown")
    p.add_argument("--records", default="none", choices=("none", "found", "all"),
                   help="the detectors' records (default none, as the targets are stated; "
                        "found is the Detector's default)")
    p.add_argument("--profile", type=int, default=0, metavar="N",
                   help="print cProfile's N costliest functions (own CPU time of the calling "
                        "thread) per scene, with the NumPy planner")
    p.add_argument("--against", metavar="SRC", help="another checkout's src folder: measure it "
                   "and this one in alternating fresh processes")
    p.add_argument("--rounds", type=int, default=3, help="processes per checkout (--against)")
    p.add_argument("--json", metavar="PATH", help="write the rows as JSON ('-': stdout)")
    p.add_argument("--robot", metavar="NAME", help="instead: host CPU per configuration of "
                   "Robot.check on robot NAME with its environment, in checks of --batch "
                   "configurations (1,024 for the target)")
    p.add_argument("--matrix-samples", type=int, default=0, metavar="N",
                   help="with --robot: MoveIt's allowed-collision matrix from N random "
                        "configurations, as the robot benchmark makes it (default 0: the matrix "
                        "the robot loads with)")
    p.add_argument("--planner-sweep", nargs="*", type=int, metavar="N",
                   help="instead: both planners' frame wall and host CPU on ManyBodies scenes of "
                        f"N bodies (default {' '.join(map(str, SWEEP_SIZES))})")
    a = p.parse_args(argv)
    if a.matrix_samples < 0:
        p.error(f"--matrix-samples must be 0 or more configurations, got {a.matrix_samples}")
    say = (lambda msg: print(msg, file=sys.stderr, flush=True))
    if a.robot:
        r = robot_configurations(a.robot, a.batch, samples=a.matrix_samples)
        matrix = f"MoveIt's matrix from {a.matrix_samples} samples" if a.matrix_samples \
            else "the matrix it loads with"
        print(f"{r['robot']} ({matrix}), batches of {r['batch']}: host CPU "
              f"{r['host_cpu_us']:.1f} us a "
              f"configuration, wall {r['wall_ms']:.3f} ms a configuration; by stage (us a "
              "configuration): " + ", ".join(f"{k} {v:.1f}" for k, v in r["stages_us"].items()))
        return
    if a.planner_sweep is not None:
        rows = planner_sweep(a.planner_sweep or SWEEP_SIZES)
        if a.json:
            Path(a.json).write_text(json.dumps(rows, indent=1))
        print("\n".join(sweep_lines(rows)))
        return
    if a.against:
        result = compare(a.against, a.scenes, a.planners, rounds=a.rounds, repeats=a.repeats,
                         batch=a.batch, progress=say, records=a.records)
        text = "\n".join(comparison_lines(result) + [""] + markdown_lines(result["after"]) + [""]
                         + validation_lines(result["after"], result["before"]))
        if a.json:
            Path(a.json).write_text(json.dumps(result, indent=1))
        print(text)
        return
    if a.profile:
        for name in a.scenes:
            print(f"## {name}\n\n```\n{profile(CASES[name], top=a.profile)}```\n")
        return
    rows = run(a.scenes, a.planners, repeats=a.repeats, batch=a.batch,
               stages=not a.no_stages, progress=say if a.json != "-" else None,
               records=a.records)
    if a.json == "-":
        print(json.dumps(rows))
        return
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    print("\n".join(markdown_lines(rows) + [""] + validation_lines(rows)))


if __name__ == "__main__":
    main()

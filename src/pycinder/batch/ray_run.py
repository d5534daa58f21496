"""Many scenes over Ray workers: streamed in, checked in chunks, results out, faults retried.

    scenes (dicts, read lazily) -> checked entries -> chunks of ``batch_size`` scenes
      -> worker actors (one Detector each; meshes read once per worker, by path)
      -> results in input order, or as completed

At most ``depth`` chunks wait per worker, so a manifest of any length is read as the workers
keep up, and in input order at most a bounded window of finished results is held back. A chunk
whose worker died (killed, device lost) is retried scene by scene on the restarted worker; a
scene that fails ``attempts`` times is given back with its error and the run goes on.

Without an address a local Ray instance is started (``workers`` CPUs) and shut down at the end;
with one, the run connects to that cluster. Within an already initialised Ray, the run uses it.
"""

from __future__ import annotations

import logging
import os
import time
from collections import deque
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any

from ..optional import require
from .manifest import normalize
from .worker import BatchWorker, error_result

DEPTH = 2
"""Chunks in flight per worker: one running, one waiting, so a worker never waits for the
driver."""
RECOVERY_S = 120.0
"""Seconds a dead worker has to come back (Ray restarts it) before it is given up."""


@dataclass
class _Item:
    seq: int
    entry: dict
    attempt: int = 1


def _ray() -> Any:
    return require("ray", "pycinder batch (Ray workers)", "cluster")


class BatchRun(Iterator[dict]):
    """An iterator over the results of a batch run (see :func:`run`); ``summary`` says what it
    did, ``pids`` the workers' processes at the start. Close it (or use it in a ``with``) to
    stop early; it closes itself when the scenes are done."""

    def __init__(self, scenes: Iterable[Any], *, workers: int | None = None,
                 address: str | None = None, gpus_per_worker: float | None = None,
                 tolerance: float | None = None, ordered: bool = True, batch_size: int = 64,
                 attempts: int = 2, strict: bool = False, base: str | None = None,
                 options: dict | None = None) -> None:
        for name, value in (("batch_size", batch_size), ("attempts", attempts)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a whole number of at least 1, got {value!r}")
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                    or workers < 1):
            raise ValueError(f"workers must be a whole number of at least 1, got {workers!r}")
        ray = self._ray = _ray()
        detector = {"tolerance": tolerance, "strict": strict, **(options or {})}
        from ..request import CollisionRequest

        CollisionRequest(**detector)  # options checked here, once, not in every worker
        self._started = False
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"logging_level": logging.WARNING, "log_to_driver": False}
            if address:
                ray.init(address=address, **kwargs)
            else:
                ray.init(num_cpus=workers or os.cpu_count() or 1, include_dashboard=False,
                         **kwargs)
            self._started = True
        self.closed = False
        try:
            have = ray.cluster_resources()
            gpus, cpus = float(have.get("GPU", 0)), float(have.get("CPU", 0))
            if gpus_per_worker is None:
                gpus_per_worker = 1.0 if gpus else 0.0
            if workers is None:
                workers = max(1, int(gpus // gpus_per_worker)) if gpus_per_worker else 1
            # Workers that could never be placed would wait for ever: say so now.
            if workers * gpus_per_worker > gpus or workers > cpus:
                raise ValueError(
                    f"{workers} workers need {workers} CPUs and {workers * gpus_per_worker:g} "
                    f"GPUs; the Ray cluster has {cpus:g} CPUs and {gpus:g} GPUs (set workers "
                    "or gpus_per_worker)")
            actor = ray.remote(BatchWorker).options(
                num_cpus=1, num_gpus=gpus_per_worker, max_restarts=-1, max_task_retries=0)
            self.workers = [actor.remote(detector, k) for k in range(workers)]
            ready = ray.get([w.ready.remote() for w in self.workers])
        except Exception:
            self.close()
            raise
        self.pids = [r["pid"] for r in ready]
        self.adapter = ready[0]["adapter"]
        self._scenes = iter(scenes)
        self._base = base
        self._ordered = ordered
        self._batch = batch_size
        self._attempts = attempts
        self._window = max(4 * workers * DEPTH * batch_size, 256)
        self._seq = 0
        self._emitted = 0
        self._exhausted = False
        self._retry: deque[_Item] = deque()
        self._done: dict[int, dict] = {}
        self._queue: deque[dict] = deque()
        self._flight: dict[Any, tuple[int, list[_Item]]] = {}
        self._load = [0] * workers
        self._alive = [True] * workers
        self._probes: dict[Any, tuple[int, float]] = {}  # ready() calls to restarted workers
        self._t0 = time.perf_counter()
        self.summary: dict[str, Any] = {
            "workers": workers, "gpus_per_worker": gpus_per_worker, "batch_size": batch_size,
            "adapter": self.adapter, "scenes": 0, "failed": 0, "retried": 0,
            "worker_failures": 0, "seconds": 0.0, "scenes_per_s": 0.0}

    # -- iteration -------------------------------------------------------------------------

    def __iter__(self) -> BatchRun:
        return self

    def __next__(self) -> dict:
        try:
            while True:
                out = self._pop()
                if out is not None:
                    return out
                if self.closed:
                    raise StopIteration
                self._fill()
                if not self._flight:
                    if self._exhausted and not self._retry:
                        self.summary["mesh_loads"] = self.mesh_loads()
                        self.close()
                        raise StopIteration
                    if not self._probes and not any(self._alive):
                        raise RuntimeError(
                            f"every worker died and none came back within {RECOVERY_S:.0f} s; "
                            "the results so far are kept")
                    if not self._probes:
                        continue  # results made without a worker (bad entries) are waiting
                done, _ = self._ray.wait(list(self._flight) + list(self._probes),
                                         num_returns=1)
                for ref in done:
                    if ref in self._probes:
                        self._probed(ref)
                    else:
                        self._collect(ref)
        except StopIteration:
            raise
        except BaseException:
            self.close()
            raise

    def _pop(self) -> dict | None:
        if self._ordered:
            out = self._done.pop(self._emitted, None)
        else:
            out = self._queue.popleft() if self._queue else None
        if out is not None:
            self._emitted += 1
            self.summary["scenes"] += 1
            self.summary["failed"] += "error" in out
            elapsed = time.perf_counter() - self._t0
            self.summary["seconds"] = elapsed
            self.summary["scenes_per_s"] = self.summary["scenes"] / max(elapsed, 1e-9)
        return out

    # -- dispatch --------------------------------------------------------------------------

    def _fill(self) -> None:
        for k in range(len(self.workers)):
            while self._alive[k] and self._load[k] < DEPTH:
                items = self._chunk()
                if not items:
                    return
                ref = self.workers[k].check.remote([i.entry for i in items],
                                                   self._batch > 1)
                self._flight[ref] = (k, items)
                self._load[k] += 1

    def _chunk(self) -> list[_Item]:
        """The next chunk: a scene to retry alone, or up to ``batch_size`` new scenes."""
        if self._retry:
            return [self._retry.popleft()]
        items: list[_Item] = []
        while len(items) < self._batch and not self._exhausted:
            if self._ordered and self._seq - self._emitted >= self._window:
                break
            try:
                raw = next(self._scenes)
            except StopIteration:
                self._exhausted = True
                break
            seq = self._seq
            self._seq += 1
            try:
                items.append(_Item(seq, normalize(raw, seq, self._base)))
            except ValueError as exc:  # no worker can get past it: given back at once
                scene_id = raw.get("id", seq) if isinstance(raw, dict) else seq
                self._finish(seq, error_result(scene_id, exc))
        return items

    def _collect(self, ref: Any) -> None:
        k, items = self._flight.pop(ref)
        self._load[k] -= 1
        try:
            results = self._ray.get(ref)
        except Exception as exc:  # the worker died: Ray restarts it; its scenes go again
            self.summary["worker_failures"] += 1
            why = f"worker {k} failed while checking it ({type(exc).__name__})"
            for item in items:
                self._fail(item, why)
            if self._alive[k]:
                # Calls sent while Ray restarts it would fail too: wait until it answers.
                self._alive[k] = False
                self._probe(k, time.perf_counter())
            return
        for item, result in zip(items, results):
            if "error" in result:
                self._fail(item, result["error"])
            else:
                result["stats"]["attempt"] = item.attempt
                self._finish(item.seq, result)

    def _probe(self, k: int, since: float) -> None:
        self._probes[self.workers[k].ready.remote()] = (k, since)

    def _probed(self, ref: Any) -> None:
        k, since = self._probes.pop(ref)
        try:
            self.pids[k] = self._ray.get(ref)["pid"]
            self._alive[k] = True
        except Exception:
            if time.perf_counter() - since < RECOVERY_S:
                time.sleep(0.2)
                self._probe(k, since)

    def _fail(self, item: _Item, why: str) -> None:
        if item.attempt < self._attempts:
            self.summary["retried"] += 1
            self._retry.append(_Item(item.seq, item.entry, item.attempt + 1))
        else:
            self._finish(item.seq, error_result(
                item.entry["id"], f"{why} (failed {item.attempt} times)"))

    def _finish(self, seq: int, result: dict) -> None:
        if self._ordered:
            self._done[seq] = result
        else:
            self._queue.append(result)

    # -- the end ---------------------------------------------------------------------------

    def mesh_loads(self) -> list[int | None]:
        """Mesh files each worker has read since it (re)started (each once, while cached);
        None for a worker that is not answering."""
        out: list[int | None] = []
        for w, alive in zip(self.workers, self._alive):
            try:
                out.append(self._ray.get(w.mesh_loads.remote()) if alive else None)
            except Exception:  # it died just now
                out.append(None)
        return out

    def close(self) -> None:
        """Stop the workers (and the local Ray instance this run started)."""
        if self.closed:
            return
        self.closed = True
        if self._ray.is_initialized():
            for w in getattr(self, "workers", []):
                self._ray.kill(w)
            if self._started:
                self._ray.shutdown()

    def __enter__(self) -> BatchRun:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def run(scenes: Iterable[Any], *, workers: int | None = None, address: str | None = None,
        gpus_per_worker: float | None = None, tolerance: float | None = None,
        ordered: bool = True, batch_size: int = 64, attempts: int = 2, strict: bool = False,
        base: str | None = None, options: dict | None = None) -> BatchRun:
    """Check many scenes on Ray workers; an iterator of one result per scene.

    Parameters
    ----------
    scenes : iterable of dict
        Scene entries as in a manifest (:mod:`pycinder.batch.manifest`): ``{"id", "tolerance",
        "bodies": [{"mesh", "transform", "name"}]}``; read lazily. Meshes given by path are
        read once per worker; a path must be readable where the workers run.
    workers : int, optional
        Worker actors. Default: one per GPU of the cluster (one when it has none). Without an
        ``address`` a local Ray instance with this many CPUs is started.
    address : str, optional
        A Ray cluster to connect to (``"auto"``, ``"ray://host:10001"``).
    gpus_per_worker : float, optional
        GPUs each worker reserves (default: 1 where the cluster has GPUs, else 0).
    tolerance : float, optional
        World units, for scenes that give none (default: 1% of the smaller body, per pair).
    ordered : bool
        Results in input order (default), or as they complete.
    batch_size : int
        Scenes per query: a worker checks each chunk in one query (``1``: a query per scene).
    attempts : int
        Tries per scene before its error is given back (a worker that dies counts as a try).
    strict : bool
        Open, inside-out and zero-area meshes are errors rather than warnings.
    base : str, optional
        Folder that relative mesh paths start from (default: the working directory).
    options : dict, optional
        Other options of :class:`~pycinder.CollisionRequest`.

    Returns
    -------
    BatchRun
        Yields ``{"id", "pairs": [[i, j], ...], "names": [[a, b], ...], "stats": {...}}``, or
        ``{"id", "error"}`` for a scene that could not be checked.
    """
    return BatchRun(scenes, workers=workers, address=address, gpus_per_worker=gpus_per_worker,
                    tolerance=tolerance, ordered=ordered, batch_size=batch_size,
                    attempts=attempts, strict=strict, base=base, options=options)

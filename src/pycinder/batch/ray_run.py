"""Many scenes over Ray workers: streamed in, checked in chunks, results out, faults retried.

    scenes (dicts, read lazily) -> checked entries -> chunks of ``batch_size`` scenes
      -> worker actors (one Detector each; meshes read once per worker, by path)
      -> results in input order, or as completed

At most ``depth`` chunks wait per worker, so a manifest of any length is read as the workers
keep up, and in input order at most a bounded window of finished results is held back. A chunk
whose worker died (killed, device lost) is retried scene by scene on the restarted worker; a
scene that fails ``attempts`` times is given back with its error and the run goes on. A scene
whose own input is bad (a mesh file missing or unreadable, NaN vertices, a singular transform:
``error_kind`` ``"input"``) is given back at once: no other try could succeed.

Without an address a local Ray instance is started (``workers`` CPUs) and shut down at the end;
with one, the run connects to that cluster. Within an already initialised Ray, the run uses it.
A local instance gets Ray's own default authentication, said explicitly (:func:`_ray`).
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections import deque
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any

from ..util.optional import require
from .manifest import normalize
from .worker import BatchWorker, error_result

DEPTH = 2
"""Chunks in flight per worker: one running, one waiting, so a worker never waits for the
driver."""
RECOVERY_S = 120.0
"""Seconds a dead worker has to come back (Ray restarts it) before it is given up."""
AUTH_MODE = "RAY_AUTH_MODE"
"""Ray's setting of how its cluster authenticates calls (``token`` or ``disabled``)."""


def start_ray(ray: Any, address: str | None, workers: int | None) -> bool:
    """Connect to the cluster at ``address``, or start a local one of ``workers`` CPUs (all of
    this machine's by default), unless Ray is initialised already; True when this call did (the
    run then shuts it down at its end)."""
    if ray.is_initialized():
        return False
    kwargs: dict[str, Any] = {"logging_level": logging.WARNING, "log_to_driver": False}
    if address:
        ray.init(address=address, **kwargs)
    else:
        ray.init(num_cpus=workers or os.cpu_count() or 1, include_dashboard=False, **kwargs)
    return True


def placement(ray: Any, workers: int | None, gpus_per_worker: float | None
              ) -> tuple[int, float]:
    """The workers of a run and each one's GPUs: by default a GPU each where the cluster has
    GPUs (as many workers as GPUs), else one worker.

    Raises
    ------
    ValueError
        The cluster cannot place that many workers (they would wait for ever)."""
    have = ray.cluster_resources()
    gpus, cpus = float(have.get("GPU", 0)), float(have.get("CPU", 0))
    if gpus_per_worker is None:
        gpus_per_worker = 1.0 if gpus else 0.0
    if workers is None:
        workers = max(1, int(gpus // gpus_per_worker)) if gpus_per_worker else 1
    if workers * gpus_per_worker > gpus or workers > cpus:
        raise ValueError(
            f"{workers} workers need {workers} CPUs and {workers * gpus_per_worker:g} "
            f"GPUs; the Ray cluster has {cpus:g} CPUs and {gpus:g} GPUs (set workers "
            "or gpus_per_worker)")
    return workers, gpus_per_worker


@dataclass
class _Item:
    seq: int
    entry: dict
    attempt: int = 1


def _ray(local: bool) -> Any:
    """Ray, imported; for a ``local`` cluster (one this run may start), with its authentication
    mode said.

    Ray (2.59 on) starts a local cluster with token authentication unless :data:`AUTH_MODE`
    says otherwise, and warns at every start that it chose so; a mode that is set explicitly
    it follows without a word. Ray reads the variable when it is imported: where the user set
    none and Ray is not imported yet, it is set to Ray's own default, ``token`` (Ray makes the
    token, in ``~/.ray/auth_token``), so that the cluster is the same and the warning goes.
    Ray before 2.52 has no token authentication and ignores it. A user's own setting, and a Ray
    imported before (whose settings are read), are left alone; so is a cluster given by
    address, whose mode its owner chose.
    """
    if local and AUTH_MODE not in os.environ and "ray" not in sys.modules:
        os.environ[AUTH_MODE] = "token"
    return require("ray", "pycinder batch (Ray workers)", "cluster")


class BatchRun(Iterator[dict]):
    """An iterator over the results of a batch run (see :func:`run`); ``summary`` says what it
    did, ``pids`` the workers' processes at the start. Close it (or use it in a ``with``) to
    stop early; it closes itself when the scenes are done.

    ``summary`` holds ``scenes`` (rows given so far), ``failed`` (error rows among them),
    ``retried`` (tries made again), ``worker_failures`` (worker deaths), ``workers``,
    ``gpus_per_worker``, ``batch_size``, ``adapter``, ``mesh_loads`` (once done: files each
    worker read), and the times: ``seconds``, the run's wall time from the call to :func:`run`
    to its last row (to its end once closed), starting Ray (when the run starts it) and the
    workers, each up to a first query, included, and so is stopping them;
    ``startup_seconds``, the part of it spent starting; and ``scenes_per_s``, rows per second
    since the workers were ready.
    """

    def __init__(self, scenes: Iterable[Any], *, workers: int | None = None,
                 address: str | None = None, gpus_per_worker: float | None = None,
                 tolerance: float | None = None, ordered: bool = True, batch_size: int = 64,
                 attempts: int = 2, strict: bool = False, base: str | None = None,
                 options: dict | None = None) -> None:
        self._t_start = time.perf_counter()
        for name, value in (("batch_size", batch_size), ("attempts", attempts)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a whole number of at least 1, got {value!r}")
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                    or workers < 1):
            raise ValueError(f"workers must be a whole number of at least 1, got {workers!r}")
        ray = self._ray = _ray(local=not address)
        detector = {"tolerance": tolerance, "strict": strict, **(options or {})}
        from ..request import CollisionRequest

        CollisionRequest(**detector)  # options checked here, once, not in every worker
        self._started = start_ray(ray, address, workers)
        self.closed = False
        try:
            workers, gpus_per_worker = placement(ray, workers, gpus_per_worker)
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
        self._t_ready = time.perf_counter()
        self.summary: dict[str, Any] = {
            "workers": workers, "gpus_per_worker": gpus_per_worker, "batch_size": batch_size,
            "adapter": self.adapter, "scenes": 0, "failed": 0, "retried": 0,
            "worker_failures": 0, "seconds": self._t_ready - self._t_start,
            "startup_seconds": self._t_ready - self._t_start, "scenes_per_s": 0.0}

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
            now = time.perf_counter()
            self.summary["seconds"] = now - self._t_start
            self.summary["scenes_per_s"] = self.summary["scenes"] / max(now - self._t_ready,
                                                                        1e-9)
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
                self._fail(item, why, "worker")
            if self._alive[k]:
                # Calls sent while Ray restarts it would fail too: wait until it answers.
                self._alive[k] = False
                self._probe(k, time.perf_counter())
            return
        for item, result in zip(items, results):
            if "error" in result and result["error_kind"] == "input":
                result["attempts"] = item.attempt  # no other try can succeed: given back now
                self._finish(item.seq, result)
            elif "error" in result:
                self._fail(item, result["error"], result["error_kind"])
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

    def _fail(self, item: _Item, why: str, kind: str) -> None:
        """A scene that failed for a reason another try may not meet (``kind`` ``"worker"``: its
        worker died; ``"query"``: its query raised): tried again, alone, or given back with
        its error after ``attempts`` tries."""
        if item.attempt < self._attempts:
            self.summary["retried"] += 1
            self._retry.append(_Item(item.seq, item.entry, item.attempt + 1))
        else:
            self._finish(item.seq, error_result(
                item.entry["id"], f"{why} (failed {item.attempt} times)", kind, item.attempt))

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
        if hasattr(self, "summary"):
            self.summary["seconds"] = time.perf_counter() - self._t_start

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
        An iterator of one row per scene (see Notes); its ``summary`` says what the run did.

    Raises
    ------
    ValueError
        A bad option, or workers the cluster cannot place. A bad scene raises nothing: its
        row is an error row.

    Notes
    -----
    A row is a dict of plain JSON data. Every row has ``id`` (the scene's) and ``status``,
    ``"ok"`` or ``"error"``. A scene that was checked::

        {"id": "a-17", "status": "ok",
         "pairs": [[0, 2]],                  # colliding bodies: indices into its bodies, i < j
         "names": [["bracket", "base"]],     # the same pairs by body name
         "stats": {"bodies": 3, "attempt": 1, "worker": 0, "query_scenes": 64,
                   "query_ms": 41.2, "candidates_in_query": 310,
                   "warnings": ["scene 'a-17' body 0 ('bracket'): ..."]}}

    A body's name is its ``name``, else its mesh file's name, else ``body J``. In ``stats``:
    ``attempt`` is the try that gave the row, ``worker`` the worker's number,
    ``query_scenes``, ``query_ms`` and ``candidates_in_query`` describe the query the scene
    shared with others; ``warnings`` (open, inside-out or zero-area meshes, each naming the
    scene and the body) and ``possibly_lost_in_query`` appear only when there are some.

    A scene that could not be checked has no ``pairs``, ``names`` or ``stats``::

        {"id": "a-18", "status": "error",
         "error": "FileError: scene 'a-18' body 0 ('bracket'): /data/b.stl: no such file",
         "error_kind": "input", "attempts": 1}

    ``error`` is the exception's type and message, naming the scene and, where one is at
    fault, the body. ``error_kind`` says what failed, and ``attempts`` how many tries were made:

    - ``"input"``: the scene's own input (a mesh file missing or unreadable, NaN vertices, a
      singular transform, an entry with unknown keys). No other try can succeed, so it is
      given back at once, without a retry: fix the input and run the scene again.
    - ``"query"``: its query raised another error on a worker that still answers; given
      back after ``attempts`` tries.
    - ``"worker"``: its worker died while checking it (killed, out of memory, device lost),
      ``attempts`` times; Ray restarts a dead worker and the run goes on.

    Test ``"error" in row`` (or ``row["status"] == "error"``) before reading a row's pairs.

    Examples
    --------
    A scene whose mesh file is missing fails alone, at its first try, naming its body:

    >>> import pycinder.batch
    >>> scenes = [{"id": 7, "bodies": [{"mesh": "lid.stl", "name": "lid"}]}]
    >>> results = pycinder.batch.run(scenes, workers=1, base="/no")
    >>> rows = list(results)
    >>> for row in rows:
    ...     if "error" in row:
    ...         print(f"scene {row['id']} failed ({row['error_kind']}): {row['error']}")
    scene 7 failed (input): FileError: scene 7 body 0 ('lid'): /no/lid.stl: no such file
    >>> rows[0]["attempts"], results.summary["failed"], results.summary["retried"]
    (1, 1, 0)
    """
    return BatchRun(scenes, workers=workers, address=address, gpus_per_worker=gpus_per_worker,
                    tolerance=tolerance, ordered=ordered, batch_size=batch_size,
                    attempts=attempts, strict=strict, base=base, options=options)

"""A robot manifest's configurations over Ray workers (``pycinder batch ROBOT.json --workers N``)::

    configurations not yet in OUT -> chunks (each the rows written at once)
      -> worker actors (the robot and its environment loaded once each, one detector)
      -> rows in the configurations' order

Each worker holds at most :data:`~pycinder.batch.ray_run.DEPTH` chunks, so a worker never waits
for the driver and the driver holds a bounded window of rows. A worker that dies (killed, device
lost) is restarted by Ray, which runs its chunks again (``max_task_retries``); a chunk that still
fails ends the run with its error, the rows before it written (run the same command again to go
on). Ray is started and stopped as :mod:`.ray_run` does it (:func:`~.ray_run.start_ray`,
:func:`~.ray_run.placement`).
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Iterator
from typing import Any

import numpy as np

from .ray_run import DEPTH, _ray, placement, start_ray
from .robot_manifest import check_rows, load_robot

TASK_RETRIES = 2
"""Times Ray runs a chunk again on its restarted worker after the worker died."""


class RobotWorker:
    """A Ray actor's state: the manifest's robot and environment, loaded once.

    Parameters
    ----------
    spec : dict
        The checked manifest (:func:`~pycinder.batch.robot_run.read_robot_manifest`).
    """

    def __init__(self, spec: dict[str, Any]) -> None:
        self.spec = spec
        self.robot, self.environment = load_robot(spec, spec["robot"])

    def ready(self) -> dict[str, Any]:
        """The worker's process and adapter (once its device is up)."""
        return {"pid": os.getpid(), "adapter": self.robot.detector.gpu.description}

    def check(self, ids: np.ndarray, q: np.ndarray, batch: int | None) -> list[dict[str, Any]]:
        """The rows of configurations ``q`` (C, J), numbered ``ids`` (C,)."""
        return check_rows(self.robot, self.environment, self.spec, ids, q, batch)


class RobotRun(Iterator[dict]):
    """The rows of a robot manifest's configurations ``todo`` (indices into ``q``), checked on
    Ray workers, in order. Close it (or use it in a ``with``) to stop early.

    Parameters
    ----------
    spec : dict
        The checked manifest.
    q : (C, J) float
        Every configuration of the manifest.
    todo : (T,) int
        The configurations to check.
    workers : int, optional
        Workers (default: a GPU each where the cluster has GPUs, else one).
    address : str, optional
        A Ray cluster's address (default: a local instance of ``workers`` CPUs).
    gpus_per_worker : float, optional
        GPUs each worker takes (default: one where the cluster has GPUs, else none).
    chunk : int
        Configurations a worker is given at once.
    batch : int, optional
        Configurations per query (:meth:`pycinder.robot.Robot.check`'s ``batch``).
    """

    def __init__(self, spec: dict[str, Any], q: np.ndarray, todo: np.ndarray, *,
                 workers: int | None = None, address: str | None = None,
                 gpus_per_worker: float | None = None, chunk: int = 1000,
                 batch: int | None = None) -> None:
        if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
            raise ValueError(f"chunk must be a whole number of at least 1, got {chunk!r}")
        ray = self._ray = _ray(local=not address)
        self._started = start_ray(ray, address, workers)
        self.closed = False
        try:
            self.workers, gpus = placement(ray, workers, gpus_per_worker)
            actor = ray.remote(RobotWorker).options(
                num_cpus=1, num_gpus=gpus, max_restarts=-1, max_task_retries=TASK_RETRIES)
            self._actors = [actor.remote(spec) for _ in range(self.workers)]
            ready = ray.get([a.ready.remote() for a in self._actors])
        except BaseException:
            self.close()
            raise
        self.pids = [r["pid"] for r in ready]
        self.adapter = ready[0]["adapter"]
        self._chunks = deque(np.asarray(todo[k:k + chunk], np.int64)
                             for k in range(0, len(todo), chunk))
        self._q, self._batch = q, batch
        self._flight: deque[Any] = deque()  # in the configurations' order
        self._next = 0  # the worker given the next chunk
        self._rows: deque[dict] = deque()

    def __iter__(self) -> RobotRun:
        return self

    def __next__(self) -> dict:
        try:
            while not self._rows:
                self._fill()
                if not self._flight:
                    self.close()
                    raise StopIteration
                self._rows.extend(self._ray.get(self._flight.popleft()))
            return self._rows.popleft()
        except StopIteration:
            raise
        except BaseException:
            self.close()
            raise

    def _fill(self) -> None:
        """Give out chunks, in order, round the workers, up to DEPTH each in flight."""
        while self._chunks and len(self._flight) < DEPTH * self.workers:
            ids = self._chunks.popleft()
            worker = self._actors[self._next]
            self._next = (self._next + 1) % self.workers
            self._flight.append(worker.check.remote(ids, self._q[ids], self._batch))

    def close(self) -> None:
        """Stop the workers (and the local Ray instance this run started)."""
        if self.closed:
            return
        self.closed = True
        if self._ray.is_initialized():
            for a in getattr(self, "_actors", []):
                self._ray.kill(a)
            if self._started:
                self._ray.shutdown()

    def __enter__(self) -> RobotRun:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


__all__ = ["TASK_RETRIES", "RobotRun", "RobotWorker"]

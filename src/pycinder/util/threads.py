"""The host's worker threads: one pool for the NumPy and hashing work of a query (validating large
bodies, planning many tiles), which release the GIL on large arrays.

A forked child (as ``multiprocessing`` makes on Linux) has none of its parent's threads: it makes
a pool of its own when it needs one.

The pool has as many threads as the process may use CPUs, at most :data:`MOST_WORKERS`: the CPUs
of its affinity mask (``taskset``, a scheduler's placement) and of its cgroup's CPU quota (a
container's ``--cpus``), not every CPU of the machine. ``PYCINDER_THREADS`` sets the number
(1: no pool); ``OMP_NUM_THREADS``, which other NumPy-side libraries also follow, caps it.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

MOST_WORKERS = 8
"""Most threads of the pool when ``PYCINDER_THREADS`` does not set the number."""


def _cgroup_cpus(root: str = "/sys/fs/cgroup") -> float | None:
    """CPUs of the cgroup's quota (v2 ``cpu.max``, or v1 ``cpu.cfs_quota_us``) under the cgroup
    file system ``root``; None when there is none or it cannot be read."""
    for quota_file, period_file in ((f"{root}/cpu.max", None),
                                    (f"{root}/cpu/cpu.cfs_quota_us",
                                     f"{root}/cpu/cpu.cfs_period_us")):
        try:
            with open(quota_file) as f:
                words = f.read().split()
            if period_file is not None:
                with open(period_file) as f:
                    words += f.read().split()
            if len(words) < 2 or words[0] in ("max", "-1"):
                continue
            quota, period = float(words[0]), float(words[1])
            if quota > 0 and period > 0:
                return quota / period
        except (OSError, ValueError):
            continue
    return None


def _positive_int(name: str) -> int | None:
    value = os.environ.get(name, "").strip()
    if not value:
        return None
    try:
        number = int(value)
    except ValueError:
        number = 0
    if number < 1:
        raise ValueError(f"{name} must be a whole number of at least 1, got {value!r}")
    return number


def usable_cpus() -> int:
    """CPUs this process may run on: its affinity mask, within its cgroup's CPU quota."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on every OS
        cpus = os.cpu_count() or 1
    quota = _cgroup_cpus()
    if quota is not None:
        cpus = min(cpus, max(int(quota), 1))  # a fraction of a CPU is one thread
    return max(cpus, 1)


def workers() -> int:
    """Threads the pool gets (see the module's docstring)."""
    given = _positive_int("PYCINDER_THREADS")
    if given is not None:
        return given
    count = min(MOST_WORKERS, usable_cpus())
    # OpenMP's variable may list one count per nesting level ("4,2"): the first is the outer.
    first = os.environ.get("OMP_NUM_THREADS", "").split(",")[0].strip()
    cap = int(first) if first.isdigit() and int(first) > 0 else None
    return count if cap is None else min(count, cap)


WORKERS = workers()
"""Threads of the pool (one on a single core: then nothing runs on the pool)."""

_pool: ThreadPoolExecutor | None = None
_made = threading.Lock()


def pool() -> ThreadPoolExecutor | None:
    """The pool, made on first use (once, whichever thread asks first); None with a single
    core."""
    global _pool
    if WORKERS < 2:
        return None
    with _made:
        if _pool is None:
            _pool = ThreadPoolExecutor(max_workers=WORKERS, thread_name_prefix="pycinder")
        return _pool


def _forget_pool() -> None:
    global _pool, _made
    _pool, _made = None, threading.Lock()  # a lock held at the fork stays held in the child


os.register_at_fork(after_in_child=_forget_pool)

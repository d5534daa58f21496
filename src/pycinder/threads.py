"""The host's worker threads: one pool for the NumPy and hashing work of a query (validating large
bodies, planning many tiles), which release the GIL on large arrays.

A forked child (as ``multiprocessing`` makes on Linux) has none of its parent's threads: it makes
a pool of its own when it needs one.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

WORKERS = min(8, os.cpu_count() or 1)
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

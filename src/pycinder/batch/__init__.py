"""Many scenes: in one query (:func:`find_collisions_batch`) and over Ray workers (:func:`run`).

    from pycinder.batch import run
    for result in run(scenes, workers=4):     # scenes: manifest entries (dicts)
        print(result["id"], result["pairs"])

Ray is optional (``pip install '.[cluster]'``); it is imported only by :func:`run`.
"""

from __future__ import annotations

from typing import Any

from .query import find_collisions_batch

__all__ = ["find_collisions_batch", "run"]


def run(*args: Any, **kwargs: Any) -> Any:
    """See :func:`pycinder.batch.run.run` (imports Ray)."""
    from .ray_run import run as _run

    return _run(*args, **kwargs)

"""Many scenes: in one query (:func:`find_collisions_batch`) and over Ray workers (:func:`run`).

    import pycinder.batch
    for result in pycinder.batch.run(scenes, workers=4):    # scenes: manifest entries (dicts)
        print(result["id"], result["names"])

Ray is optional (``pip install '.[cluster]'``): :func:`run` imports it when called.
"""

from .query import find_collisions_batch
from .ray_run import BatchRun, run

__all__ = ["BatchRun", "find_collisions_batch", "run"]

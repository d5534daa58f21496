"""Many scenes: in one query (:func:`find_collisions_batch`) and over Ray workers (:func:`run`).

:func:`run` (and ``pycinder batch``, which writes them to a file) gives one row per scene, a
dict of plain JSON data, in the scenes' order (or as they complete). Every row has ``id`` and
``status``:

- ``"ok"``: the scene was checked; ``pairs`` (indices into its bodies), ``names`` (the same
  pairs by body name) and ``stats`` say what was found.
- ``"error"``: it could not be; ``error`` says why, naming the scene and the body at fault,
  ``error_kind`` what failed (``"input"``: the scene's own input, given back at once;
  ``"query"`` or ``"worker"``: after ``attempts`` tries) and ``attempts`` how many tries were
  made. An error row has no ``pairs``, ``names`` or ``stats``.

:func:`run`'s notes list every key. Test ``"error" in row`` before reading a row's pairs:

>>> import trimesh
>>> import pycinder.batch
>>> box = trimesh.creation.box((1.0, 1.0, 1.0))
>>> moved = trimesh.transformations.translation_matrix((0.5, 0.0, 0.0))
>>> scenes = [
...     {"id": "lid-on-base", "bodies": [{"mesh": box, "name": "base"},
...                                      {"mesh": box, "transform": moved, "name": "lid"}]},
...     {"id": "lost-part", "bodies": [{"mesh": "no-such-file.stl", "name": "ghost"}]},
... ]
>>> for row in pycinder.batch.run(scenes, workers=1):
...     if "error" in row:
...         print(row["id"], "failed:", row["error_kind"])
...     else:
...         print(row["id"], row["names"])
lid-on-base [['base', 'lid']]
lost-part failed: input

Ray is optional (``pip install 'pycinder[cluster]'``): :func:`run` imports it when called.
"""

from .query import find_collisions_batch
from .ray_run import BatchRun, run

__all__ = ["BatchRun", "find_collisions_batch", "run"]

"""A batch worker: one Detector, the meshes it has read, and chunks of scenes checked.

    chunk of scene entries -> meshes (by path, read once) + transforms
      -> one query for the whole chunk (find_collisions_batch), or one per scene
      -> a result per scene (:func:`ok_result`, :func:`error_result`)

On Ray each worker is an actor wrapping this class (:mod:`.ray_run`); it runs the same
in-process. A chunk whose query fails is run again scene by scene, so that one bad scene
fails alone. A scene's failure is classed (:func:`error_kind`): bad input (a mesh file missing
or unreadable, NaN vertices, a singular transform) fails the same way on every try, so the
driver writes it at once; any other error may be the device's, and is tried again.
"""

from __future__ import annotations

import os
import time
import warnings
from typing import Any

import numpy as np

from .manifest import MeshCache, body_label, body_name

INPUT_ERRORS: tuple[type[BaseException], ...] = (ValueError, TypeError, OSError)
"""What pycinder raises for a scene's own input (FileError and ManifestError are ValueErrors,
FileNotFoundError an OSError): no other try can succeed."""


class BodyError(Exception):
    """A body that cannot be used: the error of its scene, naming the body.

    Parameters
    ----------
    where : str
        The body, as :func:`.manifest.body_label` names it.
    cause : BaseException
        What loading or checking its mesh raised.
    """

    def __init__(self, where: str, cause: BaseException) -> None:
        super().__init__(f"{type(cause).__name__}: {where}: {cause}")
        self.cause = cause


def error_kind(exc: BaseException) -> str:
    """``"input"`` for the scene's own bad input (:data:`INPUT_ERRORS`), else ``"query"``."""
    cause = exc.cause if isinstance(exc, BodyError) else exc
    return "input" if isinstance(cause, INPUT_ERRORS) else "query"


def ok_result(scene_id: Any, pairs: list, names: list, stats: dict) -> dict:
    """The result row of a scene that was checked (the schema: :mod:`pycinder.batch`)."""
    return {"id": scene_id, "status": "ok", "pairs": pairs, "names": names, "stats": stats}


def error_result(scene_id: Any, exc: BaseException | str, kind: str | None = None,
                 attempts: int = 1) -> dict:
    """The result row of a scene that could not be checked (the schema: :mod:`pycinder.batch`).

    Parameters
    ----------
    scene_id : str or int
    exc : BaseException or str
        The error, or its text.
    kind : {"input", "query", "worker"}, optional
        Why it failed (default: :func:`error_kind` of ``exc``; ``"query"`` for a text).
    attempts : int
        Tries made.
    """
    if isinstance(exc, BodyError):
        text = str(exc)
    else:
        text = exc if isinstance(exc, str) else f"{type(exc).__name__}: {exc}"
    if kind is None:
        kind = "query" if isinstance(exc, str) else error_kind(exc)
    return {"id": scene_id, "status": "error", "error": text, "error_kind": kind,
            "attempts": attempts}


class BatchWorker:
    """Checks chunks of scene entries (see :func:`.manifest.normalize`) on one Detector.

    Parameters
    ----------
    options : dict
        Options of :class:`~pycinder.CollisionRequest` for the detector.
    index : int
        The worker's number, reported in each result's stats.
    """

    def __init__(self, options: dict | None = None, index: int = 0) -> None:
        from ..detector import Detector

        self.detector = Detector(**(options or {}))
        self.meshes = MeshCache(self.detector.shapes, strict=self.detector.request.strict)
        self.index = index

    def ready(self) -> dict:
        """The worker's process and adapter, once its detector has answered a first query (its
        pipelines are built then, not in the first chunk's time)."""
        if not self._healthy():
            raise RuntimeError(f"worker {self.index}: the detector on "
                               f"{self.detector.gpu.description} failed a query of two boxes")
        return {"pid": os.getpid(), "adapter": self.detector.gpu.description,
                "index": self.index}

    def mesh_loads(self) -> int:
        """Mesh files read so far (each at most once while it stays cached)."""
        return self.meshes.loads

    def check(self, entries: list[dict], batch: bool = True) -> list[dict]:
        """A result per entry, in order: all scenes in one query when ``batch``, else one
        query per scene."""
        out: list[dict | None] = [None] * len(entries)
        scenes = []
        for k, entry in enumerate(entries):
            try:
                scenes.append((k, self._scene(entry)))
            except BodyError as exc:  # a mesh that cannot be read fails its scene alone
                out[k] = error_result(entry["id"], exc)
        done = False
        if batch and len(scenes) > 1:
            try:
                self._query(scenes, entries, out)
                done = True
            except Exception:  # run scene by scene: the failing one fails alone
                pass
        if not done:
            failed = False
            for item in scenes:
                try:
                    self._query([item], entries, out)
                except Exception as exc:
                    out[item[0]] = error_result(entries[item[0]]["id"], exc)
                    failed = failed or error_kind(exc) != "input"
            if failed and not self._healthy():  # bad input says nothing of the device
                # The device is gone: end this process, so that Ray starts a fresh one and
                # the scenes of this call are tried again there.
                os._exit(70)
        return out  # type: ignore[return-value]

    def _healthy(self) -> bool:
        """Whether the detector still answers a query it must: two overlapping boxes."""
        import trimesh

        box = trimesh.creation.box((1.0, 1.0, 1.0))
        moved = np.eye(4)
        moved[0, 3] = 0.5
        try:
            return len(self.detector.find_collisions([box, box], [np.eye(4), moved]).pairs) == 1
        except Exception:
            return False

    def _scene(self, entry: dict) -> dict:
        """The meshes, transforms and names of a scene, and the warnings its mesh files raised,
        each naming its body (scene id and manifest name) before the file.

        Raises
        ------
        BodyError
            A mesh that cannot be read or checked, naming the scene and the body.
        """
        names = [body_name(b, j) for j, b in enumerate(entry["bodies"])]
        bodies, said = [], []
        for j, body in enumerate(entry["bodies"]):
            if not isinstance(body["mesh"], str):
                bodies.append(body["mesh"])
                continue
            where = body_label(entry["id"], j, names[j])
            try:
                mesh, warned = self.meshes.get(body["mesh"])
            except Exception as exc:
                raise BodyError(where, exc) from exc
            bodies.append(mesh)
            said += [f"{where}: {w}" for w in warned]
        n = len(bodies)
        transforms = np.tile(np.eye(4), (n, 1, 1))
        for j, body in enumerate(entry["bodies"]):
            if body["transform"] is not None:
                transforms[j] = body["transform"]
        return {"bodies": bodies, "transforms": transforms, "names": names, "warnings": said}

    def _query(self, scenes: list[tuple[int, dict]], entries: list[dict],
               out: list[dict | None]) -> None:
        t0 = time.perf_counter()
        picked = [entries[k] for k, _ in scenes]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            results = self.detector.find_collisions_batch(
                [(s["bodies"], s["transforms"], s["names"]) for _, s in scenes],
                tolerance=[e.get("tolerance") for e in picked],
                labels=[e["id"] for e in picked], records="none")
        ms = (time.perf_counter() - t0) * 1e3
        said = sorted({str(w.message) for w in caught})
        ids = [e["id"] for e in picked]
        for (k, scene), result in zip(scenes, results):
            names = scene["names"]
            stats = {"bodies": len(names), "candidates_in_query": result.stats.candidates,
                     "query_scenes": len(scenes), "query_ms": round(ms, 3),
                     "worker": self.index}
            mine = scene["warnings"] + _own(said, ids, entries[k]["id"])
            if mine:
                stats["warnings"] = mine
            if result.stats.possibly_lost:
                stats["possibly_lost_in_query"] = result.stats.possibly_lost
            pairs = result.pairs.tolist()
            out[k] = ok_result(entries[k]["id"], pairs,
                               [[names[i], names[j]] for i, j in pairs], stats)


def _own(messages: list[str], ids: list[Any], scene_id: Any) -> list[str]:
    """The warnings of a query of several scenes that concern ``scene_id``: those that name no
    other scene of the query (the query names bodies ``scene ID: NAME``)."""
    others = [f"scene {i}: " for i in ids if i != scene_id]
    own = f"scene {scene_id}: "
    return [m for m in messages if own in m or not any(o in m for o in others)]

"""A batch worker: one Detector, the meshes it has read, and chunks of scenes checked.

    chunk of scene entries -> meshes (by path, read once) + transforms
      -> one query for the whole chunk (find_collisions_batch), or one per scene
      -> a result per scene: id, pairs, names, stats; or id and error

On Ray each worker is an actor wrapping this class (:mod:`.ray_run`); it runs the same
in-process. A chunk whose query fails is run again scene by scene, so that one bad scene
fails alone.
"""

from __future__ import annotations

import os
import time
import warnings
from typing import Any

import numpy as np

from .manifest import MeshCache, body_name


def error_result(scene_id: Any, exc: BaseException | str) -> dict:
    """The result of a scene that could not be checked."""
    text = exc if isinstance(exc, str) else f"{type(exc).__name__}: {exc}"
    return {"id": scene_id, "error": text}


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
            except Exception as exc:  # a mesh that cannot be read fails its scene alone
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
                    failed = True
            if failed and not self._healthy():
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
        bodies, mesh_warnings = [], set()
        for body in entry["bodies"]:
            if isinstance(body["mesh"], str):
                mesh, said = self.meshes.get(body["mesh"])
                mesh_warnings.update(said)
                bodies.append(mesh)
            else:
                bodies.append(body["mesh"])
        n = len(bodies)
        transforms = np.tile(np.eye(4), (n, 1, 1))
        for j, body in enumerate(entry["bodies"]):
            if body["transform"] is not None:
                transforms[j] = body["transform"]
        names = [body_name(b, j) for j, b in enumerate(entry["bodies"])]
        return {"bodies": bodies, "transforms": transforms, "names": names,
                "warnings": sorted(mesh_warnings)}

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
        for (k, scene), result in zip(scenes, results):
            names = scene["names"]
            stats = {"bodies": len(names), "candidates_in_query": result.stats.candidates,
                     "query_scenes": len(scenes), "query_ms": round(ms, 3),
                     "worker": self.index}
            if scene["warnings"] or said:
                stats["warnings"] = scene["warnings"] + said
            if result.stats.possibly_lost:
                stats["possibly_lost_in_query"] = result.stats.possibly_lost
            out[k] = {"id": entries[k]["id"], "pairs": result.pairs.tolist(),
                      "names": [[names[i], names[j]] for i, j in result.pairs.tolist()],
                      "stats": stats}

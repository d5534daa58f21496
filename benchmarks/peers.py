"""The systems compared, each answering "which pairs collide in this frame?".

* pycinder: one :class:`~pycinder.Detector` kept across frames, asked for pairs only
  (``records="none"``) like the others, the meshes of rigid scenes checked once
  (``Detector.prepare``); ``pycinder-scene`` is the paper's whole-scene strategy.
* python-fcl: ``BVHModel`` objects in a ``DynamicAABBTreeCollisionManager``; python-fcl cannot
  refit, so deforming meshes are rebuilt every frame.
* coal: ``BVHModelOBBRSS`` refitted through ``beginReplaceModel``/``replaceSubModel``. Its Python
  bindings accept no Python broad-phase callback, so candidate pairs come from a NumPy sweep over
  world AABBs and each candidate goes through ``coal.collide``.
* trimesh: ``trimesh.collision.CollisionManager`` (FCL underneath, with trimesh's own overhead);
  deforming meshes are re-added every frame.
* warp: everything on the Warp device (:mod:`.warp_peer`): world boxes, a sort-and-sweep broad
  phase and a triangle-versus-BVH narrow phase in kernels replayed as one graph per frame, with
  ``wp.Mesh`` BVHs refitted only when bodies deform; its CPU device here, CUDA on a GPU.

Every peer reports all colliding pairs, not just the first.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pycinder.detector import Detector
from pycinder.focused.broad.broad_numpy import sweep_and_prune
from pycinder.scene import PreparedBodies
from pycinder.testing.scenes import Scene
from pycinder.util import optional

from .system import System
from .warp_peer import Warp


def aabb_candidates(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Pairs (K, 2) whose world boxes overlap; lo, hi : (N, 3). The peers get pycinder's own
    vectorised sweep, so that no system pays for a slow broad phase."""
    return sweep_and_prune(lo, hi)


def world_aabbs(verts: list[np.ndarray], transforms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = [], []
    for v, t in zip(verts, transforms):
        w = v @ t[:3, :3].T + t[:3, 3]
        lo.append(w.min(axis=0))
        hi.append(w.max(axis=0))
    return np.array(lo), np.array(hi)


def require(module: str, package: str) -> Any:
    """Import an optional peer, or say which extra installs it."""
    return optional.require(module, f"the {package} peer", "bench", package)


def as_pairs(found: set[tuple[int, int]]) -> np.ndarray:
    return np.array(sorted(found), dtype=np.int64).reshape(-1, 2)


class Pycinder(System):
    """pycinder with a request's options (default: the focused strategy, pairs only). The
    meshes are checked once (:meth:`~pycinder.Detector.prepare`), as the other systems build
    their BVHs once; a deforming scene's new vertices are given to every body each frame
    (:meth:`~pycinder.PreparedBodies.update`, timed, as the others' refits are)."""

    def __init__(self, name: str = "pycinder", **options: Any) -> None:
        options.setdefault("records", "none")
        self.detector = Detector(**options)
        self.name = name
        self.last = None
        self.prepared: PreparedBodies | None = None

    def prepare(self, scene: Scene) -> None:
        self.prepared = self.detector.prepare(scene.bodies(0)[0])

    def bodies(self, scene: Scene, k: int) -> tuple[Any, np.ndarray]:
        """What a query of frame k is given: the prepared bodies (with frame k's vertices, for
        a deforming scene) and the transforms."""
        vertices, transforms = scene.frame(k)
        if self.prepared is None:  # not prepared: the meshes as they are
            return list(zip(vertices, scene.faces)), transforms
        if scene.deforming:
            self.prepared.update(range(len(vertices)), vertices)
        return self.prepared, transforms

    def step(self, scene: Scene, k: int) -> np.ndarray:
        self.last = self.detector.find_collisions(*self.bodies(scene, k))
        return self.last.pairs


class FCL(System):
    name = "python-fcl"

    def __init__(self) -> None:
        fcl = self.fcl = require("fcl", "python-fcl")
        self.request = fcl.CollisionRequest(num_max_contacts=1, enable_contact=False)

    def _build(self, verts: list[np.ndarray], faces: list[np.ndarray], transforms: np.ndarray) -> None:
        fcl = self.fcl
        self.geoms, self.objs = [], []
        for v, f, t in zip(verts, faces, transforms):
            g = fcl.BVHModel()
            g.beginModel(len(v), len(f))
            g.addSubModel(np.asarray(v, np.float64), np.asarray(f, np.int32))
            g.endModel()
            self.geoms.append(g)
            self.objs.append(fcl.CollisionObject(g, fcl.Transform(t[:3, :3], t[:3, 3])))
        self.index = {id(g): i for i, g in enumerate(self.geoms)}
        self.manager = fcl.DynamicAABBTreeCollisionManager()
        self.manager.registerObjects(self.objs)
        self.manager.setup()

    def prepare(self, scene: Scene) -> None:
        verts, transforms = scene.frame(0)
        self._build(verts, scene.faces, transforms)

    def step(self, scene: Scene, k: int) -> np.ndarray:
        fcl = self.fcl
        verts, transforms = scene.frame(k)
        if scene.deforming:
            self._build(verts, scene.faces, transforms)  # no refit in python-fcl
        else:
            for o, t in zip(self.objs, transforms):
                o.setTransform(fcl.Transform(t[:3, :3], t[:3, 3]))
            self.manager.update()
        found: set[tuple[int, int]] = set()
        index, request = self.index, self.request

        def callback(o1: Any, o2: Any, cdata: Any) -> bool:
            result = fcl.CollisionResult()
            if fcl.collide(o1, o2, request, result):
                c = result.contacts[0]
                a, b = index[id(c.o1)], index[id(c.o2)]
                found.add((min(a, b), max(a, b)))
            return False

        self.manager.collide(fcl.CollisionData(), callback)
        return as_pairs(found)


class Coal(System):
    name = "coal"

    def __init__(self) -> None:
        self.coal = require("coal", "coal")

    def prepare(self, scene: Scene) -> None:
        coal = self.coal
        verts, transforms = scene.frame(0)
        self.geoms, self.objs = [], []
        for v, f, t in zip(verts, scene.faces, transforms):
            g = coal.BVHModelOBBRSS()
            g.beginModel(len(f), len(v))
            g.addVertices(np.asarray(v, np.float64))
            g.addTriangles(np.asarray(f, np.int64))
            g.endModel()
            self.geoms.append(g)
            self.objs.append(coal.CollisionObject(g, coal.Transform3s(t[:3, :3], t[:3, 3])))
        self.request = coal.CollisionRequest()

    def step(self, scene: Scene, k: int) -> np.ndarray:
        coal = self.coal
        verts, transforms = scene.frame(k)
        if scene.deforming:
            for g, v in zip(self.geoms, verts):
                points = coal.StdVec_Vec3s()
                points.extend(list(np.asarray(v, np.float64)))
                g.beginReplaceModel()
                g.replaceSubModel(points)
                g.endReplaceModel(True, True)  # refit, bottom-up
        for o, t in zip(self.objs, transforms):
            o.setTransform(coal.Transform3s(t[:3, :3], t[:3, 3]))
        lo, hi = world_aabbs(verts, transforms)
        found = set()
        for i, j in aabb_candidates(lo, hi).tolist():
            result = coal.CollisionResult()
            if coal.collide(self.objs[i], self.objs[j], self.request, result):
                found.add((i, j))
        return as_pairs(found)


class Trimesh(System):
    name = "trimesh"

    def prepare(self, scene: Scene) -> None:
        import trimesh

        verts, transforms = scene.frame(0)
        self.meshes = [trimesh.Trimesh(v, f, process=False) for v, f in zip(verts, scene.faces)]
        self.manager = trimesh.collision.CollisionManager()
        for i, (m, t) in enumerate(zip(self.meshes, transforms)):
            self.manager.add_object(str(i), m, t)

    def step(self, scene: Scene, k: int) -> np.ndarray:
        import trimesh

        verts, transforms = scene.frame(k)
        for i, t in enumerate(transforms):
            if scene.deforming:
                self.manager.add_object(str(i), trimesh.Trimesh(verts[i], scene.faces[i],
                                                                process=False), t)
            else:
                self.manager.set_transform(str(i), t)
        _, names = self.manager.in_collision_internal(return_names=True)
        return as_pairs({tuple(sorted((int(a), int(b)))) for a, b in names})


PEERS = {"python-fcl": FCL, "coal": Coal, "trimesh": Trimesh, "warp": Warp}

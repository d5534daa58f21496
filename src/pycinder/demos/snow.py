"""Snow Bunny (paper 5.2): snowflakes of 6 triangles fall on the Stanford bunny and a floor.

A flake that hits freezes, is enlarged, and moves to a list that detection no longer checks; flakes
frozen on the bunny turn with it. The scene holds at most ``flakes`` flakes: once it is full, the
oldest frozen flakes melt as new ones fall, so that it snows for as long as the demo runs. ``scan=True`` uses pymeshlab's scanned 10k bunny, which is open at
the bottom (the paper's hole problem): pycinder warns, and ``close_holes=True`` repairs it first.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np
import trimesh

from ..detector import Detector
from ..scene import OpenMeshWarning
from ..testing import bunny, sample_mesh_path
from .display import Layer, Look

FLAKE_SIZE = 0.025
BUNNY_REACH, BUNNY_TOP = 0.4, 0.65
"""The turning bunny stays within this distance of the y axis and below this height."""
FLOOR = (2.4, 0.1, 2.4)
DT = 1.0 / 30.0
FPS = 30
LOOK = Look(eye=(1.05, 0.95, 1.75), target=(0.0, 0.24, 0.0), fov=42.0,
            keep_in_view=np.array([[-0.45, 0.0, -0.45], [0.45, 0.62, 0.45]]),
            background=("#a9bbd1", "#33425b"), sun=(0.5, 1.0, 0.35), shadow_extent=3.0)
BUNNY_COLOUR = (0.80, 0.70, 0.58)
FLOOR_COLOUR = (0.42, 0.52, 0.47)
FLAKE_COLOUR = (1.0, 1.0, 1.0)
FROZEN_COLOUR = (0.78, 0.88, 1.0)


def flake_mesh(size: float = FLAKE_SIZE) -> trimesh.Trimesh:
    """A closed snowflake of 6 triangles: a flat triangular bipyramid."""
    ang = np.radians([90, 210, 330])
    ring = np.c_[np.cos(ang), np.zeros(3), np.sin(ang)] * size
    v = np.vstack([ring, [[0, 0.35 * size, 0], [0, -0.35 * size, 0]]])
    f = np.array([[0, 3, 1], [1, 3, 2], [2, 3, 0], [0, 1, 4], [1, 2, 4], [2, 0, 4]])
    mesh = trimesh.Trimesh(v, f, process=False)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def load_bunny(scan: bool = False, close_holes: bool = False, subdivisions: int = 1
               ) -> tuple[trimesh.Trimesh, str]:
    """The demo's bunny, scaled to about 0.6 across with its feet at y = 0, and a note on it."""
    if close_holes and not scan:
        raise ValueError("close_holes (--close-holes) repairs the scanned bunny; the default "
                         "bunny is closed already: add scan=True (--scan)")
    if scan:
        mesh = trimesh.load(sample_mesh_path("bunny10k_textured.obj"), force="mesh", process=True)
        note = "scanned bunny (open at the bottom)"
        if close_holes:
            import pymeshlab

            ms = pymeshlab.MeshSet()
            ms.add_mesh(pymeshlab.Mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces)))
            ms.meshing_remove_duplicate_vertices()
            ms.meshing_repair_non_manifold_edges()
            ms.meshing_close_holes(maxholesize=2000)
            m = ms.current_mesh()
            mesh = trimesh.Trimesh(m.vertex_matrix(), m.face_matrix(), process=True)
            trimesh.repair.fix_normals(mesh)
            note = f"scanned bunny, holes closed (watertight: {mesh.is_watertight})"
    else:
        mesh = bunny(subdivisions)
        note = f"Stanford bunny, {len(mesh.faces)} triangles"
    mesh = mesh.copy()
    mesh.apply_translation(-mesh.bounds.mean(axis=0))
    mesh.apply_scale(0.6 / mesh.extents.max())
    mesh.apply_translation((0, -mesh.bounds[0, 1] - 0.01, 0))  # feet just into the floor
    return mesh, note


@dataclass
class Frozen:
    transform: np.ndarray  # world from flake when frozen on the floor, bunny-local on the bunny
    on_bunny: bool


class SnowSim:
    def __init__(self, flakes: int = 150, seed: int = 0, tolerance: float | None = None,
                 scan: bool = False,
                 close_holes: bool = False, spin: float = 0.6) -> None:
        self.rng = np.random.default_rng(seed)
        self.bunny, self.note = load_bunny(scan, close_holes)
        self.floor = trimesh.creation.box(FLOOR)
        self.floor_t = trimesh.transformations.translation_matrix((0, -FLOOR[1] / 2, 0))
        self.flake = flake_mesh()
        self.big_flake = flake_mesh(FLAKE_SIZE * 1.8)
        self.capacity = flakes
        self.position = np.zeros((0, 3))
        self.velocity = np.zeros((0, 3))
        self.frozen: list[Frozen] = []
        self.landed = 0
        """Flakes that have landed so far (the oldest frozen ones melt away)."""
        self.spin = spin
        self.angle = 0.0
        self.detector = Detector(tolerance=tolerance, contacts=True)  # pairs and contacts
        self.warnings: list[str] = []

    def bunny_transform(self) -> np.ndarray:
        return trimesh.transformations.rotation_matrix(self.angle, (0, 1, 0))

    def _spawn(self) -> None:
        """Four new flakes a frame above the scene, up to a third of ``flakes`` in the air; on
        the first frame that third at every height, so that flakes land from the first frames
        on."""
        first = not len(self.position) and not self.landed
        falling = max(self.capacity // 3, 4)  # at most this many in the air at once
        n = min(falling if first else 4, falling - len(self.position))
        if n <= 0:
            return
        # The scene holds at most `capacity` flakes: the oldest frozen ones melt to make room.
        melt = len(self.position) + len(self.frozen) + n - self.capacity
        if melt > 0:
            del self.frozen[:melt]
        p = np.c_[self.rng.uniform(-0.45, 0.45, n),
                  self.rng.uniform(0.15 if first else 1.0, 1.2, n),
                  self.rng.uniform(-0.45, 0.45, n)]
        # None starts inside the (turning) bunny: those over its footprint start above it.
        over = (np.hypot(p[:, 0], p[:, 2]) < BUNNY_REACH) & (p[:, 1] < BUNNY_TOP)
        p[over, 1] += BUNNY_TOP
        v = np.c_[self.rng.normal(0, 0.05, n), self.rng.uniform(-0.7, -0.5, n),
                  self.rng.normal(0, 0.05, n)]
        self.position = np.vstack([self.position, p])
        self.velocity = np.vstack([self.velocity, v])

    def step(self) -> dict:
        """Advance one frame: spawn, fall, detect, freeze the flakes that hit.

        Returns
        -------
        dict
            ``result``, ``ms`` (detection and contact time), ``pairs`` (colliding flake-bunny
            and flake-floor pairs), ``frozen_now``, ``marks`` and ``normals`` ((C, 3) the
            contacts of those pairs and their normals, from the bunny or floor into the flake),
            ``frozen_at``.
        """
        self._spawn()
        self.angle += self.spin * DT
        self.position += self.velocity * DT
        bt = self.bunny_transform()
        flakes = np.tile(np.eye(4), (len(self.position), 1, 1))
        flakes[:, :3, 3] = self.position
        bodies = [self.bunny, self.floor] + [self.flake] * len(self.position)
        transforms = np.concatenate([bt[None], self.floor_t[None], flakes])
        # Flakes fall through each other, and the bunny stands in the floor: only flakes
        # against the bunny and the floor are tested.
        groups = np.r_[0, 0, np.ones(len(self.position), np.int64)]
        t0 = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", OpenMeshWarning)
            result = self.detector.find_collisions(bodies, transforms, groups=groups)
            contacts = result.contacts()
        self.warnings += [str(w.message) for w in caught if issubclass(w.category, OpenMeshWarning)]
        ms = (time.perf_counter() - t0) * 1e3
        pairs = result.pairs
        hits = pairs[(pairs[:, 0] < 2) & (pairs[:, 1] >= 2)]
        stuck = {}
        for target, flake in hits.tolist():
            stuck.setdefault(flake - 2, target)
        self.landed += len(stuck)
        for k, target in stuck.items():
            t = flakes[k].copy()
            if target == 0:
                self.frozen.append(Frozen(np.linalg.inv(bt) @ t, True))
            else:
                self.frozen.append(Frozen(t, False))
        keep = np.ones(len(self.position), bool)
        keep[list(stuck)] = False
        keep &= self.position[:, 1] > -0.5
        self.position, self.velocity = self.position[keep], self.velocity[keep]
        return {"result": result, "ms": ms, "pairs": len(hits), "frozen_now": len(stuck),
                "marks": contacts.point, "normals": contacts.normal,
                "frozen_at": [flakes[k] for k in stuck]}

    def frozen_world(self) -> np.ndarray:
        bt = self.bunny_transform()
        return np.array([bt @ f.transform if f.on_bunny else f.transform for f in self.frozen]
                        ).reshape(-1, 4, 4)

    def layers(self) -> dict[str, Layer]:
        """What the display shows: the bunny, the floor, falling and frozen flakes."""
        flakes = np.tile(np.eye(4), (len(self.position), 1, 1))
        flakes[:, :3, 3] = self.position
        return {"bunny": Layer(self.bunny, self.bunny_transform()[None], np.array(BUNNY_COLOUR)),
                "floor": Layer(self.floor, self.floor_t[None], np.array(FLOOR_COLOUR), flat=True),
                "flakes": Layer(self.flake, flakes, np.array(FLAKE_COLOUR), flat=True,
                                shadows=False),
                "frozen": Layer(self.big_flake, self.frozen_world(), np.array(FROZEN_COLOUR),
                                flat=True, shadows=False)}

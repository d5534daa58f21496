"""Edges coloured by normals (paper 5.3): spheres bounce off the bunny using the surface normal
read straight from the collision records (``Detector(encode="normal")``), with no CPU lookup of
the mesh. No response when a sphere already moves away from the plane."""

from __future__ import annotations

import time

import numpy as np
import trimesh

from ..detector import Detector
from ..view import View
from .snow import load_bunny

RADIUS = 0.04
DT = 1.0 / 60.0
RESTITUTION = 0.9


class NormalsSim:
    def __init__(self, spheres: int = 24, seed: int = 0, tolerance: float | None = None) -> None:
        self.rng = np.random.default_rng(seed)
        self.bunny, self.note = load_bunny()
        self.ball = trimesh.creation.icosphere(subdivisions=2, radius=RADIUS)
        self.centre = self.bunny.bounds.mean(axis=0)
        self.n = spheres
        self.position = np.zeros((spheres, 3))
        self.velocity = np.zeros((spheres, 3))
        for i in range(spheres):
            self._shoot(i)
        self.colour = np.tile([0.8, 0.8, 0.8], (spheres, 1))
        self.detector = Detector(tolerance=tolerance, encode="normal", records="all")
        self.bounces = 0
        self.contacts: list[tuple[np.ndarray, np.ndarray]] = []  # (points, normals) per frame

    def _shoot(self, i: int) -> None:
        d = self.rng.normal(size=3)
        d[1] = abs(d[1]) * 0.5
        d /= np.linalg.norm(d)
        self.position[i] = self.centre + d * 0.75
        aim = self.centre + self.rng.normal(scale=0.08, size=3)
        v = aim - self.position[i]
        self.velocity[i] = v / np.linalg.norm(v) * self.rng.uniform(0.6, 1.0)

    def step(self) -> dict:
        self.position += self.velocity * DT
        far = np.linalg.norm(self.position - self.centre, axis=1) > 1.0
        for i in np.flatnonzero(far):
            self._shoot(i)
        balls = np.tile(np.eye(4), (self.n, 1, 1))
        balls[:, :3, 3] = self.position
        # Only spheres near the bunny go to the detector (the view is fitted to the bunny).
        near = np.flatnonzero((np.abs(self.position - self.centre) < 0.5 - RADIUS).all(axis=1))
        bodies = [self.bunny] + [self.ball] * len(near)
        transforms = np.concatenate([np.eye(4)[None], balls[near]])
        t0 = time.perf_counter()
        result = self.detector.find_collisions(bodies, transforms)
        ms = (time.perf_counter() - t0) * 1e3
        rec = result.records
        # The bunny's edges carry its normals; spheres are only ever the penetrated body (5.3.1).
        mine = rec[(rec["penetrating"] == 0) & (rec["penetrated"] > 0)]
        self.contacts.append((result.points()[(rec["penetrating"] == 0) & (rec["penetrated"] > 0)],
                              mine["normal"]))
        for j in np.unique(mine["penetrated"]):
            n = mine["normal"][mine["penetrated"] == j].mean(axis=0)
            n /= np.linalg.norm(n)
            i = near[j - 1]
            vn = float(self.velocity[i] @ n)
            self.colour[i] = 0.5 + 0.5 * n
            if vn < 0:  # moving into the plane: reflect
                self.velocity[i] -= (1 + RESTITUTION) * vn * n
                self.bounces += 1
        return {"result": result, "ms": ms, "pairs": len(np.unique(mine["penetrated"]))}

    def scene_for_display(self) -> tuple[list, np.ndarray, np.ndarray]:
        balls = np.tile(np.eye(4), (self.n, 1, 1))
        balls[:, :3, 3] = self.position
        colours = np.vstack([[0.85, 0.8, 0.75], self.colour])
        return [self.bunny] + [self.ball] * self.n, np.concatenate([np.eye(4)[None], balls]), colours


def display_view() -> View:
    return View.look_at(eye=(0.2, 0.9, 1.6), target=(0, 0.25, 0), fov_y=45.0, near=0.3, far=10.0)

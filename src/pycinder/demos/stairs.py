"""Stairs (paper 5.1): spheres shot out at the top bounce down 11 box steps.

When a sphere hits a step it keeps its x and z velocity; its y velocity is reflected and damped.
Sphere-sphere contacts get no response. Contact pixels are marked with the paper's purple
rectangles.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import trimesh

from ..detector import Detector
from ..view import View

STEPS = 11
STEP_SIZE = (0.78, 0.28, 3.0)  # a small gap between steps: they never touch
STEP_DX, STEP_DY = 0.8, -0.3
RADIUS = 0.08
GRAVITY = -9.81
DAMPING = 0.75
DT = 1.0 / 60.0


def step_transforms() -> np.ndarray:
    """(11, 4, 4) world from body of the steps, descending along +x."""
    t = np.tile(np.eye(4), (STEPS, 1, 1))
    t[:, 0, 3] = STEP_DX * np.arange(STEPS)
    t[:, 1, 3] = STEP_DY * np.arange(STEPS)
    return t


def step_boxes() -> np.ndarray:
    """(11, 2, 3) world min and max corners of the steps."""
    centres = step_transforms()[:, :3, 3]
    half = np.array(STEP_SIZE) / 2
    return np.stack([centres - half, centres + half], axis=1)


DOMAIN = np.array([[-1.0, -5.0, -2.5], [STEP_DX * STEPS + 1.0, 2.5, 2.5]])
"""The world box the simulation lives in; spheres leaving it are shot again from the top."""

_boxes = step_boxes()
REGION = np.array([_boxes[:, 0].min(axis=0) - 0.25, _boxes[:, 1].max(axis=0) + 0.25])
"""Where a sphere can touch a step: the steps' box grown by more than a sphere's diameter.
Only spheres inside it go to the detector, and CInDeR's views are fitted to it."""


@dataclass
class StairsSim:
    spheres: int = 50
    seed: int = 0
    tolerance: float | None = None
    emit_per_frame: int = 2
    position: np.ndarray = field(init=False)
    velocity: np.ndarray = field(init=False)
    active: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.step_mesh = trimesh.creation.box(STEP_SIZE)
        self.ball = trimesh.creation.icosphere(subdivisions=2, radius=RADIUS)
        self.position = np.zeros((self.spheres, 3))
        self.velocity = np.zeros((self.spheres, 3))
        self.active = np.zeros(self.spheres, bool)
        # Each candidate pair gets its own tile: no views to fit, no contact hidden behind others.
        self.detector = Detector(tolerance=self.tolerance)
        self.steps = step_transforms()
        self.frame_index = 0

    def _shoot(self, idx: np.ndarray) -> None:
        n = len(idx)
        self.position[idx] = np.c_[self.rng.uniform(-0.3, 0.2, n), self.rng.uniform(0.4, 0.9, n),
                                   self.rng.uniform(-1.2, 1.2, n)]
        self.velocity[idx] = np.c_[self.rng.uniform(0.5, 1.6, n), self.rng.uniform(0.0, 2.0, n),
                                   self.rng.uniform(-0.3, 0.3, n)]
        self.active[idx] = True

    def near_steps(self) -> np.ndarray:
        """Indices of active spheres that lie wholly inside :data:`REGION`."""
        inside = ((self.position - RADIUS > REGION[0]) & (self.position + RADIUS < REGION[1])).all(axis=1)
        return np.flatnonzero(self.active & inside)

    def bodies(self, idx: np.ndarray | None = None) -> tuple[list, np.ndarray]:
        """Steps first, then the spheres ``idx`` (default: all active), and their transforms."""
        idx = np.flatnonzero(self.active) if idx is None else idx
        balls = np.tile(np.eye(4), (len(idx), 1, 1))
        balls[:, :3, 3] = self.position[idx]
        return [self.step_mesh] * STEPS + [self.ball] * len(idx), np.concatenate([self.steps, balls])

    def step(self) -> dict:
        """Advance one frame: emit, integrate, detect, respond. Returns what happened."""
        waiting = np.flatnonzero(~self.active)[: self.emit_per_frame]
        self._shoot(waiting)
        idx = np.flatnonzero(self.active)
        self.velocity[idx, 1] += GRAVITY * DT
        self.position[idx] += self.velocity[idx] * DT
        out = (self.position < DOMAIN[0] + RADIUS) | (self.position > DOMAIN[1] - RADIUS)
        self._shoot(np.flatnonzero(out.any(axis=1) & self.active))
        idx = self.near_steps()
        bodies, transforms = self.bodies(idx)
        t0 = time.perf_counter()
        result = self.detector.find_collisions(bodies, transforms)
        ms = (time.perf_counter() - t0) * 1e3
        pairs = result.pairs
        step_hits = pairs[(pairs[:, 0] < STEPS) & (pairs[:, 1] >= STEPS)]
        hit = idx[np.unique(step_hits[:, 1] - STEPS)]
        falling = hit[self.velocity[hit, 1] < 0]
        self.velocity[falling, 1] *= -DAMPING
        self.frame_index += 1
        rec = result.records
        sphere_px = (rec["penetrating"] >= STEPS) | (rec["penetrated"] >= STEPS)
        shown, shown_t = self.bodies()
        return {"result": result, "ms": ms, "pairs": len(step_hits), "all_pairs": len(pairs),
                "bodies": shown, "transforms": shown_t, "marks": result.points()[sphere_px]}


def display_view() -> View:
    return View.look_at(eye=(2.5, 2.8, 8.5), target=(4.2, -1.6, 0.0), fov_y=50.0, near=1.0,
                        far=40.0)


def colours(n_bodies: int) -> np.ndarray:
    c = np.tile([0.95, 0.55, 0.25], (n_bodies, 1))
    c[:STEPS] = [0.55, 0.6, 0.7]
    return c

"""Stairs (paper 5.1): spheres shot out at the top bounce down 11 box steps.

Spheres are shot in volleys from behind the top step. When the detector reports a sphere
against a step, the sphere's y velocity is reflected and damped if it was falling, and it is
lifted back onto the step's top (undoing the frame's penetration); its x and z velocity are
kept. Sphere-sphere contacts get no response. The throw and the bounce are tuned so that a
sphere lands on every step in turn: the first volley reaches the bottom in about 100 frames.

A frame is :data:`DT` (1/20 s) of simulated time; videos play at :data:`FPS`, in real time.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import trimesh

from ..detector import Detector
from .display import Layer, fit_look
from .marks import pair_points

STEPS = 11
STEP_SIZE = (0.78, 0.28, 3.0)  # a small gap between steps: they never touch
STEP_DX, STEP_DY = 0.8, -0.3
RADIUS = 0.1
GRAVITY = -9.81
RESTITUTION = 0.55
"""Rebound speed over impact speed: a sphere hops once per step at this and :data:`SPEED`."""
DT = 1.0 / 20.0
FPS = 20
SPEED = 1.75
"""Horizontal speed (x) of a shot: one step per hop."""
LAUNCH = np.array([-0.6, STEP_SIZE[1] / 2 + 0.45, 0.0])
"""Where spheres are shot from: behind and just above the top step."""
LAUNCH_VELOCITY = np.array([SPEED, 1.5, 0.0])


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


LANES = 12
LANE_WIDTH = 0.23
"""Spheres are shot in lanes this far apart in z, one lane after another: with 4 shots a frame a
lane is used again 3 frames (over a sphere's diameter along its path) later."""

DOMAIN = np.array([[-2.0, -5.0, -2.5], [STEP_DX * STEPS + 1.5, 3.0, 2.5]])
"""The world box the simulation lives in; spheres leaving it are shot again from the top."""

_boxes = step_boxes()
REGION = np.array([_boxes[:, 0].min(axis=0) - 0.25, _boxes[:, 1].max(axis=0) + 0.25])
"""Where a sphere can touch a step: the steps' box grown by more than a sphere's diameter.
Only spheres inside it go to the detector."""

SCENE_BOX = np.array([[LAUNCH[0] - RADIUS, _boxes[:, 0, 1].min(), _boxes[:, 0, 2].min()],
                      [_boxes[:, 1, 0].max(), 0.85, _boxes[:, 1, 2].max()]])
"""The staircase and the spheres' flight above its top: what the camera keeps in view."""

LOOK = fit_look(SCENE_BOX, (0.45, 0.55, -1.0), fov=40.0, sun=(0.2, 1.0, -0.45),
                shadow_extent=13.0, legend_right=True)
"""From behind the steps and above, so the stairs run from the top right to the bottom left and
leave the corners for the text (top left) and the legend (bottom right)."""
STEP_COLOUR = (0.56, 0.61, 0.70)
SPHERE_COLOUR = (0.95, 0.52, 0.18)


@dataclass
class StairsSim:
    """The stairs simulation: ``step()`` advances one frame.

    Attributes
    ----------
    position, velocity : (spheres, 3) float
        Sphere centres and velocities.
    active : (spheres,) bool
        Shot and in flight.
    steps_hit : (spheres, 11) bool
        The steps each sphere has bounced on since it was last shot.
    descents : int
        How many times a sphere has bounced on all 11 steps.
    """

    spheres: int = 50
    seed: int = 0
    tolerance: float | None = None
    emit_per_frame: int = 4
    position: np.ndarray = field(init=False)
    velocity: np.ndarray = field(init=False)
    active: np.ndarray = field(init=False)
    steps_hit: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.step_mesh = trimesh.creation.box(STEP_SIZE)
        self.ball = trimesh.creation.icosphere(subdivisions=2, radius=RADIUS)
        self.position = np.zeros((self.spheres, 3))
        self.velocity = np.zeros((self.spheres, 3))
        self.active = np.zeros(self.spheres, bool)
        self.steps_hit = np.zeros((self.spheres, STEPS), bool)
        self.descents = 0
        self.shots = 0
        # Each candidate pair gets its own tile: no views to fit, no contact hidden behind others.
        self.detector = Detector(tolerance=self.tolerance)
        self.steps = step_transforms()
        self.frame_index = 0

    def _shoot(self, idx: np.ndarray) -> None:
        """Shoot spheres ``idx`` from the launcher, each in the next of :data:`LANES` lanes
        across the steps, so that spheres shot a few frames apart do not overlap."""
        n = len(idx)
        lane = (self.shots + np.arange(n)) % LANES
        self.shots += n
        z = (lane - (LANES - 1) / 2) * LANE_WIDTH
        self.position[idx] = LAUNCH + np.c_[self.rng.uniform(-0.04, 0.04, n),
                                            self.rng.uniform(-0.05, 0.05, n),
                                            z + self.rng.uniform(-0.02, 0.02, n)]
        self.velocity[idx] = LAUNCH_VELOCITY * np.c_[self.rng.uniform(0.99, 1.01, n),
                                                     self.rng.uniform(0.96, 1.04, n), np.zeros(n)]
        self.steps_hit[idx] = False
        self.active[idx] = True

    def near_steps(self) -> np.ndarray:
        """Indices of active spheres that lie wholly inside :data:`REGION`."""
        inside = ((self.position - RADIUS > REGION[0]) &
                  (self.position + RADIUS < REGION[1])).all(axis=1)
        return np.flatnonzero(self.active & inside)

    def bodies(self, idx: np.ndarray | None = None) -> tuple[list, np.ndarray]:
        """Steps first, then the spheres ``idx`` (default: all active), and their transforms."""
        idx = np.flatnonzero(self.active) if idx is None else idx
        balls = np.tile(np.eye(4), (len(idx), 1, 1))
        balls[:, :3, 3] = self.position[idx]
        bodies = [self.step_mesh] * STEPS + [self.ball] * len(idx)
        return bodies, np.concatenate([self.steps, balls])

    def step(self) -> dict:
        """Advance one frame: emit, integrate, detect, respond.

        Returns
        -------
        dict
            ``result`` (the CollisionResult), ``ms`` (detection time), ``pairs`` (colliding
            sphere-step pairs), ``all_pairs`` (with sphere-sphere pairs), ``marks`` ((pairs, 3)
            one contact point per sphere-step pair).
        """
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
        fallback = transforms[step_hits[:, 1], :3, 3] - [0, RADIUS, 0]
        marks = pair_points(result.records, step_hits, fallback)
        self._respond(idx[step_hits[:, 1] - STEPS], step_hits[:, 0])
        self.frame_index += 1
        return {"result": result, "ms": ms, "pairs": len(step_hits), "all_pairs": len(pairs),
                "marks": marks}

    def _respond(self, sphere: np.ndarray, step: np.ndarray) -> None:
        """Bounce each sphere off the highest step it touches; count the steps it has hit."""
        if len(sphere) == 0:
            return
        before = self.steps_hit.all(axis=1)
        self.steps_hit[sphere, step] = True
        self.descents += int((self.steps_hit.all(axis=1) & ~before).sum())
        top = np.full(self.spheres, -np.inf)
        np.maximum.at(top, sphere, STEP_DY * step + STEP_SIZE[1] / 2)
        hit = np.unique(sphere)
        falling = hit[self.velocity[hit, 1] < 0]
        self.velocity[falling, 1] *= -RESTITUTION
        self.position[hit, 1] = np.maximum(self.position[hit, 1], top[hit] + RADIUS)

    def layers(self) -> dict[str, Layer]:
        """What the display shows: the steps and the spheres in flight."""
        balls = np.tile(np.eye(4), (int(self.active.sum()), 1, 1))
        balls[:, :3, 3] = self.position[self.active]
        return {"steps": Layer(self.step_mesh, self.steps, np.array(STEP_COLOUR), flat=True),
                "spheres": Layer(self.ball, balls, np.array(SPHERE_COLOUR))}

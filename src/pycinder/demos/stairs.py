"""Stairs (paper 5.1): spheres shot out at the top bounce down 11 steps onto a floor.

The steps are solid blocks standing on the floor (so each has a riser), and spheres are shot in
volleys from behind the top step. Every frame one query finds all colliding pairs, spheres
against steps, the floor and each other, and :meth:`~pycinder.CollisionResult.contacts` gives
one contact per contact region with its normal and depth. The response is a simple impulse
model on those contacts:

* **sphere against a step or the floor** (static): the sphere is pushed out along the normal by
  the depth, and its velocity along the normal is reflected and damped if it moved into the
  surface (:data:`RESTITUTION`); the velocity along the surface is kept;
* **sphere against sphere** (equal masses): both are pushed apart by half the depth each, and
  the equal and opposite impulse that reflects their approach speed (:data:`SPHERE_RESTITUTION`)
  is applied to both.

The throw and the bounce are tuned so that a sphere lands on every step in turn; spheres that
roll off the far end of the floor, or leave the region the camera shows, are shot again. A frame
is :data:`DT` (1/20 s) of simulated time; videos play at :data:`FPS`, in real time.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import trimesh

from ..contacts import Contacts
from ..detector import Detector
from .display import Layer, fit_look

STEPS = 11
STEP_DEPTH, STEP_WIDTH = 0.78, 3.0  # along x (a small gap between steps: they never touch), z
STEP_DX, STEP_DY = 0.8, -0.3
STEP_TOP = 0.14
"""The top of the highest step; step k's top is ``STEP_TOP + k * STEP_DY``."""
FLOOR_TOP = STEP_TOP + STEPS * STEP_DY
"""The floor lies one step below the lowest step."""
FLOOR_RUN = 2.4
"""How far the floor reaches past the lowest step."""
FLOOR_THICKNESS = 0.4
RADIUS = 0.1
GRAVITY = -9.81
RESTITUTION = 0.55
"""Rebound speed over impact speed off a step or the floor: a sphere hops once per step at this
and :data:`SPEED`."""
SPHERE_RESTITUTION = 0.8
"""Rebound speed over approach speed between two spheres."""
DT = 1.0 / 20.0
SUBSTEPS = 2
"""Detections per frame: a sphere falling off a step moves about its radius in half a frame, so
its centre seldom passes into a step, where the overlap no longer says which way is out."""
FPS = 20
SPEED = 1.75
"""Horizontal speed (x) of a shot: one step per hop."""
LAUNCH = np.array([-0.6, STEP_TOP + 0.45, 0.0])
"""Where spheres are shot from: behind and just above the top step."""
LAUNCH_VELOCITY = np.array([SPEED, 1.5, 0.0])


def step_boxes() -> np.ndarray:
    """(11, 2, 3) world min and max corners of the steps: blocks from the floor to each top."""
    x = STEP_DX * np.arange(STEPS)
    top = STEP_TOP + STEP_DY * np.arange(STEPS)
    lo = np.c_[x - STEP_DEPTH / 2, np.full(STEPS, FLOOR_TOP), np.full(STEPS, -STEP_WIDTH / 2)]
    hi = np.c_[x + STEP_DEPTH / 2, top, np.full(STEPS, STEP_WIDTH / 2)]
    return np.stack([lo, hi], axis=1)


FLOOR_BOX = np.array([[-STEP_DEPTH / 2 - 0.4, FLOOR_TOP - FLOOR_THICKNESS, -STEP_WIDTH / 2 - 0.6],
                      [STEP_DX * (STEPS - 1) + STEP_DEPTH / 2 + FLOOR_RUN, FLOOR_TOP,
                       STEP_WIDTH / 2 + 0.6]])
"""World min and max corners of the floor."""


def box_transforms(boxes: np.ndarray) -> np.ndarray:
    """(n, 4, 4) transforms that carry the unit cube centred at the origin onto ``boxes``
    ((n, 2, 3) min and max corners)."""
    t = np.tile(np.eye(4), (len(boxes), 1, 1))
    t[:, [0, 1, 2], [0, 1, 2]] = boxes[:, 1] - boxes[:, 0]
    t[:, :3, 3] = boxes.mean(axis=1)
    return t


def step_transforms() -> np.ndarray:
    """(11, 4, 4) world from body of the steps (a unit cube scaled into each block)."""
    return box_transforms(step_boxes())


VIEW_BOX = np.array([[LAUNCH[0] - 0.3, FLOOR_BOX[0, 1], FLOOR_BOX[0, 2]],
                     [FLOOR_BOX[1, 0], LAUNCH[1] + 0.45, FLOOR_BOX[1, 2]]])
"""What the camera keeps in view: the staircase, the floor and the spheres' flight above the top
step. Spheres whose centre leaves it are shot again, so every sphere in play is in view."""

VIEW_DIRECTION = (0.45, 0.55, -1.0)
"""From behind the steps and above, so the stairs run from the top right to the bottom left and
leave the corners for the text (top left) and the legend (bottom right)."""
LOOK = fit_look(VIEW_BOX, VIEW_DIRECTION, fov=40.0, margin=0.03, sun=(0.2, 1.0, -0.45),
                shadow_extent=16.0, legend_right=True)
"""The whole scene in view (a window starts here); headless videos follow the spheres."""
FOLLOW_SIZE = np.array([4.0, 2.0, STEP_WIDTH + 0.6])
"""The smallest box the camera frames around the spheres in play."""
STEP_COLOUR = (0.56, 0.61, 0.70)
FLOOR_COLOUR = (0.47, 0.50, 0.46)
SPHERE_COLOUR = (0.95, 0.52, 0.18)
TOUCH_COLOUR = (0.55, 0.12, 0.72)
"""A sphere while it touches anything: the purple of the contact marks."""
STEP_TOUCH_COLOUR = (0.74, 0.64, 0.88)
"""A step while a sphere touches it."""

LANES = 12
LANE_WIDTH = 0.23
"""Spheres are shot in lanes this far apart in z, one lane after another: with 4 shots a frame a
lane is used again 3 frames (over a sphere's diameter along its path) later."""


@dataclass
class StairsSim:
    """The stairs simulation: ``step()`` advances one frame.

    Attributes
    ----------
    position, velocity : (spheres, 3) float
        Sphere centres and velocities.
    active : (spheres,) bool
        Shot and in play.
    steps_hit : (spheres, 11) bool
        The steps each sphere has bounced on since it was last shot.
    descents : int
        How many times a sphere has bounced on all 11 steps.
    touching : (spheres,) bool
        Spheres in a colliding pair this frame.
    static_touched : (12,) bool
        Steps (and, last, the floor) in a colliding pair this frame.
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
        self.cube = trimesh.creation.box((1.0, 1.0, 1.0))
        self.ball = trimesh.creation.icosphere(subdivisions=2, radius=RADIUS)
        self.position = np.zeros((self.spheres, 3))
        self.velocity = np.zeros((self.spheres, 3))
        self.active = np.zeros(self.spheres, bool)
        self.steps_hit = np.zeros((self.spheres, STEPS), bool)
        self.touching = np.zeros(self.spheres, bool)
        self.static_touched = np.zeros(STEPS + 1, bool)
        self.descents = 0
        self.shots = 0
        self.sphere_contacts = 0
        # Pairs and contacts together, every substep: each result keeps every record of every
        # pair, and contacts() reduces them with no GPU.
        self.detector = Detector(tolerance=self.tolerance, contacts=True)
        self.statics = np.concatenate([step_transforms(), box_transforms(FLOOR_BOX[None])])
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

    def bodies(self, idx: np.ndarray | None = None) -> tuple[list, np.ndarray]:
        """The steps, the floor, then the spheres ``idx`` (default: all in play), and their
        transforms."""
        idx = np.flatnonzero(self.active) if idx is None else idx
        balls = np.tile(np.eye(4), (len(idx), 1, 1))
        balls[:, :3, 3] = self.position[idx]
        bodies = [self.cube] * (STEPS + 1) + [self.ball] * len(idx)
        return bodies, np.concatenate([self.statics, balls])

    def step(self) -> dict:
        """Advance one frame: emit, integrate, detect, respond.

        Returns
        -------
        dict
            ``result`` (the CollisionResult), ``contacts`` (its Contacts), ``ms`` (detection
            and contact time), ``pairs`` (colliding pairs), ``contacts_count``, ``marks``
            ((C, 3) the contact points) and ``normals`` ((C, 3) their normals, from the first
            body of the pair into the second).
        """
        waiting = np.flatnonzero(~self.active)[: self.emit_per_frame]
        self._shoot(waiting)
        ms = 0.0
        for _ in range(SUBSTEPS):
            idx = np.flatnonzero(self.active)
            self.velocity[idx, 1] += GRAVITY * DT / SUBSTEPS
            self.position[idx] += self.velocity[idx] * DT / SUBSTEPS
            gone = ((self.position < VIEW_BOX[0]) | (self.position > VIEW_BOX[1])).any(axis=1)
            self._shoot(np.flatnonzero(gone & self.active))
            idx = np.flatnonzero(self.active)
            bodies, transforms = self.bodies(idx)
            t0 = time.perf_counter()
            # The steps and the floor stand still together: one group, never tested against
            # each other; every sphere in a group of its own.
            groups = np.r_[np.zeros(STEPS + 1, np.int64), 1 + np.arange(len(idx))]
            result = self.detector.find_collisions(bodies, transforms, groups=groups)
            contacts = result.contacts()
            ms += (time.perf_counter() - t0) * 1e3
            self._respond(idx, result.pairs, contacts)
        self.frame_index += 1
        return {"result": result, "contacts": contacts, "ms": ms, "pairs": len(result.pairs),
                "contacts_count": len(contacts), "marks": contacts.point,
                "normals": contacts.normal}

    def _respond(self, idx: np.ndarray, pairs: np.ndarray, contacts: Contacts) -> None:
        """The impulse response of the module's doc, contact by contact; which bodies touch."""
        first = STEPS + 1  # body index of the first sphere
        self.touching[:] = False
        self.static_touched[:] = False
        sphere_of = lambda body: idx[body - first]  # noqa: E731
        for a, b in pairs.tolist():
            for body in (a, b):
                if body < first:
                    self.static_touched[body] = True
                else:
                    self.touching[sphere_of(body)] = True
        before = self.steps_hit.all(axis=1)
        for (a, b), n, depth in zip(contacts.pair.tolist(), contacts.normal, contacts.depth):
            if a < first:  # a step or the floor (a) and a sphere (b): n points into the sphere
                s = sphere_of(b)
                self.position[s] += n * depth
                vn = self.velocity[s] @ n
                if vn < 0:
                    self.velocity[s] -= (1 + RESTITUTION) * vn * n
                if a < STEPS and n[1] > 0.5:  # landed on the step's top
                    self.steps_hit[s, a] = True
            else:  # two spheres: n points from a into b
                sa, sb = sphere_of(a), sphere_of(b)
                self.position[sa] -= 0.5 * depth * n
                self.position[sb] += 0.5 * depth * n
                vn = (self.velocity[sb] - self.velocity[sa]) @ n
                if vn < 0:
                    j = 0.5 * (1 + SPHERE_RESTITUTION) * vn
                    self.velocity[sa] += j * n
                    self.velocity[sb] -= j * n
                self.sphere_contacts += 1
        self.descents += int((self.steps_hit.all(axis=1) & ~before).sum())

    view_direction = VIEW_DIRECTION

    def view_box(self) -> np.ndarray:
        """(2, 3) the world box the camera should show: every sphere in play, with room around
        it (at least :data:`FOLLOW_SIZE`), within :data:`VIEW_BOX`."""
        centres = self.position[self.active]
        if not len(centres):
            return VIEW_BOX.copy()
        lo, hi = centres.min(axis=0) - 2 * RADIUS, centres.max(axis=0) + 2 * RADIUS
        grow = np.maximum(FOLLOW_SIZE - (hi - lo), 0) / 2
        lo, hi = lo - grow, hi + grow
        return np.stack([np.maximum(lo, VIEW_BOX[0]), np.minimum(hi, VIEW_BOX[1])])

    def layers(self) -> dict[str, Layer]:
        """What the display shows: the steps and the floor, the spheres in play; spheres and
        steps in their touching colours while they are in a colliding pair (the floor, which
        spheres roll on, keeps its own)."""
        balls = np.tile(np.eye(4), (int(self.active.sum()), 1, 1))
        balls[:, :3, 3] = self.position[self.active]
        touching = self.touching[self.active]
        sphere_colours = np.where(touching[:, None], TOUCH_COLOUR, SPHERE_COLOUR)
        steps = np.where(self.static_touched[:STEPS, None], STEP_TOUCH_COLOUR, STEP_COLOUR)
        return {"steps": Layer(self.cube, self.statics[:STEPS], steps, flat=True),
                "floor": Layer(self.cube, self.statics[STEPS:], np.array(FLOOR_COLOUR), flat=True),
                "spheres": Layer(self.ball, balls, sphere_colours)}

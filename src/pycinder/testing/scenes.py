"""The benchmarks' scenes, which the tests use too: each is a sequence of frames of the same
bodies, scored by exact truth (:func:`pycinder.testing.ground_truth`).

A frame is (meshes, transforms): meshes as (vertices (V, 3), faces (F, 3)) pairs, transforms
(N, 4, 4). Rigid scenes keep the same vertex arrays and change transforms; deforming scenes
change the vertices every frame. :func:`drifting_spheres` gives the broad phase's scene as
boxes and radii alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from . import bunny, make_shape, random_rotation


@dataclass
class Scene:
    name: str
    description: str
    faces: list[np.ndarray]
    rest: list[np.ndarray]
    frames: int
    deforming: bool = False
    params: dict = field(default_factory=dict)

    def frame(self, k: int) -> tuple[list[np.ndarray], np.ndarray]:
        """Vertices per body and (N, 4, 4) transforms of frame k."""
        raise NotImplementedError

    def bodies(self, k: int) -> tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray]:
        verts, transforms = self.frame(k)
        return list(zip(verts, self.faces)), transforms

    def cached(self) -> Scene:
        """This scene with its frames made once and kept, so that timing never includes making
        them (deforming scenes compute every vertex of every frame)."""
        frames = [self.frame(k) for k in range(self.frames)]
        self.frame = lambda k: frames[k]  # type: ignore[method-assign]
        return self

    @property
    def triangles(self) -> int:
        return int(sum(len(f) for f in self.faces))


class Stairs(Scene):
    """The paper's Stairs (5.1) frozen into frames: 11 box steps, spheres falling down them."""

    def __init__(self, spheres: int = 250, frames: int = 10, seed: int = 0) -> None:
        step = trimesh.creation.box((1.0, 0.3, 3.0))
        ball = trimesh.creation.icosphere(subdivisions=2, radius=0.08)
        faces = [np.asarray(step.faces)] * 11 + [np.asarray(ball.faces)] * spheres
        rest = [np.asarray(step.vertices)] * 11 + [np.asarray(ball.vertices)] * spheres
        super().__init__(f"stairs-{spheres}", f"Stairs: 11 boxes and {spheres} spheres, rigid",
                         faces, rest, frames, params={"spheres": spheres})
        rng = np.random.default_rng(seed)
        self.steps = np.stack([trimesh.transformations.translation_matrix((0.8 * i, -0.3 * i, 0))
                               for i in range(11)])
        # Spheres spread over the staircase, some resting on steps, moving down and along.
        i = rng.integers(0, 11, spheres)
        self.start = np.c_[0.8 * i + rng.uniform(-0.45, 0.45, spheres),
                           -0.3 * i + 0.15 + rng.uniform(0.0, 0.6, spheres),
                           rng.uniform(-1.4, 1.4, spheres)]
        self.velocity = np.c_[rng.uniform(0.2, 0.6, spheres), rng.uniform(-1.5, 0.5, spheres),
                              rng.uniform(-0.2, 0.2, spheres)]

    def frame(self, k: int) -> tuple[list[np.ndarray], np.ndarray]:
        pos = self.start + self.velocity * (k / 60.0)
        balls = np.tile(np.eye(4), (len(pos), 1, 1))
        balls[:, :3, 3] = pos
        return self.rest, np.concatenate([self.steps, balls])


class DeformingBunnies(Scene):
    """16 Stanford bunnies (about 56k triangles each), every vertex displaced every frame."""

    def __init__(self, count: int = 16, frames: int = 5, amplitude: float = 0.01) -> None:
        b = bunny()
        super().__init__(f"deforming-{count}-bunnies",
                         f"{count} bunnies of {len(b.faces)} triangles, every vertex moving",
                         [np.asarray(b.faces)] * count, [np.asarray(b.vertices)] * count,
                         frames, deforming=True, params={"count": count})
        side = int(np.ceil(np.sqrt(count)))
        spacing = 0.55  # the bunny is about 0.62 across: neighbours overlap a little
        self.transforms = np.tile(np.eye(4), (count, 1, 1))
        for n in range(count):
            self.transforms[n, :3, 3] = (spacing * (n % side), 0.0, spacing * (n // side))
        self.amplitude = amplitude
        self.phase = np.asarray(b.vertices) @ np.array([17.0, 23.0, 29.0])

    def frame(self, k: int) -> tuple[list[np.ndarray], np.ndarray]:
        rest = self.rest[0]
        verts = []
        for n in range(len(self.rest)):
            wobble = np.sin(self.phase + 0.7 * k + n)[:, None] * self.amplitude
            verts.append(rest + wobble * np.array([1.0, 0.6, 0.8]))
        return verts, self.transforms


class Drifting(Scene):
    """Rigid bodies at ``self.base`` (N, 4, 4) drifting at ``self.drift`` (N, 3) per second."""

    base: np.ndarray
    drift: np.ndarray

    def frame(self, k: int) -> tuple[list[np.ndarray], np.ndarray]:
        t = self.base.copy()
        t[:, :3, 3] += self.drift * (k / 60.0)
        return self.rest, t


class ManyBodies(Drifting):
    """Many small rigid bodies in a box, moving a little every frame."""

    def __init__(self, count: int = 1000, frames: int = 5, seed: int = 1) -> None:
        rng = np.random.default_rng(seed)
        shapes = [make_shape(kind, 1.0, rng) for kind in ("box", "icosphere", "cylinder")]
        for s in shapes:
            s.apply_scale(0.1)
        picks = rng.integers(0, len(shapes), count)
        super().__init__(f"many-{count}", f"{count} small rigid bodies in a box",
                         [np.asarray(shapes[p].faces) for p in picks],
                         [np.asarray(shapes[p].vertices) for p in picks], frames,
                         params={"count": count})
        side = 0.1 * (count / 0.25) ** (1 / 3) * 0.6
        self.base = np.stack([random_rotation(rng) for _ in range(count)])
        self.base[:, :3, 3] = rng.uniform(-side / 2, side / 2, (count, 3))
        self.drift = rng.normal(scale=0.05, size=(count, 3))


class NarrowPhase(Scene):
    """Two bunnies, frame by frame from deep penetration to a near miss."""

    def __init__(self, frames: int = 8) -> None:
        b = bunny()
        super().__init__("narrow-phase", "2 bunnies, from deep overlap to a near miss",
                         [np.asarray(b.faces)] * 2, [np.asarray(b.vertices)] * 2, frames)
        self.offsets = np.linspace(0.1, 0.7, frames)

    def frame(self, k: int) -> tuple[list[np.ndarray], np.ndarray]:
        t = np.tile(np.eye(4), (2, 1, 1))
        t[1, 0, 3] = self.offsets[k]
        return self.rest, t


class SphereField(Drifting):
    """Sweeps: ``count`` icospheres of ``subdivisions`` in a cube, rigid, moving slightly."""

    def __init__(self, count: int, subdivisions: int, frames: int = 5, seed: int = 2) -> None:
        ball = trimesh.creation.icosphere(subdivisions=subdivisions, radius=0.5)
        super().__init__(f"spheres-{count}x{len(ball.faces)}",
                         f"{count} spheres of {len(ball.faces)} triangles",
                         [np.asarray(ball.faces)] * count, [np.asarray(ball.vertices)] * count,
                         frames, params={"count": count, "triangles_per_body": len(ball.faces)})
        rng = np.random.default_rng(seed)
        side = (count / 0.3) ** (1 / 3) * 0.8
        self.base = np.tile(np.eye(4), (count, 1, 1))
        self.base[:, :3, 3] = rng.uniform(-side / 2, side / 2, (count, 3))
        self.drift = rng.normal(scale=0.2, size=(count, 3))


class SpreadPairs(Drifting):
    """``pairs`` pairs of spheres (radius 0.5) spread through a cube ``extent`` wide: half of
    them 4 tolerances deep into each other, half 2 tolerances apart. The same pairs at any
    extent: time and answers should not change with it."""

    def __init__(self, extent: float, pairs: int = 64, tolerance: float = 0.005, frames: int = 5,
                 seed: int = 4) -> None:
        ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
        n = 2 * pairs
        super().__init__(f"spread-{extent:g}", f"{pairs} sphere pairs spread over {extent:g}",
                         [np.asarray(ball.faces)] * n, [np.asarray(ball.vertices)] * n, frames,
                         params={"extent": extent, "pairs": pairs, "tolerance": tolerance})
        rng = np.random.default_rng(seed)
        # Pair centres on a jittered grid filling the cube, so pairs never meet each other.
        side = int(np.ceil(pairs ** (1 / 3)))
        cell = max(extent / side, 3.0)
        grid = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3)
        centres = (grid[rng.permutation(len(grid))[:pairs]] + 0.5) * cell
        direction = rng.normal(size=(pairs, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        # Icosphere vertices lie on the sphere, faces inside it: meshes touch slightly inside
        # the radius; the offsets below are measured on the meshes (exact truth scores them).
        gap = np.where(np.arange(pairs) % 2 == 0, -4 * tolerance, 2 * tolerance)
        half = 0.5 * (1.0 + gap)[:, None] * direction
        self.base = np.tile(np.eye(4), (n, 1, 1))
        self.base[0::2, :3, 3] = centres - half
        self.base[1::2, :3, 3] = centres + half
        self.drift = np.zeros((n, 3))


def sweep_scenes(frames: int) -> dict[str, list[Scene]]:
    """The three sweeps: triangles per body, body count at fixed total, resolution (one scene)."""
    return {
        "triangles-per-body": [SphereField(20, s, frames) for s in (1, 2, 3, 4, 5)],
        "bodies-at-fixed-total": [SphereField(c, s, frames)
                                  for c, s in ((5, 5), (20, 4), (80, 3), (320, 2), (1280, 1))],
        "extent": [SpreadPairs(e, frames=frames) for e in (10.0, 100.0, 1000.0, 10000.0)],
    }


DRIFTING_RADIUS = 0.05
"""Radius of :func:`drifting_spheres`' spheres."""


def drifting_spheres(count: int, frames: int, seed: int = 1
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
    """Spheres of radius :data:`DRIFTING_RADIUS` drifting in a box, at the density of the
    ``many`` scene (:class:`ManyBodies`): the broad phase's benchmark scene, as local boxes,
    radii and poses.

    Returns
    -------
    local_lo, local_hi : (N, 3) float64
    radius : (N,) float64
    transforms : list of (N, 4, 4) float64
        One per frame.
    """
    rng = np.random.default_rng(seed)
    side = 0.1 * (count / 0.25) ** (1 / 3) * 0.6
    base = np.stack([random_rotation(rng) for _ in range(count)])
    base[:, :3, 3] = rng.uniform(-side / 2, side / 2, (count, 3))
    drift = rng.normal(scale=0.05, size=(count, 3))
    poses = []
    for k in range(frames):
        t = base.copy()
        t[:, :3, 3] += drift * (k / 60.0)
        poses.append(t)
    r = DRIFTING_RADIUS
    return np.full((count, 3), -r), np.full((count, 3), r), np.full(count, r), poses


SCENES = {
    "stairs": lambda frames: [Stairs(250, frames)],
    "deforming": lambda frames: [DeformingBunnies(16, frames)],
    "many": lambda frames: [ManyBodies(1000, frames)],
    "narrow": lambda frames: [NarrowPhase(max(frames, 4))],
    "sweep-triangles": lambda frames: sweep_scenes(frames)["triangles-per-body"],
    "sweep-bodies": lambda frames: sweep_scenes(frames)["bodies-at-fixed-total"],
    "sweep-extent": lambda frames: sweep_scenes(frames)["extent"],
    "sweep-tolerance": lambda frames: [Stairs(250, frames)],
}

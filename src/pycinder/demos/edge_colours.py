"""Edges coloured by normals (paper 5.3): spheres bounce off the bunny using the surface normal
read straight from the collision records (``Detector(encode="normal")``), with no CPU lookup of
the mesh.

With ``encode="normal"`` the detector carries, for every edge of a body, the normal it encodes
(the mean of the edge's two face normals) into the records of that edge. The display shows
exactly those normals: each edge of the bunny is drawn in the colour 0.5 + 0.5 n of its encoded
normal n (x red, y green, z blue), over a dark surface. A sphere takes the colour of the last
normal it bounced off (white while it touches the bunny); it gets no response when it already
moves away from the plane. Contacts (points and counts) come from ``result.contacts()``.
"""

from __future__ import annotations

import time

import numpy as np
import trimesh

from ..detector import Detector
from ..scene import prepare_scene
from .display import Layer, Lines, fit_look
from .snow import load_bunny

RADIUS = 0.04
DT = 1.0 / 60.0
FPS = 30
"""Videos play at half speed: the bounces are quick."""
RESTITUTION = 0.9
LOOK = fit_look(np.array([[-0.3, -0.22, -0.24], [0.3, 0.6, 0.24]]), (0.2, 0.4, 1.0), fov=40.0,
                margin=0.03, background=("#1c1f26", "#3a4150"), sun=(0.3, 1.0, 0.6),
                shadow_extent=2.5)
"""The bunny, with room below it for the legend."""
SURFACE_COLOUR = (0.16, 0.17, 0.2)
UNTOUCHED_COLOUR = (0.5, 0.5, 0.5)
"""A sphere before its first bounce."""
TOUCH_COLOUR = (1.0, 1.0, 1.0)
"""A sphere while it touches the bunny; afterwards it keeps the colour of the normal it bounced
off."""
EDGE_INSET = 0.0015
"""The surface is drawn this far (world units) inside the bunny, so its edges lie on top."""


def normal_colours(normals: np.ndarray) -> np.ndarray:
    """Colours (n, 3) in [0, 1] of unit normals (n, 3): 0.5 + 0.5 n."""
    return np.clip(0.5 + 0.5 * np.asarray(normals, float), 0, 1)


class NormalsSim:
    """The normals simulation: ``step()`` advances one frame.

    Attributes
    ----------
    position, velocity : (spheres, 3) float
    colour : (spheres, 3) float
        Each sphere's colour: the last normal it bounced off (grey before its first bounce, white while it touches).
    bounces : int
        Reflections so far.
    contacts : list of ((m, 3), (m, 3)) float
        Per frame, the record points on the bunny's edges inside spheres and their normals.
    """

    def __init__(self, spheres: int = 24, seed: int = 0, tolerance: float | None = None) -> None:
        self.rng = np.random.default_rng(seed)
        self.bunny, self.note = load_bunny()
        self.ball = trimesh.creation.icosphere(subdivisions=2, radius=RADIUS)
        self.centre = self.bunny.bounds.mean(axis=0)
        self.n = spheres
        self.position = np.zeros((spheres, 3))
        self.velocity = np.zeros((spheres, 3))
        for i in range(spheres):
            self._shoot(i, first=True)
        self.colour = np.tile(UNTOUCHED_COLOUR, (spheres, 1))
        self.touching = np.zeros(spheres, bool)
        self.detector = Detector(tolerance=tolerance, encode="normal", contacts=True)
        self.bounces = 0
        self.contacts: list[tuple[np.ndarray, np.ndarray]] = []  # (points, normals) per frame
        self.surface = self._inset_surface()
        self.edges = self.edge_lines()

    def _shoot(self, i: int, first: bool = False) -> None:
        """Shoot sphere ``i`` at the bunny from 0.75 away, across the camera's view (a sphere
        between the camera and the bunny would seem to touch it, one behind would be hidden);
        the first spheres start anywhere along their way in, clear of the bunny, so that
        contacts begin within the first frames."""
        towards_camera = np.subtract(LOOK.eye, LOOK.target)
        towards_camera /= np.linalg.norm(towards_camera)
        while True:  # from the sides and above: contacts on the bunny's outline, in view
            d = self.rng.normal(size=3)
            d[1] = abs(d[1]) * 0.5
            d /= np.linalg.norm(d)
            start = self.centre + d * (self.rng.uniform(0.4, 0.75) if first else 0.75)
            if abs(d @ towards_camera) < 0.3 and (not first or trimesh.proximity.signed_distance(
                    self.bunny, start[None])[0] < -2 * RADIUS):  # not in or on the bunny
                break
        self.position[i] = start
        aim = self.centre + self.rng.normal(scale=0.08, size=3)
        v = aim - self.position[i]
        self.velocity[i] = v / np.linalg.norm(v) * self.rng.uniform(0.6, 1.0)

    def step(self) -> dict:
        """Advance one frame: move, detect, bounce off the normals read from the records.

        Returns
        -------
        dict
            ``result``, ``ms`` (detection time), ``pairs`` (spheres touching the bunny),
            ``marks`` ((C, 3) the contact points of those pairs, from ``result.contacts()``) and
            ``normals`` ((C, 3) at each contact, the normal its sphere bounced off: the mean of
            the bunny's record normals in that sphere, or the contact's normal where the bunny
            has no record in it).
        """
        self.position += self.velocity * DT
        far = np.linalg.norm(self.position - self.centre, axis=1) > 1.0
        for i in np.flatnonzero(far):
            self._shoot(i)
        balls = np.tile(np.eye(4), (self.n, 1, 1))
        balls[:, :3, 3] = self.position
        # Only spheres near the bunny go to the detector, and only against the bunny.
        near = np.flatnonzero((np.abs(self.position - self.centre) < 0.5 - RADIUS).all(axis=1))
        bodies = [self.bunny] + [self.ball] * len(near)
        transforms = np.concatenate([np.eye(4)[None], balls[near]])
        groups = np.r_[0, np.ones(len(near), np.int64)]
        t0 = time.perf_counter()
        result = self.detector.find_collisions(bodies, transforms, groups=groups)
        contacts = result.contacts()
        ms = (time.perf_counter() - t0) * 1e3
        rec = result.records
        # The bunny's edges and faces inside a sphere carry the bunny's normals (5.3.1).
        mine = rec[(rec["penetrating"] == 0) & (rec["penetrated"] > 0)]
        self.contacts.append((np.asarray(mine["point"], float), mine["normal"]))
        touched = result.pairs[:, 1]
        self.touching[:] = False
        self.touching[near[touched - 1]] = True
        bounce = {}
        for j in touched.tolist():
            n = mine["normal"][mine["penetrated"] == j].astype(float).sum(axis=0)
            if np.linalg.norm(n) < 1e-9:  # no record of the bunny inside this sphere
                n = contacts.normal[contacts.pair[:, 1] == j].sum(axis=0)
            n /= max(np.linalg.norm(n), 1e-12)
            bounce[j] = n
            i = near[j - 1]
            vn = float(self.velocity[i] @ n)
            self.colour[i] = normal_colours(n)
            if vn < 0:  # moving into the plane: reflect
                self.velocity[i] -= (1 + RESTITUTION) * vn * n
                self.bounces += 1
        normals = np.array([bounce[b] for b in contacts.pair[:, 1].tolist()]).reshape(-1, 3)
        return {"result": result, "ms": ms, "pairs": len(touched), "marks": contacts.point,
                "normals": normals}

    def _inset_surface(self) -> trimesh.Trimesh:
        normals = np.asarray(self.bunny.vertex_normals)
        return trimesh.Trimesh(self.bunny.vertices - EDGE_INSET * normals, self.bunny.faces,
                               process=False)

    def edge_lines(self) -> Lines:
        """The bunny's edges, each coloured by the normal the detector encodes for it."""
        shape = prepare_scene([self.bunny]).shapes[0]
        edges = shape.topology.edges
        segments = (np.asarray(shape.vertices, float) + shape.offset)[edges]  # as the bunny's
        return Lines(segments, normal_colours(shape.normals()[1]), thickness=1.6)

    def layers(self) -> dict[str, Layer | Lines]:
        """What the display shows: the dark surface, its coloured edges, the spheres."""
        balls = np.tile(np.eye(4), (self.n, 1, 1))
        balls[:, :3, 3] = self.position
        return {"surface": Layer(self.surface, np.eye(4)[None], np.array(SURFACE_COLOUR),
                                 shadows=False),
                "edges": self.edges,
                "spheres": Layer(self.ball, balls,
                                 np.where(self.touching[:, None], TOUCH_COLOUR, self.colour))}

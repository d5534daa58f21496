"""Clashes pictured: a PNG of each group of clashes, rendered offscreen with pygfx
(``pip install 'pycinder[bim]'``).

Each picture shows the group's elements in their surroundings: the ``a`` elements of its
clashes in :data:`COLOUR_A`, the ``b`` elements in :data:`COLOUR_B`, both outlined on top of
everything (a sleeve inside a wall shows through the wall), and the other elements near them
in translucent grey. The camera (:class:`Camera`) looks down at the group from one side,
z up, far enough back that the group's elements fill the frame; the BCF viewpoint carries the
same camera, so a BCF viewer opens where the picture was taken. pygfx renders on its own wgpu
device, offscreen (rendercanvas's offscreen canvas): no window or display is needed, and a CPU
adapter (lavapipe, llvmpipe) does.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..gpu.device import fit_default_device_to_adapter
from ..util.optional import require

__all__ = ["Camera", "Snapshotter", "group_camera", "COLOUR_A", "COLOUR_B"]

COLOUR_A = (0.86, 0.16, 0.12)
"""Group A's elements (each clash's ``a``): red."""
COLOUR_B = (0.10, 0.35, 0.90)
"""Group B's elements (each clash's ``b``): blue."""
CONTEXT = (0.62, 0.64, 0.67)
"""The other elements: grey, translucent."""
VIEW_FROM = np.array([1.0, -1.6, 1.1])
"""From the target towards the camera: above, in front and to the right."""


@dataclass(frozen=True)
class Camera:
    """A perspective camera, as a BCF viewpoint holds it (metres, world coordinates, z up).

    Attributes
    ----------
    position : (3,) float
        Where the camera is.
    direction : (3,) float
        Unit vector it looks along.
    up : (3,) float
        Unit vector up in the picture, normal to ``direction``.
    fov : float
        Vertical field of view in degrees.
    """

    position: np.ndarray
    direction: np.ndarray
    up: np.ndarray
    fov: float = 50.0

    @property
    def target(self) -> np.ndarray:
        """(3,) float: a point it looks at (one metre ahead)."""
        return self.position + self.direction


def _bounds(bodies: Sequence[Any]) -> np.ndarray:
    """(2, 3) float: the bodies' bounding box."""
    lo = np.min([b.mesh.bounds[0] for b in bodies], axis=0)
    hi = np.max([b.mesh.bounds[1] for b in bodies], axis=0)
    return np.array([lo, hi], np.float64)


def group_camera(bodies: Sequence[Any], point: np.ndarray | None = None, *,
                 fov: float = 50.0, aspect: float = 4 / 3) -> Camera:
    """A camera that looks at ``point`` (default: the bodies' centre) from above and to the
    side (:data:`VIEW_FROM`), far enough back that the bodies' bounding sphere about the
    point (of radius at least 0.4 m) fits the frame.

    Parameters
    ----------
    bodies : sequence of IfcBody
        The elements to show (their meshes' bounds, in metres).
    point : (3,) float, optional
    fov : float
        Vertical field of view in degrees.
    aspect : float
        The picture's width over its height.

    Returns
    -------
    Camera
    """
    box = _bounds(bodies)
    target = box.mean(axis=0) if point is None else np.asarray(point, np.float64)
    radius = max(float(np.max(np.linalg.norm(
        np.array([[box[i, 0], box[j, 1], box[k, 2]] for i in (0, 1) for j in (0, 1)
                  for k in (0, 1)]) - target, axis=1))), 0.4)
    half = np.radians(fov) / 2
    half = min(half, np.arctan(np.tan(half) * aspect))  # the narrower of the two
    distance = 1.1 * radius / np.sin(half)
    back = VIEW_FROM / np.linalg.norm(VIEW_FROM)
    direction = -back
    up = np.array([0.0, 0.0, 1.0]) - direction * direction[2]
    return Camera(target + back * distance, direction, up / np.linalg.norm(up), float(fov))


def _import_pygfx() -> Any:
    require("rendercanvas.offscreen", "clash snapshots", "bim", package="rendercanvas")
    return require("pygfx", "clash snapshots", "bim")


class Snapshotter:
    """Renders pictures of groups of clashes, offscreen; one renderer for every picture.

    Parameters
    ----------
    bodies : sequence of IfcBody
        Every element of the model (the surroundings are drawn from them).
    size : (int, int)
        The pictures' width and height in pixels.
    surroundings : float
        Elements whose boxes come within this many metres of the group's box are drawn
        around it.

    Raises
    ------
    ImportError
        Without pygfx, rendercanvas or pillow (``pip install 'pycinder[bim]'``).

    Notes
    -----
    pygfx renders on wgpu's default device, which the first picture creates (pycinder's
    queries keep a device of their own). The demos configure that device for pycinder and
    pygfx both before anything creates it, so a demo run after pictures were rendered in the
    same process stops with an error that says to start it in a fresh process.
    """

    def __init__(self, bodies: Sequence[Any], size: tuple[int, int] = (640, 480), *,
                 surroundings: float = 2.0) -> None:
        self.gfx = _import_pygfx()
        self.image = require("PIL.Image", "clash snapshots", "bim", package="pillow")
        from rendercanvas.offscreen import RenderCanvas

        self.bodies = list(bodies)
        self.size = (int(size[0]), int(size[1]))
        self.surroundings = float(surroundings)
        self.lo = np.array([b.mesh.bounds[0] for b in self.bodies]).reshape(-1, 3)
        self.hi = np.array([b.mesh.bounds[1] for b in self.bodies]).reshape(-1, 3)
        fit_default_device_to_adapter("pycinder clash snapshots")  # OpenGL adapters too
        self.canvas = RenderCanvas(size=self.size, pixel_ratio=1)
        self.renderer = self.gfx.WgpuRenderer(self.canvas, pixel_scale=2, ppaa="none",
                                              pixel_filter="linear")

    def _mesh(self, bodies: Sequence[Any], colour: tuple[float, float, float],
              opacity: float) -> Any:
        gfx = self.gfx
        import trimesh

        mesh = trimesh.util.concatenate([b.mesh for b in bodies])
        geometry = gfx.Geometry(positions=np.ascontiguousarray(mesh.vertices, np.float32),
                                normals=np.ascontiguousarray(mesh.vertex_normals, np.float32),
                                indices=np.ascontiguousarray(mesh.faces, np.int32))
        material = gfx.MeshPhongMaterial(color=(*colour, opacity), shininess=10,
                                         side="both")
        if opacity < 1:
            material.alpha_mode = "blend"
            material.depth_write = False
        return gfx.Mesh(geometry, material)

    def _outline(self, bodies: Sequence[Any], colour: tuple[float, float, float]) -> Any:
        """The bodies' sharp edges (faces meeting at over 20 degrees), drawn over
        everything."""
        gfx = self.gfx
        segments = []
        for b in bodies:
            m = b.mesh
            sharp = m.face_adjacency_edges[m.face_adjacency_angles > np.radians(20)]
            segments.append(m.vertices[sharp].reshape(-1, 3))
        positions = np.ascontiguousarray(np.concatenate(segments), np.float32)
        material = gfx.LineSegmentMaterial(thickness=3.0, color=colour, depth_test=False)
        material.render_queue = 4000  # after the meshes, on top
        return gfx.Line(gfx.Geometry(positions=positions), material)

    def render(self, a: Sequence[Any], b: Sequence[Any], camera: Camera,
               translucent: Sequence[Any] = ()) -> np.ndarray:
        """(H, W, 3) uint8: elements ``a`` and ``b`` highlighted among their surroundings,
        seen by ``camera``; those of them in ``translucent`` (the larger element of each
        clash) let what runs through them show."""
        gfx = self.gfx
        shown = list(a) + list(b)
        box = _bounds(shown)
        near = np.all((self.lo <= box[1] + self.surroundings)
                      & (self.hi >= box[0] - self.surroundings), axis=1)
        ids = {id(x) for x in shown}
        context = [x for x, keep in zip(self.bodies, near.tolist(), strict=True)
                   if keep and id(x) not in ids]
        scene = gfx.Scene()
        scene.add(gfx.Background.from_color("#f4f5f7", "#dfe3ea"))
        scene.add(gfx.AmbientLight(intensity=0.7))
        light = gfx.DirectionalLight(intensity=1.6)
        light.local.position = tuple(-camera.direction + np.array([0.3, 0.2, 1.0]))
        scene.add(light)
        clear = {id(x) for x in translucent}
        for group, colour in ((a, COLOUR_A), (b, COLOUR_B)):
            for opacity in (1.0, 0.45):
                chosen = [x for x in group if (id(x) in clear) == (opacity < 1)]
                if chosen:
                    scene.add(self._mesh(chosen, colour, opacity))
        if context:
            scene.add(self._mesh(context, CONTEXT, 0.28))
        for group, colour in ((a, COLOUR_A), (b, COLOUR_B)):
            if group:
                scene.add(self._outline(group, colour))
        width, height = self.size
        aspect = width / height
        # pygfx's fov spans the mean of the view's width and height; Camera.fov is vertical.
        fov = 2 * np.degrees(np.arctan(np.tan(np.radians(camera.fov) / 2) * (1 + aspect) / 2))
        cam = gfx.PerspectiveCamera(fov, aspect)
        cam.world.reference_up = tuple(camera.up)
        cam.local.position = tuple(camera.position)
        cam.look_at(tuple(camera.position + camera.direction))
        distance = float(np.linalg.norm(camera.position - box.mean(axis=0)))
        cam.depth_range = (distance / 100, distance * 20)
        self.canvas.request_draw(lambda: self.renderer.render(scene, cam))
        return np.asarray(self.canvas.draw())[..., :3].copy()

    def png(self, a: Sequence[Any], b: Sequence[Any], camera: Camera,
            translucent: Sequence[Any] = ()) -> bytes:
        """:meth:`render` as PNG bytes."""
        buffer = io.BytesIO()
        self.image.fromarray(self.render(a, b, camera, translucent)).save(
            buffer, format="PNG", optimize=True)
        return buffer.getvalue()

    def group(self, group: Any) -> tuple[bytes, Camera]:
        """A group's picture (PNG bytes) and its camera: each clash's ``a`` in
        :data:`COLOUR_A`, its ``b`` in :data:`COLOUR_B` (an element in both roles keeps its
        first)."""
        a: dict[tuple[str, str], Any] = {}
        b: dict[tuple[str, str], Any] = {}
        for c in group.clashes:
            for body, side in ((c.a, a), (c.b, b)):
                key = (body.file, body.global_id)
                if key not in a and key not in b:
                    side[key] = body
        # Framed: each clash's smaller element (a pipe, not the whole wall it runs through);
        # the larger one translucent.
        def size(x: Any) -> float:
            return float(np.prod(np.ptp(x.mesh.bounds, axis=0)))

        ordered = [sorted((c.a, c.b), key=size) for c in group.clashes]
        focus = [small for small, _ in ordered]
        larger = {id(large): large for _, large in ordered if id(large) not in map(id, focus)}
        camera = group_camera(focus, aspect=self.size[0] / self.size[1])
        png = self.png(list(a.values()), list(b.values()), camera, list(larger.values()))
        return png, camera

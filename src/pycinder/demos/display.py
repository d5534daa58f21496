"""The demos' 3-D view: pygfx on the detector's own device (see :mod:`.device`).

A demo describes each frame as *layers*, copies of one mesh drawn alike (:class:`Layer`), and
optional line sets (:class:`Lines`); :class:`Display` keeps a pool of pygfx objects per layer and
moves them. The camera keeps the frame's true aspect ratio, a sun casts shadows, and headless
frames are rendered at twice the size in each direction and filtered down (anti-aliasing).

The display camera is independent of how the detector looks at the scene (paper 4.2: the
focused strategy gives every candidate pair its own view), and the display may show bodies that
detection no longer checks (frozen snowflakes).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import trimesh

from .shared import import_pygfx, shared_device


@dataclass(frozen=True)
class Look:
    """How a demo is shown.

    Attributes
    ----------
    eye, target : (3,) float
        Camera position and the point it looks at (the orbit centre in a window).
    fov : float
        Vertical field of view in degrees.
    keep_in_view : (2, 3) float
        World box (min, max corners) that must stay inside the frame.
    background : (str, str)
        Colours at the bottom and the top of the frame.
    sun : (3,) float
        Direction towards the light that casts the shadows.
    shadow_extent : float
        Width in world units of the region that gets shadows, around ``target``.
    legend_right : bool
        Put the legend in the bottom-right corner (else bottom-left), where it hides nothing.
    """

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    fov: float
    keep_in_view: np.ndarray
    background: tuple[str, str] = ("#c7d0dc", "#f3f5f9")
    sun: tuple[float, float, float] = (0.3, 1.0, 0.5)
    shadow_extent: float = 12.0
    legend_right: bool = False


def _camera_frame(eye: np.ndarray, target: np.ndarray, up: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    return right, np.cross(right, forward), forward


def fit_look(box: np.ndarray, direction: tuple[float, float, float], *, fov: float = 40.0,
             aspect: float = 4 / 3, margin: float = 0.05, **kwargs: Any) -> Look:
    """A Look from ``direction`` in which ``box`` fills the frame but for ``margin``.

    Parameters
    ----------
    box : (2, 3) float
        World min and max corners to frame.
    direction : (3,) float
        From the target towards the eye.
    fov : float
        Vertical field of view in degrees.
    aspect : float
        Frame width over height.
    margin : float
        Fraction of the frame's width and height left free on each side.
    **kwargs
        The Look's other fields (background, sun, shadow_extent).

    Returns
    -------
    Look
        Eye and target such that the box's eight corners project inside the frame, the
        tighter direction filling it to within the margin, with ``keep_in_view=box``.
    """
    box = np.asarray(box, float)
    corners = np.array([[box[i, 0], box[j, 1], box[k, 2]]
                        for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    direction = np.asarray(direction, float) / np.linalg.norm(direction)
    up = np.array([0.0, 1.0, 0.0])
    tan_y = np.tan(np.radians(fov) / 2)
    limit = 1 - 2 * margin
    target = box.mean(axis=0)
    distance = float(np.linalg.norm(box[1] - box[0]))

    def ndc(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
        right, true_up, forward = _camera_frame(eye, target, up)
        rel = corners - eye
        depth = rel @ forward
        return np.c_[rel @ right / (depth * tan_y * aspect), rel @ true_up / (depth * tan_y)]

    for _ in range(40):
        p = ndc(target + direction * distance, target)
        lo, hi = p.min(axis=0), p.max(axis=0)
        # Centre the box on screen, then scale the distance towards a snug fit.
        right, true_up, forward = _camera_frame(target + direction * distance, target, up)
        depth = float((box.mean(axis=0) - (target + direction * distance)) @ forward)
        shift = (hi + lo) / 2 * depth * tan_y * np.array([aspect, 1.0])
        target = target + right * shift[0] + true_up * shift[1]
        distance *= max((hi - lo).max() / 2 / limit, 0.5) ** 0.5
    return Look(eye=tuple(target + direction * distance), target=tuple(target), fov=fov,
                keep_in_view=box, **kwargs)


@dataclass
class Layer:
    """Copies of one mesh drawn alike.

    Attributes
    ----------
    mesh : trimesh.Trimesh
        The mesh, in body coordinates.
    transforms : (n, 4, 4) float
        World from body, one per copy.
    colours : (3,) or (n, 3) float
        Colour in [0, 1], for all copies or per copy.
    flat : bool
        Flat shading (one normal per face), for boxes.
    shadows : bool
        Cast and receive shadows.
    """

    mesh: trimesh.Trimesh
    transforms: np.ndarray
    colours: np.ndarray
    flat: bool = False
    shadows: bool = True


@dataclass
class Lines:
    """Line segments with a colour each, drawn unlit.

    Attributes
    ----------
    segments : (E, 2, 3) float
        World end points.
    colours : (E, 3) float
        Colour in [0, 1] per segment.
    thickness : float
        Width in pixels.
    """

    segments: np.ndarray
    colours: np.ndarray
    thickness: float = 1.5


def mesh_geometry(gfx: Any, mesh: trimesh.Trimesh, *, flat: bool = False) -> Any:
    """A pygfx Geometry of ``mesh``: shared vertices with vertex normals, or one vertex per
    face corner with the face's normal when ``flat``."""
    if flat:
        positions = np.asarray(mesh.vertices, np.float32)[np.asarray(mesh.faces).reshape(-1)]
        normals = np.repeat(np.asarray(mesh.face_normals, np.float32), 3, axis=0)
        indices = np.arange(len(positions), dtype=np.int32).reshape(-1, 3)
    else:
        positions = np.asarray(mesh.vertices, np.float32)
        normals = np.asarray(mesh.vertex_normals, np.float32)
        indices = np.asarray(mesh.faces, np.int32)
    return gfx.Geometry(positions=np.ascontiguousarray(positions),
                        normals=np.ascontiguousarray(normals), indices=indices)


@dataclass
class _Pool:
    geometry: Any
    objects: list = field(default_factory=list)
    colours: list = field(default_factory=list)


class Display:
    """A pygfx scene, camera and lights for one demo, headless or in a window.

    Parameters
    ----------
    look : Look
        Camera, lights and background.
    size : (width, height)
        Frame size in pixels.
    window : bool
        Draw into a window (rendercanvas.auto, with an orbit controller) instead of offscreen.
    title : str
        The window title.
    """

    def __init__(self, look: Look, size: tuple[int, int] = (640, 480), *, window: bool = False,
                 title: str = "pycinder") -> None:
        gfx = import_pygfx()
        shared_device()
        self.gfx, self.look, self.window = gfx, look, window
        self._size = (int(size[0]), int(size[1]))
        if window:
            from rendercanvas.auto import RenderCanvas

            self.canvas = RenderCanvas(size=size, title=title, update_mode="continuous",
                                       max_fps=60)
        else:
            from rendercanvas.offscreen import RenderCanvas

            self.canvas = RenderCanvas(size=size, pixel_ratio=1)
        # Twice the pixels in each direction, filtered down: smooth edges at a modest cost.
        self.renderer = gfx.WgpuRenderer(self.canvas, pixel_scale=2, ppaa="none",
                                         pixel_filter="linear")
        self.scene = gfx.Scene()
        self.scene.add(gfx.Background.from_color(*look.background))
        self.scene.add(gfx.AmbientLight(intensity=0.55))
        self.scene.add(gfx.DirectionalLight(intensity=0.8))  # a head light: nothing is black
        sun = gfx.DirectionalLight(intensity=2.2, cast_shadow=True)
        target = np.asarray(look.target, float)
        direction = np.asarray(look.sun, float) / np.linalg.norm(look.sun)
        sun.local.position = target + direction * look.shadow_extent
        sun.target.local.position = target
        sun.shadow.camera.width = sun.shadow.camera.height = look.shadow_extent
        sun.shadow.camera.depth_range = (0.01, 3 * look.shadow_extent)
        sun.shadow.bias = 0.0005
        self.scene.add(sun, sun.target)
        # pygfx's fov spans the mean of the view's width and height; Look.fov is vertical.
        aspect = size[0] / size[1]
        fov = 2 * np.degrees(np.arctan(np.tan(np.radians(look.fov) / 2) * (1 + aspect) / 2))
        self.camera = gfx.PerspectiveCamera(fov, aspect)
        self.camera.local.position = look.eye
        self.camera.show_pos(look.target)
        distance = float(np.linalg.norm(np.subtract(look.eye, look.target)))
        self.camera.depth_range = (distance / 50, distance * 10)
        self.camera.set_view_size(*size)
        self.controller = None
        if window:
            self.controller = gfx.OrbitController(self.camera, register_events=self.renderer)
        self._hud: tuple | None = None  # the overlay's image, scene and camera in a window
        self._pools: dict[str, _Pool] = {}
        self._lines: dict[str, Any] = {}

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the frame in pixels; a window's follows its resizing."""
        if self.window:
            width, height = self.canvas.get_logical_size()
            return max(int(round(width)), 1), max(int(round(height)), 1)
        return self._size

    # -- the scene --------------------------------------------------------------------------

    def update(self, layers: dict[str, Layer | Lines]) -> None:
        """Show these layers; layers not named keep what they showed last, and a Lines object
        shown before (the same object) is not uploaded again."""
        for name, layer in layers.items():
            if isinstance(layer, Lines):
                self._set_lines(name, layer)
            else:
                self._set_layer(name, layer)

    def _set_layer(self, name: str, layer: Layer) -> None:
        gfx = self.gfx
        pool = self._pools.get(name)
        if pool is None:
            pool = self._pools[name] = _Pool(mesh_geometry(gfx, layer.mesh, flat=layer.flat))
        transforms = np.asarray(layer.transforms, float).reshape(-1, 4, 4)
        colours = np.broadcast_to(np.asarray(layer.colours, float), (len(transforms), 3))
        while len(pool.objects) < len(transforms):
            obj = gfx.Mesh(pool.geometry, gfx.MeshPhongMaterial(shininess=20, specular="#333"))
            obj.cast_shadow = obj.receive_shadow = layer.shadows
            self.scene.add(obj)
            pool.objects.append(obj)
            pool.colours.append(None)
        for k, obj in enumerate(pool.objects):
            obj.visible = k < len(transforms)
            if not obj.visible:
                continue
            obj.local.matrix = transforms[k]
            colour = tuple(np.round(colours[k], 4))
            if colour != pool.colours[k]:
                obj.material.color = colour
                pool.colours[k] = colour

    def _set_lines(self, name: str, lines: Lines) -> None:
        gfx = self.gfx
        old = self._lines.pop(name, None)
        if old is not None and old[0] is lines:
            self._lines[name] = old
            return
        if old is not None:
            self.scene.remove(old[1])
        positions = np.asarray(lines.segments, np.float32).reshape(-1, 3)
        colours = np.ones((len(positions), 4), np.float32)
        colours[:, :3] = np.repeat(np.asarray(lines.colours, np.float32), 2, axis=0)
        obj = gfx.Line(gfx.Geometry(positions=positions, colors=colours),
                       gfx.LineSegmentMaterial(thickness=lines.thickness, color_mode="vertex",
                                               aa=True))
        self.scene.add(obj)
        self._lines[name] = (lines, obj)

    # -- drawing ----------------------------------------------------------------------------

    def follow(self, box: np.ndarray, direction: tuple[float, float, float],
               smoothing: float = 0.25) -> None:
        """Move the camera so that ``box`` ((2, 3) world min and max corners) is in the frame,
        looking along ``-direction``. The framed box grows at once to hold ``box`` and shrinks
        towards it by ``smoothing`` of the way per call, so the camera glides in and never
        loses what ``box`` holds."""
        box = np.asarray(box, float)
        if getattr(self, "_followed", None) is None:
            self._followed = box
        else:
            glide = self._followed + smoothing * (box - self._followed)
            self._followed = np.stack([np.minimum(glide[0], box[0]),
                                       np.maximum(glide[1], box[1])])
        look = fit_look(self._followed, direction, fov=self.look.fov,
                        aspect=self.size[0] / self.size[1], margin=0.04)
        self.camera.local.position = look.eye
        self.camera.show_pos(look.target)
        distance = float(np.linalg.norm(np.subtract(look.eye, look.target)))
        self.camera.depth_range = (distance / 50, distance * 10)

    def render(self) -> np.ndarray:
        """Render headless: (H, W, 3) uint8."""
        self.canvas.request_draw(lambda: self.renderer.render(self.scene, self.camera))
        return np.asarray(self.canvas.draw())[..., :3].copy()

    def draw_window(self, layer: np.ndarray) -> None:
        """Inside a window's draw callback: the scene, then ``layer`` (H, W, 4) over it."""
        gfx = self.gfx
        if self._hud is None or self._hud[0].geometry.grid.data.shape != layer.shape:
            texture = gfx.Texture(np.array(layer, np.uint8), dim=2)
            image = gfx.Image(gfx.Geometry(grid=texture),
                              gfx.ImageBasicMaterial(clim=(0, 255), interpolation="nearest",
                                                     alpha_mode="blend"))
            hud = gfx.Scene()
            hud.add(image)
            self._hud = (image, hud, gfx.ScreenCoordsCamera(invert_y=True))
        image, hud, camera = self._hud
        image.geometry.grid.data[:] = layer
        image.geometry.grid.update_full()
        self.renderer.render(self.scene, self.camera, flush=False)
        self.renderer.render(hud, camera)

    # -- geometry of the view ---------------------------------------------------------------

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel positions of world points through the current camera.

        Parameters
        ----------
        points : (n, 3) float

        Returns
        -------
        xy : (n, 2) float
            Pixel coordinates, x right and y down, (0, 0) the top-left corner of the frame.
        inside : (n,) bool
            In front of the camera and inside the frame.
        """
        points = np.asarray(points, float).reshape(-1, 3)
        width, height = self.size
        self.camera.set_view_size(width, height)
        clip = np.c_[points, np.ones(len(points))] @ np.asarray(self.camera.camera_matrix).T
        w = clip[:, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            ndc = clip[:, :2] / w[:, None]
        xy = np.c_[(ndc[:, 0] + 1) * 0.5 * width, (1 - ndc[:, 1]) * 0.5 * height]
        inside = (w > 0) & (xy[:, 0] >= 0) & (xy[:, 0] < width) & (xy[:, 1] >= 0) & \
            (xy[:, 1] < height)
        return xy, inside

    def normal_ball(self, radius: int = 14) -> np.ndarray:
        """A legend glyph: a ball coloured by its normals (0.5 + 0.5 n) as this camera sees
        them, so that a direction on screen reads off as a colour. (2r+1, 2r+1, 4) uint8 RGBA."""
        rot = np.asarray(self.camera.world.matrix, float)[:3, :3]
        right, up, back = (rot[:, k] / np.linalg.norm(rot[:, k]) for k in range(3))
        u, v = np.meshgrid(np.arange(-radius, radius + 1), np.arange(-radius, radius + 1))
        u, v = u / (radius + 0.5), -v / (radius + 0.5)
        r2 = u ** 2 + v ** 2
        n = (u[..., None] * right + v[..., None] * up +
             np.sqrt(np.clip(1 - r2, 0, 1))[..., None] * back)
        out = np.zeros(u.shape + (4,), np.uint8)
        out[..., :3] = np.round((0.5 + 0.5 * n) * 255).astype(np.uint8)
        out[..., 3] = np.where(r2 <= 1, 255, 0)
        return out

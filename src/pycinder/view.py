"""Views: the projection CInDeR renders through (paper 4.2's "projection function").

A :class:`View` is a view matrix (view from world, right-handed, looking down -z) and a projection
(clip from view, WebGPU conventions: depth 0 at the near plane, 1 at the far plane). The ray of
each pixel runs from the edge towards the near plane, so a solid cut by the near or far plane
breaks the count. :meth:`View.fit` builds a view that contains every body with a margin.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

DEFAULT_DIRECTION = (-0.31, -0.42, -0.85)
"""The default viewing direction: oblique, so that edges of axis-aligned boxes do not project to
points and faces of axis-aligned boxes are not seen edge-on."""


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(4, 4) view-from-world matrix of a camera at ``eye`` looking at ``target``."""
    eye, target, up = (np.asarray(a, dtype=np.float64) for a in (eye, target, up))
    f = target - eye
    f /= np.linalg.norm(f)
    if abs(np.dot(f, up / np.linalg.norm(up))) > 0.999:
        up = np.array([1.0, 0.0, 0.0]) if abs(f[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def orthographic(half_width: float, half_height: float, near: float, far: float) -> np.ndarray:
    """(4, 4) clip-from-view matrix mapping view z in [-far, -near] to depth [1, 0]."""
    p = np.zeros((4, 4))
    p[0, 0] = 1.0 / half_width
    p[1, 1] = 1.0 / half_height
    p[2, 2] = -1.0 / (far - near)
    p[2, 3] = -near / (far - near)
    p[3, 3] = 1.0
    return p


def perspective(fov_y_degrees: float, aspect: float, near: float, far: float) -> np.ndarray:
    """(4, 4) clip-from-view perspective matrix with depth 0 at ``near`` and 1 at ``far``."""
    f = 1.0 / np.tan(np.radians(fov_y_degrees) / 2.0)
    p = np.zeros((4, 4))
    p[0, 0] = f / aspect
    p[1, 1] = f
    p[2, 2] = far / (near - far)
    p[2, 3] = near * far / (near - far)
    p[3, 2] = -1.0
    return p


@dataclass(frozen=True)
class View:
    """A camera for one CInDeR render.

    view : (4, 4) float, view from world
    projection : (4, 4) float, clip from view (WebGPU depth range [0, 1])
    """

    view: np.ndarray
    projection: np.ndarray
    pixel_size: float | None = field(default=None, compare=False)
    """World-space size of a pixel at the given resolution, for orthographic fits (else None)."""

    @property
    def clip_from_world(self) -> np.ndarray:
        return np.asarray(self.projection, dtype=np.float64) @ np.asarray(self.view, dtype=np.float64)

    @classmethod
    def look_at(cls, eye: Sequence[float], target: Sequence[float], up: Sequence[float] = (0, 1, 0),
                *, fov_y: float = 45.0, near: float = 0.1, far: float = 100.0) -> View:
        """A perspective view. The caller keeps every body between ``near`` and ``far``."""
        return cls(look_at(np.asarray(eye), np.asarray(target), np.asarray(up)),
                   perspective(fov_y, 1.0, near, far))

    @classmethod
    def fit(cls, points: np.ndarray, *, direction: Sequence[float] = DEFAULT_DIRECTION,
            up: Sequence[float] = (0, 1, 0), margin: float = 0.02, resolution: int | None = None
            ) -> View:
        """An orthographic view along ``direction`` that contains all ``points``.

        points : (n, 3) float, world-space points whose convex hull holds the scene (for example
            the corners of every body's bounding box)
        margin : fraction of the scene's size kept free around it, so that nothing touches the
            near or far plane or the image border
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(direction, dtype=np.float64)
        d /= np.linalg.norm(d)
        center = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        radius = float(np.linalg.norm(pts - center, axis=1).max()) or 1.0
        eye = center - d * 2.0 * radius
        view = look_at(eye, center, np.asarray(up, dtype=np.float64))
        local = pts @ view[:3, :3].T + view[:3, 3]
        pad = margin * radius
        half = max(np.abs(local[:, 0]).max(), np.abs(local[:, 1]).max()) + pad
        depth = -local[:, 2]
        near, far = float(depth.min() - pad), float(depth.max() + pad)
        pixel = 2.0 * half / resolution if resolution else None
        return cls(view, orthographic(half, half, near, far), pixel)

    @classmethod
    def fit_bodies(cls, bodies: Sequence, transforms: np.ndarray | Sequence | None = None,
                   **kwargs) -> View:
        """:meth:`fit` around bodies (trimesh meshes or (vertices, faces) pairs).

        transforms : None or (N, 4, 4) world-from-body matrices; keywords go to :meth:`fit`
        """
        verts = [np.asarray(b.vertices if hasattr(b, "vertices") else b[0], dtype=np.float64)
                 for b in bodies]
        t = np.broadcast_to(np.eye(4), (len(verts), 4, 4)) if transforms is None \
            else np.asarray(transforms, dtype=np.float64)
        lo = np.stack([v.min(axis=0) for v in verts])
        hi = np.stack([v.max(axis=0) for v in verts])
        return cls.fit(world_corners(lo, hi, t), **kwargs)

    def pixel_size_at(self, point: np.ndarray, resolution: int) -> float:
        """World size of one pixel of a ``resolution``-wide image at a world point (the same
        everywhere for orthographic views; growing with distance for perspective ones)."""
        p = np.asarray(self.projection, dtype=np.float64)
        if p[3, 2] == 0.0:  # orthographic
            return 2.0 / (abs(p[0, 0]) * resolution)
        eye = np.asarray(self.view, dtype=np.float64) @ np.append(np.asarray(point, float), 1.0)
        return 2.0 * max(-eye[2], 1e-12) / (abs(p[0, 0]) * resolution)

    def depth_range(self, local_min: np.ndarray, local_max: np.ndarray, transforms: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Per body, the (min, max) depth of its bounding-box corners in this view: (N,), (N,)."""
        corners = world_corners(local_min, local_max, transforms)
        z = self.project(corners, 1, 1)[:, 2].reshape(len(local_min), 8)
        return z.min(axis=1), z.max(axis=1)

    def project(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """World points (n, 3) to pixel coordinates and depth (n, 3): x right, y down."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        clip = np.c_[pts, np.ones(len(pts))] @ self.clip_from_world.T
        ndc = clip[:, :3] / clip[:, 3:4]
        x = (ndc[:, 0] + 1.0) * 0.5 * width
        y = (1.0 - ndc[:, 1]) * 0.5 * height
        return np.c_[x, y, ndc[:, 2]]

    def unproject(self, x: np.ndarray, y: np.ndarray, depth: np.ndarray, width: int, height: int
                  ) -> np.ndarray:
        """Pixel centres (x, y) at ``depth`` to world points (n, 3)."""
        ndc_x = (np.asarray(x, dtype=np.float64) + 0.5) / width * 2.0 - 1.0
        ndc_y = 1.0 - (np.asarray(y, dtype=np.float64) + 0.5) / height * 2.0
        ndc = np.c_[ndc_x, ndc_y, np.asarray(depth, dtype=np.float64), np.ones(len(ndc_x))]
        world = ndc @ np.linalg.inv(self.clip_from_world).T
        return world[:, :3] / world[:, 3:4]


def world_corners(local_min: np.ndarray, local_max: np.ndarray, transforms: np.ndarray) -> np.ndarray:
    """World-space corners of each body's bounding box.

    local_min, local_max : (N, 3) float, body-space bounds
    transforms : (N, 4, 4) float, world from body
    Returns (8N, 3) float.
    """
    bits = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], dtype=np.float64)
    corners = local_min[:, None, :] + bits[None] * (local_max - local_min)[:, None, :]
    world = np.einsum("nij,nkj->nki", transforms[:, :3, :3], corners) + transforms[:, None, :3, 3]
    return world.reshape(-1, 3)

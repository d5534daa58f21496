"""Face, vertex and edge normals of a pose. They depend on the vertices, so they are recomputed
whenever a body's vertices change (see :class:`~pycinder.scene.bodies.Shape`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from .topology import Topology

if TYPE_CHECKING:
    from .bodies import Scene


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals and face areas.

    Parameters
    ----------
    vertices : (V, 3) float
    faces : (F, 3) int

    Returns
    -------
    normals : (F, 3) float32
        Zero for zero-area faces.
    areas : (F,) float64
    """
    tri = vertices[faces].astype(np.float64)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(cross, axis=1)
    normals = np.divide(cross, length[:, None], out=np.zeros_like(cross), where=length[:, None] > 0)
    return normals.astype(np.float32), 0.5 * length


def _accumulate(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    out = np.stack([np.bincount(index, weights=values[:, k], minlength=n) for k in range(3)], axis=1)
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return np.divide(out, length, out=np.zeros_like(out), where=length > 0).astype(np.float32)


def vertex_and_edge_normals(vertices: np.ndarray, topo: Topology) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted vertex normals and edge normals (the mean of an edge's faces).

    Parameters
    ----------
    vertices : (V, 3) float
    topo : Topology

    Returns
    -------
    vertex_normals : (V, 3) float32
    edge_normals : (E, 3) float32
    """
    normals, areas = face_normals(vertices, topo.faces)
    weighted = normals.astype(np.float64) * areas[:, None]  # float32 would overflow for huge bodies
    vn = _accumulate(topo.faces.reshape(-1).astype(np.int64), np.repeat(weighted, 3, axis=0),
                     topo.n_vertices)
    en = _accumulate(topo.edge_faces, np.repeat(normals, 3, axis=0), len(topo.edges))
    return vn, en


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Volume enclosed by a closed mesh; negative when it is wound inside out."""
    tri = vertices[faces].astype(np.float64)
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


def world_edge_normals(scene: Scene, body: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """World-space unit normals of edges given by body and edge index, from the bodies' current
    vertices.

    Parameters
    ----------
    scene : Scene
    body, edge : (n,) int

    Returns
    -------
    (n, 3) float32
    """
    return _world_normals(scene, body, lambda shape, sel: shape.normals()[1][edge[sel]])


def world_face_normals(scene: Scene, body: np.ndarray, face: np.ndarray) -> np.ndarray:
    """World-space unit normals of faces given by body and face index.

    Parameters
    ----------
    scene : Scene
    body, face : (n,) int

    Returns
    -------
    (n, 3) float32
    """
    return _world_normals(scene, body, lambda shape, sel: shape.face_normals()[face[sel]])


def _world_normals(scene: Scene, body: np.ndarray,
                   local_of: Callable[[Any, np.ndarray], np.ndarray]) -> np.ndarray:
    out = np.zeros((len(body), 3), dtype=np.float32)
    if len(body) == 0:
        return out
    # Normals transform with the inverse transpose of the linear part: once per body.
    bodies, which = np.unique(body, return_inverse=True)
    inv_t = np.linalg.inv(scene.transforms[bodies, :3, :3]).transpose(0, 2, 1)
    shape = scene.body_shape[body]
    for k in np.unique(shape):
        sel = shape == k
        local = np.asarray(local_of(scene.shapes[k], sel), dtype=np.float64)
        world = np.einsum("nij,nj->ni", inv_t[which[sel]], local)
        out[sel] = world / np.maximum(np.linalg.norm(world, axis=1, keepdims=True), 1e-30)
    return out

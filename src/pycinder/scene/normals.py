"""Face, vertex and edge normals of a pose. They depend on the vertices, so they are recomputed
whenever a body's vertices change (see :class:`~pycinder.scene.bodies.Shape`)."""

from __future__ import annotations

import numpy as np

from .topology import Topology


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

"""Clusters: runs of :data:`CLUSTER_FACES` spatially close faces, and the edges they own.

The focused passes cull a tile's geometry cluster by cluster before they look at single faces and
edges, so a pair touching at one spot only costs the clusters near it. Faces are ordered along a
Morton curve through their centroids; each unique edge belongs to the first cluster among the
faces that use it. One GPU workgroup processes one cluster.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


CLUSTER_FACES = 64


@dataclass(frozen=True, eq=False)
class Clusters:
    """Face and edge order of a topology, and each cluster's range in it.

    Attributes
    ----------
    face_order : (F,) int64
        Original face index of each face, in cluster order.
    edge_order : (E,) int64
        Original unique-edge index of each edge, in cluster order.
    face_start, edge_start : (C + 1,) int64
        Prefix offsets of each cluster's faces and edges in the orders above.
    """

    face_order: np.ndarray
    edge_order: np.ndarray
    face_start: np.ndarray
    edge_start: np.ndarray

    @property
    def count(self) -> int:
        return len(self.face_start) - 1

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.face_order, self.edge_order, self.face_start,
                                      self.edge_start))


def _spread_bits(x: np.ndarray) -> np.ndarray:
    """Insert two zero bits between the low 10 bits of ``x`` (for 30-bit Morton codes)."""
    x = x.astype(np.uint32) & 0x3FF
    x = (x | (x << 16)) & 0x030000FF
    x = (x | (x << 8)) & 0x0300F00F
    x = (x | (x << 4)) & 0x030C30C3
    x = (x | (x << 2)) & 0x09249249
    return x


def build_clusters(faces: np.ndarray, edge_faces: np.ndarray, n_edges: int,
                   vertices: np.ndarray) -> Clusters:
    """Cluster a mesh's faces along a Morton curve of their centroids.

    Parameters
    ----------
    faces : (F, 3) int
    edge_faces : (3F,) int
        The unique edge of each directed edge (face ``f``'s edges at ``3f``, ``3f + 1``,
        ``3f + 2``), as :attr:`~pycinder.scene.topology.Topology.edge_faces`.
    n_edges : int
        How many unique edges.
    vertices : (V, 3) float
        A pose of the mesh (clusters only decide what is culled together; any pose is correct).
    """
    n = len(faces)
    centroids = vertices[faces].astype(np.float64).mean(axis=1)
    lo, hi = centroids.min(axis=0), centroids.max(axis=0)
    q = ((centroids - lo) / np.maximum(hi - lo, 1e-30) * 1023.0).astype(np.uint32)
    code = _spread_bits(q[:, 0]) | (_spread_bits(q[:, 1]) << 1) | (_spread_bits(q[:, 2]) << 2)
    face_order = np.argsort(code, kind="stable").astype(np.int64)
    rank = np.empty(n, dtype=np.int64)
    rank[face_order] = np.arange(n)
    count = -(-n // CLUSTER_FACES)
    face_start = np.minimum(np.arange(count + 1) * CLUSTER_FACES, n).astype(np.int64)
    cluster_of_face = rank // CLUSTER_FACES
    directed_cluster = np.repeat(cluster_of_face, 3)
    edge_cluster = np.full(n_edges, count, dtype=np.int64)
    np.minimum.at(edge_cluster, edge_faces, directed_cluster)
    edge_order = np.argsort(edge_cluster, kind="stable").astype(np.int64)
    edge_start = np.searchsorted(edge_cluster[edge_order], np.arange(count + 1)).astype(np.int64)
    return Clusters(face_order, edge_order, face_start, edge_start)

"""The whole scene in flat arrays, one copy per body, as the paper's whole-scene passes draw it
(strategy ``"scene"``; the focused strategy packs each distinct shape once instead)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .bodies import Scene

_NONE = np.zeros((1, 3), dtype=np.float32)


@dataclass(eq=False)
class PackedScene:
    """All bodies in flat arrays, as the GPU buffers hold them.

    Attributes
    ----------
    positions : (V, 3) float32
        Body-space vertices of every body, one body after another.
    vertex_body : (V,) uint32
    indices : (3F,) uint32
        Global vertex indices of all faces.
    edges : (E, 2) uint32
        Global vertex indices of all unique edges.
    vertex_normals : (V, 3) float32, or (1, 3) zeros when not asked for
    edge_normals : (E, 3) float32, or (1, 3) zeros when not asked for
    vertex_start, face_start, edge_start : (N + 1,) int64
        Prefix offsets per body.
    topology_ids : tuple of int
        Identity of every body's topology (what the draw commands depend on).
    shape_ids : tuple of int
        Identity of every body's shape (what the vertices and normals depend on).
    """

    positions: np.ndarray
    vertex_body: np.ndarray
    indices: np.ndarray
    edges: np.ndarray
    vertex_normals: np.ndarray
    edge_normals: np.ndarray
    vertex_start: np.ndarray
    face_start: np.ndarray
    edge_start: np.ndarray
    topology_ids: tuple[int, ...]
    shape_ids: tuple[int, ...]
    normals: bool


def _prefix(counts: Sequence[int]) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(np.asarray(counts, dtype=np.int64))]).astype(np.int64)


def _normals(scene: Scene, wanted: bool) -> tuple[np.ndarray, np.ndarray]:
    if not wanted:
        return _NONE, _NONE
    per_shape = [s.normals() for s in scene.shapes]
    return (np.concatenate([per_shape[k][0] for k in scene.body_shape]),
            np.concatenate([per_shape[k][1] for k in scene.body_shape]))


def pack(scene: Scene, normals: bool = False) -> PackedScene:
    """Pack a scene body by body; ``normals`` also packs vertex and edge normals."""
    shapes = [scene.shapes[k] for k in scene.body_shape]
    vs = _prefix([len(s.vertices) for s in shapes])
    fs = _prefix([len(s.topology.faces) for s in shapes])
    es = _prefix([len(s.topology.edges) for s in shapes])
    offsets = vs[:-1].astype(np.uint32)
    vn, en = _normals(scene, normals)
    return PackedScene(
        positions=np.concatenate([s.vertices for s in shapes]),
        vertex_body=np.repeat(np.arange(len(shapes), dtype=np.uint32), np.diff(vs)),
        indices=np.concatenate([s.topology.faces + o for s, o in zip(shapes, offsets)]).reshape(-1),
        edges=np.concatenate([s.topology.edges + o for s, o in zip(shapes, offsets)]),
        vertex_normals=vn,
        edge_normals=en,
        vertex_start=vs,
        face_start=fs,
        edge_start=es,
        topology_ids=tuple(id(s.topology) for s in shapes),
        shape_ids=tuple(id(s) for s in shapes),
        normals=normals,
    )


def repack(last: PackedScene | None, scene: Scene, normals: bool = False) -> PackedScene:
    """:func:`pack`, reusing ``last``'s topology arrays when every body's topology is unchanged
    (an animation frame): then only positions, and normals when asked for, are packed anew."""
    shapes = [scene.shapes[k] for k in scene.body_shape]
    topology_ids = tuple(id(s.topology) for s in shapes)
    shape_ids = tuple(id(s) for s in shapes)
    if last is None or last.topology_ids != topology_ids:
        return pack(scene, normals)
    if last.shape_ids == shape_ids and last.normals == normals:
        return last
    positions = np.concatenate([s.vertices for s in shapes])
    vn, en = _normals(scene, normals)
    return PackedScene(positions, last.vertex_body, last.indices, last.edges, vn, en,
                       last.vertex_start, last.face_start, last.edge_start, topology_ids,
                       shape_ids, normals)


@dataclass(eq=False)
class ShapePack:
    """Every distinct shape once, in cluster order, as the focused passes read them.

    Attributes
    ----------
    positions : (V, 3) float32
        Body-space vertices of every shape, one shape after another.
    faces : (F, 3) uint32
        Global vertex indices, each shape's faces in cluster order.
    edges : (E, 2) uint32
        Global vertex indices, each shape's unique edges in cluster order.
    clusters : (C, 4) uint32
        Per cluster: first face, face count, first edge, edge count (global).
    vertex_start, face_start, edge_start, cluster_start : (S + 1,) int64
        Prefix offsets per shape.
    edge_original, face_original : (E,), (F,) int64
        Index of each packed edge among its shape's own ``topology.edges``, and of each packed
        face in the shape's face array as given (faces dropped as degenerate are not packed).
    layout : tuple
        Topology identity and vertex count of every shape: equal layouts share index buffers.
    """

    positions: np.ndarray
    faces: np.ndarray
    edges: np.ndarray
    clusters: np.ndarray
    vertex_start: np.ndarray
    face_start: np.ndarray
    edge_start: np.ndarray
    cluster_start: np.ndarray
    edge_original: np.ndarray
    face_original: np.ndarray
    layout: tuple


def shape_layout(shapes: Sequence) -> tuple:
    return tuple((id(s.topology), len(s.vertices)) for s in shapes)


def pack_shapes(shapes: Sequence) -> ShapePack:
    """Pack distinct shapes for the focused passes."""
    vs = _prefix([len(s.vertices) for s in shapes])
    fs = _prefix([len(s.topology.faces) for s in shapes])
    es = _prefix([len(s.topology.edges) for s in shapes])
    cl = [s.topology.clusters(s.vertices) for s in shapes]
    cs = _prefix([c.count for c in cl])
    faces, edges, clusters = [], [], []
    for s, c, v0, f0, e0 in zip(shapes, cl, vs[:-1], fs[:-1], es[:-1]):
        faces.append(s.topology.faces[c.face_order] + np.uint32(v0))
        edges.append(s.topology.edges[c.edge_order] + np.uint32(v0))
        clusters.append(np.stack([c.face_start[:-1] + f0, np.diff(c.face_start),
                                  c.edge_start[:-1] + e0, np.diff(c.edge_start)], axis=1))
    return ShapePack(
        positions=np.concatenate([s.vertices for s in shapes]),
        faces=np.concatenate(faces).astype(np.uint32),
        edges=np.concatenate(edges).astype(np.uint32),
        clusters=np.concatenate(clusters).astype(np.uint32),
        vertex_start=vs, face_start=fs, edge_start=es, cluster_start=cs,
        edge_original=np.concatenate([c.edge_order for c in cl]),
        face_original=np.concatenate([c.face_order if s.topology.kept is None
                                      else s.topology.kept[c.face_order]
                                      for s, c in zip(shapes, cl)]),
        layout=shape_layout(shapes),
    )

"""Caches are keyed on content and bounded by bytes: animation loops that pass fresh arrays every
frame neither rebuild topologies nor grow memory."""

import numpy as np
import trimesh

import pycinder
from pycinder.scene import ShapeCache, TopologyCache


def test_fresh_arrays_each_frame_reuse_one_topology():
    ball = trimesh.creation.icosphere(subdivisions=3)
    det = pycinder.Detector()
    for k in range(50):
        verts = np.array(ball.vertices) * (1 + 0.01 * k)   # new arrays, new content
        faces = np.array(ball.faces)                         # new array, same content
        det.find_collisions([(verts, faces), (verts + [0.5, 0, 0], faces.copy())])
    assert det.shapes.topologies.builds == 1
    assert len(det.shapes.topologies) == 1


def test_trimesh_meshes_use_their_own_content_hash():
    ball = trimesh.creation.icosphere(subdivisions=2)
    cache = ShapeCache()
    first = cache.get(ball.vertices, ball.faces, "body 0", False)
    assert cache.get(ball.vertices, ball.faces, "body 0", False) is first
    ball.vertices[0] += 0.1  # trimesh marks the array dirty; the shape is rebuilt
    assert cache.get(ball.vertices, ball.faces, "body 0", False) is not first
    assert cache.topologies.builds == 1


def test_caches_are_bounded_by_bytes():
    cache = TopologyCache(max_bytes=200_000)
    rng = np.random.default_rng(0)
    for k in range(60):
        mesh = trimesh.creation.icosphere(subdivisions=2)
        faces = np.array(mesh.faces)[rng.permutation(len(mesh.faces))]  # distinct content
        cache.get(faces, len(mesh.vertices), "body")
    assert cache.nbytes <= 200_000 and len(cache) < 60
    shapes = ShapeCache(max_bytes=400_000)
    ball = trimesh.creation.icosphere(subdivisions=3)
    for k in range(200):
        shapes.get(np.array(ball.vertices) * (1 + k), np.array(ball.faces), "body", False)
    assert shapes.nbytes <= shapes.max_bytes and len(shapes) < 200

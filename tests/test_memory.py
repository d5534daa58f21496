"""Caches are keyed on content and bounded by bytes: animation loops that pass fresh arrays every
frame neither rebuild topologies nor grow memory."""

import numpy as np
import pytest
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
    for k in range(200):  # a body that deforms every query keeps only its last two shapes
        shapes.begin_query()
        shapes.get(np.array(ball.vertices) * (1 + k), np.array(ball.faces), "body", False)
        shapes.end_query()
    # Each shape holds its single-precision vertices and a copy of the bytes it was made from
    # (a cache hit is taken only after comparing them: see ShapeCache), and nothing more.
    given = np.array(ball.vertices).nbytes
    assert len(shapes) == 2
    assert shapes.nbytes <= 2 * (np.array(ball.vertices, np.float32).nbytes + given)


def _rss_mib() -> float:
    import os

    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def test_a_deforming_body_keeps_memory_flat_for_ten_thousand_frames():
    """A ball passed as fresh (vertices, faces) arrays that deform every frame, touching a box:
    its GPU slot is overwritten and its old shapes dropped, so memory stays flat."""
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    v0, f = np.array(ball.vertices), np.array(ball.faces)
    box = trimesh.creation.box((0.4, 0.4, 0.4))
    poses = np.stack([np.eye(4)] * 2)
    poses[1, 0, 3] = 0.6
    det = pycinder.Detector(tolerance=0.05, records="none")
    marks = []
    for k in range(10_500):
        result = det.find_collisions([(v0 * (1 + 0.05 * np.sin(0.01 * k)), f), box], poses)
        assert len(result.pairs) == 1
        if k % 1000 == 499:  # after 500 frames of warm-up, then every 1,000 frames
            marks.append(_rss_mib())
    growth = np.diff(marks)
    print("RSS growth per 1,000 frames (MiB):", np.round(growth, 2).tolist())
    assert marks[-1] - marks[0] < 4.0, marks
    assert len(det.shapes) <= 3 and det.shapes.topologies.builds <= 2


def test_a_mesh_larger_than_the_cache_is_kept_while_it_is_used():
    """The shapes and topologies of the current (and previous) query stay cached whatever the
    byte bound: a mesh larger than the cache is not rebuilt on every call."""
    big = trimesh.creation.icosphere(subdivisions=5)          # 20,480 faces, about 0.8 MB cached
    det = pycinder.Detector()
    det.shapes = ShapeCache(max_bytes=100_000)
    box = trimesh.creation.box((0.5, 0.5, 0.5))
    poses = np.stack([np.eye(4), np.eye(4)])
    poses[1, 0, 3] = 1.1
    for _ in range(4):
        det.find_collisions([(np.array(big.vertices), np.array(big.faces)), box], poses)
    assert det.shapes.topologies.builds == 2
    assert det.shapes.topologies.nbytes > det.shapes.topologies.max_bytes


def test_bodies_are_measured_on_threads_and_in_a_forked_child(monkeypatch):
    """Large bodies are hashed and measured on a thread pool; the answer is the one-thread
    answer, an edited body is seen, and a process forked after a query still answers (its pool
    is made anew). Two threads at least, whatever the machine and its environment allow (a
    single CPU, or OMP_NUM_THREADS=1, would have no pool)."""
    import multiprocessing

    from pycinder.util import threads
    from pycinder.scene import bodies

    monkeypatch.setattr(threads, "WORKERS", max(threads.WORKERS, 2))

    ball = trimesh.creation.icosphere(subdivisions=5)          # 10,242 vertices, 240 kB
    verts = [np.array(ball.vertices) * (1 + 0.01 * k) for k in range(8)]
    faces = np.array(ball.faces)
    poses = np.stack([np.eye(4)] * 8)
    poses[:, 0, 3] = 1.9 * np.arange(8)
    bodies_in = [(v, faces) for v in verts]
    detector = pycinder.Detector()

    class Counting:
        """The pool, counting the tasks given to it."""

        def __init__(self, pool):
            self.pool, self.tasks = pool, 0

        def submit(self, *args, **kwargs):
            self.tasks += 1
            return self.pool.submit(*args, **kwargs)

        def map(self, fn, *iterables):
            items = list(zip(*iterables))
            self.tasks += len(items)
            return self.pool.map(fn, *zip(*items))

    counting = Counting(threads.pool())
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(threads, "pool", lambda: counting)
        threaded = detector.find_collisions(bodies_in, poses)
    assert counting.tasks >= 2                               # the threads were used
    one = pycinder.Detector()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(bodies, "PARALLEL_BYTES", 1 << 60)
        alone = one.find_collisions(bodies_in, poses)
    assert threaded.pairs.tolist() == alone.pairs.tolist()
    # radii 1.0 to 1.07 at 1.9 apart: neighbours overlap by 0.1 to 0.24, more than twice the
    # default tolerance (1% of a ball's box diagonal, 0.035); the others are 1.6 or more apart
    radius = 1 + 0.01 * np.arange(8)
    want = [[i, i + 1] for i in range(7)]
    assert threaded.pairs.tolist() == want
    # A forked child (as multiprocessing makes on Linux) validates bodies on a pool of its own
    # (the parent's threads are not in it): without one, it would wait for ever.
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(1) as pool:
        radii = pool.apply_async(_radii_in_child, (bodies_in, poses)).get(timeout=60)
    assert np.allclose(radii, radius, rtol=1e-3)


def _radii_in_child(bodies_in, poses):
    from pycinder.util import threads
    from pycinder.scene import prepare_scene

    assert threads._pool is None
    scene = prepare_scene(bodies_in, poses)
    assert threads._pool is not None
    return scene.radius.tolist()

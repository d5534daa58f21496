"""The Warp benchmark peer against exact geometry, and its device broad phase against pycinder's
NumPy sweep on the same world boxes."""

import numpy as np
import pytest
import trimesh

pytest.importorskip("warp", reason="the Warp peer needs warp-lang: pip install 'pycinder[bench]'")

from pycinder.testing.scenes import Drifting, Scene  # noqa: E402
from benchmarks.warp_peer import Warp  # noqa: E402
from pycinder.focused.broad.broad_numpy import sweep_and_prune  # noqa: E402
from pycinder.testing import ground_truth, random_scene  # noqa: E402

from conftest import assert_matches_truth  # noqa: E402


def drifting_scene(n: int, seed: int, frames: int = 2) -> Drifting:
    """random_scene's bodies, moving a little every frame."""
    meshes, transforms = random_scene(n, seed)
    scene = Drifting(f"random-{n}", f"{n} random primitives", [m.faces for m in meshes],
                     [m.vertices for m in meshes], frames)
    scene.base = np.array(transforms)
    scene.drift = np.random.default_rng(seed).normal(scale=3.0, size=(n, 3))
    return scene


def exact_boxes(scene: Scene, k: int) -> tuple[np.ndarray, np.ndarray]:
    """World boxes of the vertices as the peer holds them (float32), mapped in float64."""
    verts, transforms = scene.frame(k)
    world = [np.asarray(v, np.float32).astype(np.float64) @ t[:3, :3].T + t[:3, 3]
             for v, t in zip(verts, transforms)]
    return np.array([w.min(axis=0) for w in world]), np.array([w.max(axis=0) for w in world])


@pytest.mark.parametrize("n, seed", [(60, 0), (300, 1)])
def test_pairs_match_exact_truth_and_candidates_match_the_numpy_sweep(n, seed):
    scene = drifting_scene(n, seed).cached()
    peer = Warp()
    peer.prepare(scene)
    for k in range(scene.frames):
        found = peer.step(scene, k)
        verts, transforms = scene.frame(k)
        truth = ground_truth(list(zip(verts, scene.faces)), transforms)
        score = assert_matches_truth(found, truth, context=f"{scene.name} frame {k}")
        assert score["overlaps"] > 0.5 * n  # the scene is busy enough to test something
        lo, hi, candidates = peer.candidates()
        exact_lo, exact_hi = exact_boxes(scene, k)
        scale = np.abs(exact_hi).max()
        assert (lo <= exact_lo + 1e-12 * scale).all() and (hi >= exact_hi - 1e-12 * scale).all()
        np.testing.assert_array_equal(candidates, sweep_and_prune(lo, hi))
        # Every colliding pair is a candidate; candidates are sorted unique pairs i < j.
        assert {tuple(p) for p in found.tolist()} <= {tuple(p) for p in candidates.tolist()}
        assert (candidates[:, 0] < candidates[:, 1]).all()


def test_broad_phases_and_launch_modes_agree_and_the_pair_list_grows():
    """All-pairs and sort-and-sweep, graph replay and one-by-one launches give the same pairs;
    a frame with more candidates than the pair list holds grows it and is run again."""
    scene = drifting_scene(60, 2, frames=3).cached()
    answers = []
    for options in ({}, {"broadphase": "all-pairs"}, {"graph": False}):
        peer = Warp(**options)
        peer.prepare(scene)
        peer._allocate(8)  # far fewer than the frame's candidates
        answers.append([peer.step(scene, k) for k in range(scene.frames)])
        assert peer.capacity > 8 and len(peer.candidates()[2]) > 8
    for other in answers[1:]:
        for a, b in zip(answers[0], other):
            np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="broadphase"):
        Warp(broadphase="octree")


class Inflating(Scene):
    """Two unit spheres 1.2 apart whose vertices grow by half at frame 1: apart, then crossing."""

    def __init__(self) -> None:
        ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
        super().__init__("inflating", "two spheres, growing", [ball.faces] * 2,
                         [ball.vertices] * 2, 2, deforming=True)
        self.transforms = np.tile(np.eye(4), (2, 1, 1))
        self.transforms[1, 0, 3] = 1.2

    def frame(self, k: int) -> tuple[list[np.ndarray], np.ndarray]:
        return [v * (1.0 + 0.5 * k) for v in self.rest], self.transforms


def test_deforming_bodies_are_refitted():
    scene = Inflating()
    peer = Warp()
    peer.prepare(scene)
    assert peer.step(scene, 0).tolist() == []
    assert peer.step(scene, 1).tolist() == [[0, 1]]
    assert peer.step(scene, 0).tolist() == []

"""CollisionManager against trimesh's FCL-backed CollisionManager on the same scenes."""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing import ground_truth, random_scene

fcl = pytest.importorskip("fcl")


def clear_scene(seed: int):
    """A random scene with no pair inside the tolerance band, so FCL and truth agree exactly."""
    for s in range(seed, seed + 50):
        meshes, transforms = random_scene(10, s, density=0.2)
        truth = ground_truth(meshes, transforms)
        if len(truth.ambiguous) == 0 and len(truth.overlap):
            return meshes, transforms, truth
    raise AssertionError("no clear scene")


@pytest.mark.parametrize("seed", [100, 200])
def test_internal_matches_fcl(seed):
    meshes, transforms, truth = clear_scene(seed)
    ours, theirs = pycinder.CollisionManager(), trimesh.collision.CollisionManager()
    for i, (m, t) in enumerate(zip(meshes, transforms)):
        ours.add_object(f"obj{i}", m, t)
        theirs.add_object(f"obj{i}", m, t)
    hit, names = ours.in_collision_internal(return_names=True)
    fhit, fnames = theirs.in_collision_internal(return_names=True)
    assert hit == fhit
    assert names == fnames
    assert ours.in_collision_internal() == fhit


def test_single_other_transform_and_remove():
    box = trimesh.creation.box((1, 1, 1))
    ball = trimesh.creation.icosphere(radius=0.3)
    ours, theirs = pycinder.CollisionManager(), trimesh.collision.CollisionManager()
    for m in (ours, theirs):
        m.add_object("box", box)
        m.add_object("ball", ball, trimesh.transformations.translation_matrix((3, 0, 0)))
    probe = trimesh.creation.icosphere(radius=0.25)
    at = trimesh.transformations.translation_matrix((0.6, 0, 0))
    assert ours.in_collision_single(probe, at, return_names=True) == \
        theirs.in_collision_single(probe, at, return_names=True) == (True, {"box"})
    assert ours.in_collision_internal() is False
    ours.set_transform("ball", trimesh.transformations.translation_matrix((0.5, 0.4, 0)))
    hit, names, data = ours.in_collision_internal(return_names=True, return_data=True)
    assert hit and names == {("ball", "box")}
    assert data and all(d.names == {"ball", "box"} for d in data)
    ours.remove_object("ball")
    assert ours.in_collision_internal() is False
    with pytest.raises(ValueError, match="not in collision manager"):
        ours.remove_object("ball")
    with pytest.raises(ValueError, match="not in collision manager"):
        ours.set_transform("nothing", np.eye(4))

    other = pycinder.CollisionManager()
    other.add_object("probe", probe, at)
    assert ours.in_collision_other(other, return_names=True) == (True, {("box", "probe")})

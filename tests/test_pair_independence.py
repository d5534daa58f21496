"""Other bodies never change a pair's answer: a pair is reported alone exactly when it is reported
inside larger scenes, in every mode, for solids, surfaces and meshes wound again; and a robot's
configuration gets the same pairs in every batch it is checked in.

Each scene holds pairs placed about first contact, from 2.5 tolerances deep to 3 apart (so that
many lie within the contract's band, where either answer keeps the contract and only the
pipeline's own arithmetic decides), each pair in a cell of its own, among clutter: bodies
scattered over the cells, overlapping the pairs' bodies, so that the pairs' tiles share rounds
and atlases with many others and are cut where bands end. The answers are compared with each
pair queried alone and inside random subsets of the scene.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.testing import first_contact, l_shape, random_rotation, world_mesh

T = 0.005
"""The scenes' tolerance (the clearance and hard-clash figures are 2 T)."""

MODES = {"default": {"tolerance": T}, "min_depth": {"min_depth": 2 * T},
         "clearance": {"clearance": 2 * T}}


def _shapes() -> list[trimesh.Trimesh]:
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.08)
    box = trimesh.creation.box((0.15, 0.1, 0.12))
    torus = trimesh.creation.torus(0.08, 0.025, major_sections=24, minor_sections=12)
    cup = trimesh.Trimesh(ball.vertices, ball.faces[30:], process=False)  # open: a surface
    rewound = trimesh.Trimesh(box.vertices, np.array(box.faces), process=False)
    rewound.faces[[1, 4, 7]] = rewound.faces[[1, 4, 7]][:, ::-1]  # closed, wound again
    return [ball, box, torus, cup, rewound, l_shape(0.2, 0.06, 0.1)]


def scene(seed: int, pairs: int = 18, clutter: int = 40):
    """Meshes and transforms: ``pairs`` pairs about first contact, from 2.5 T deep to 3 T apart
    (bodies ``2 k``, ``2 k + 1``)
    on a grid of cells, then ``clutter`` bodies over the cells."""
    rng = np.random.default_rng(seed)
    shapes = _shapes()
    meshes, transforms = [], []
    for k in range(pairs):
        a, b = shapes[rng.integers(len(shapes))], shapes[rng.integers(len(shapes))]
        ta = random_rotation(rng)
        ta[:3, 3] = (k % 6 * 0.5, k // 6 * 0.5, 0.0)
        tb = random_rotation(rng)
        tb[:3, 3] = ta[:3, 3]
        way = rng.normal(size=3)
        way /= np.linalg.norm(way)
        contact = first_contact(world_mesh(a, ta), world_mesh(b, tb), way)
        tb[:3, 3] += way * (contact + rng.uniform(-2.5 * T, 3.0 * T))
        meshes += [a, b]
        transforms += [ta, tb]
    for _ in range(clutter):
        m = random_rotation(rng)
        m[:3, 3] = rng.uniform((-0.2, -0.2, -0.15), (2.7, 1.2, 0.15))
        meshes.append(shapes[rng.integers(3)])
        transforms.append(m)
    return meshes, np.array(transforms)


@pytest.fixture(scope="module")
def scenes():
    return [scene(seed) for seed in (1, 2)]


@pytest.mark.filterwarnings("ignore::pycinder.MeshWarning")
@pytest.mark.parametrize("mode", list(MODES))
def test_a_pair_is_answered_alone_as_inside_larger_scenes(scenes, mode):
    detector = pycinder.Detector(**MODES[mode])
    rng = np.random.default_rng(7)
    compared = found = 0
    for meshes, transforms in scenes:
        n = len(meshes)
        whole = set(map(tuple, detector.find_collisions(meshes, transforms).pairs.tolist()))
        # Random subsets of the scene, each holding a few of the pairs and some clutter.
        subsets = [np.sort(rng.choice(n, size=n // 2, replace=False)) for _ in range(2)]
        answers = [(np.arange(n), whole)]
        for keep in subsets:
            got = detector.find_collisions([meshes[i] for i in keep], transforms[keep]).pairs
            answers.append((keep, {(int(keep[i]), int(keep[j])) for i, j in got.tolist()}))
        for k in range(18):
            pair = (2 * k, 2 * k + 1)
            alone = len(detector.find_collisions([meshes[i] for i in pair],
                                                 transforms[list(pair)]).pairs) > 0
            found += alone
            for keep, reported in answers:
                if pair[0] in keep and pair[1] in keep:
                    compared += 1
                    assert (pair in reported) == alone, (mode, k, "alone" if alone else "apart")
    assert compared >= 40 and 0 < found < 36  # both answers occur, in many comparisons


@pytest.mark.filterwarnings("ignore::pycinder.MeshWarning")
def test_a_configuration_gets_the_same_pairs_in_every_batch(monkeypatch):
    """The Panda near a box, on straight lines between random configurations (many pass
    through first contact): each configuration's pairs are the same checked alone, in batches
    of 7 and 64, and in one batch of all."""
    pytest.importorskip("yourdfpy")
    from pycinder.testing import robots as R
    from pycinder.robot import AllowedCollisionMatrix, Environment

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        panda = R.load("panda")
    panda.allowed = AllowedCollisionMatrix((a, b, "Adjacent") for a, b in panda.adjacent_links())
    box = np.eye(4)
    box[:3, 3] = (0.45, 0.0, 0.35)
    env = Environment([("box", trimesh.creation.box((0.3, 0.3, 0.3)), box)])
    rng = np.random.default_rng(5)
    limits = np.asarray(panda.limits)
    ends = rng.uniform(limits[:, 0], limits[:, 1], size=(2, 6, len(limits)))
    steps = np.linspace(0.0, 1.0, 24)[:, None, None]
    q = (ends[0][None] * (1 - steps) + ends[1][None] * steps).reshape(-1, len(limits))
    seen: dict[int, list[np.ndarray]] = {}  # per configuration, its poses in each check
    offset = [0]  # where the configurations of the current check start in q
    real = type(panda)._query

    def spy(self, poses, start, *args, **kwargs):
        for c in range(len(poses)):
            seen.setdefault(offset[0] + start + c, []).append(np.array(poses.rows[c]))
        return real(self, poses, start, *args, **kwargs)

    monkeypatch.setattr(type(panda), "_query", spy)
    whole = panda.check(q, environment=env, return_pairs=True, batch=len(q))[1]
    for size in (7, 64):
        assert panda.check(q, environment=env, return_pairs=True, batch=size)[1] == whole
    for c in range(0, len(q), 9):
        offset[0] = c
        assert panda.check(q[c:c + 1], environment=env, return_pairs=True)[1] == [whole[c]]
    colliding = sum(bool(p) for p in whole)
    assert 0 < colliding < len(q)
    # The answers agree because every check gave each configuration the very same poses, in
    # one batch of all, in batches of 7 and 64, and alone.
    for c, poses in seen.items():
        assert all(np.array_equal(poses[0], other) for other in poses[1:]), c
    assert all(len(seen[c]) == 4 for c in range(0, len(q), 9))

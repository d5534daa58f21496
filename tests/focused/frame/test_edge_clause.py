"""The contract's edge clause: an edge of one body lying 1.6 tolerances inside the other always
yields a record of that edge, whatever the size of the cluster that owns it.

Pass F5 tests edges cluster by cluster; a cluster of 64 faces owns about 90-130 edges, more than a
workgroup's threads, so every edge of clusters of every size is checked here against geometry
built by hand: bodies lying wholly inside a box with room to spare, every one of whose edges is
therefore inside it.
"""

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder.gpu.layout import CLUSTER_FACES, WORKGROUP
from pycinder.testing import random_rotation

T = 0.01


def _inside_a_box(inner: trimesh.Trimesh, seed: int):
    """``inner`` turned at random inside a box that clears it by 10 tolerances all round."""
    rot = random_rotation(np.random.default_rng(seed))
    world = inner.copy()
    world.apply_transform(rot)
    box = trimesh.creation.box(world.extents + 20 * T)
    box.apply_translation(world.bounds.mean(axis=0))
    return [box, inner], [np.eye(4), rot]


@pytest.mark.parametrize("name, mesh", [
    ("icosphere 4", trimesh.creation.icosphere(subdivisions=4, radius=0.5)),
    ("icosphere 5", trimesh.creation.icosphere(subdivisions=5, radius=0.5)),
    ("cylinder of 37 sections", trimesh.creation.cylinder(radius=0.3, height=1.0, sections=37)),
    ("torus", trimesh.creation.torus(major_radius=0.4, minor_radius=0.1, major_sections=41,
                                     minor_sections=13)),
    ("tetrahedron", trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]],
                                    [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])),
])
def test_every_edge_of_a_body_inside_another_yields_a_record(name, mesh):
    meshes, transforms = _inside_a_box(mesh, seed=len(mesh.faces))
    result = pycinder.Detector(tolerance=T, records="all").find_collisions(meshes, transforms)
    assert result.pairs.tolist() == [[0, 1]]
    rec = result.records
    inner_edges = rec["edge"][(rec["penetrating"] == 1) & (rec["edge"] >= 0)]
    # topology.edges of the inner body are trimesh's unique edges, in some order: compare sets of
    # vertex pairs.
    found = {tuple(sorted(e)) for e in result.edge_vertices()[(rec["penetrating"] == 1)
                                                             & (rec["edge"] >= 0)].tolist()}
    expected = {tuple(sorted(e)) for e in np.asarray(mesh.edges_unique).tolist()}
    assert len(np.unique(inner_edges)) == len(expected)
    assert found == expected, f"{name}: {len(expected - found)} of {len(expected)} edges unseen"


def test_clusters_own_more_edges_than_a_workgroup_has_threads():
    """The case above is the one that matters: clusters of CLUSTER_FACES faces own more edges
    than WORKGROUP threads."""
    from pycinder.scene import prepare_scene

    mesh = trimesh.creation.icosphere(subdivisions=4)
    topo = prepare_scene([mesh]).shapes[0].topology
    clusters = topo.clusters(np.asarray(mesh.vertices, np.float32))
    assert np.diff(clusters.face_start).max() == CLUSTER_FACES
    assert np.diff(clusters.edge_start).max() > WORKGROUP


@pytest.mark.parametrize("seed", range(4))
def test_an_edge_one_point_six_tolerances_inside_yields_its_record(seed):
    """A box turned 45 degrees so that one edge points down into a slab, 1.6 tolerances deep.
    The overlap is a right-angled wedge whose inscribed ball (radius 0.66 t) is below the ball
    clause's 0.71 t: the edge clause alone promises the record."""
    slab = trimesh.creation.box((4.0, 4.0, 1.0))
    slab.apply_translation((0, 0, -0.5))                          # top face at z = 0
    cube = trimesh.creation.box((0.5, 0.5, 0.5))
    rng = np.random.default_rng(seed)
    turn = trimesh.transformations.rotation_matrix(np.pi / 4, (1, 0, 0))
    spin = trimesh.transformations.rotation_matrix(rng.uniform(0, 2 * np.pi), (0, 0, 1))
    pose = spin @ turn
    low = (np.asarray(cube.vertices) @ pose[:3, :3].T)[:, 2]
    bottom = np.flatnonzero(np.isclose(low, low.min()))
    assert len(bottom) == 2                                        # one edge points down
    pose[:3, 3] = (rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), -low.min() - 1.6 * T)
    result = pycinder.Detector(tolerance=T, records="all").find_collisions([slab, cube],
                                                                         [np.eye(4), pose])
    assert result.pairs.tolist() == [[0, 1]]
    rec = result.records
    edges = result.edge_vertices()[(rec["penetrating"] == 1) & (rec["edge"] >= 0)]
    assert tuple(sorted(bottom)) in {tuple(sorted(e)) for e in edges.tolist()}

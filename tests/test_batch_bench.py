"""The robot behind ``pycinder bench batch``: its poses against pybullet's own forward
kinematics, and a short run of the benchmark scored against exact geometry."""

import numpy as np
import pytest

from pycinder.benchmarks import batch, robot

pybullet = pytest.importorskip("pybullet", reason="the test and bench extras bring pybullet")


@pytest.fixture(scope="module")
def panda():
    return robot.panda()


def test_panda_links_and_poses_match_pybullet(panda):
    """Every link frame of 5 random configurations, as pybullet computes it from the same URDF
    (its own parser and kinematics)."""
    import pybullet_data

    assert len(panda.bodies) == 11 and len(panda.actuated) == 8
    assert all(b.mesh.is_volume for b in panda.bodies)
    assert [b.repaired != "" for b in panda.bodies].count(True) == 1  # link6.obj is open
    q = panda.random_configurations(5, seed=3)
    links = panda.link_transforms(q)
    client = pybullet.connect(pybullet.DIRECT)
    try:
        arm = pybullet.loadURDF(f"{pybullet_data.getDataPath()}/franka_panda/panda.urdf",
                                useFixedBase=True, physicsClientId=client)
        joints = [pybullet.getJointInfo(arm, k, physicsClientId=client)
                  for k in range(pybullet.getNumJoints(arm, physicsClientId=client))]
        by_joint = {j[1].decode(): j[0] for j in joints}
        for c in range(len(q)):
            for k, name in enumerate(panda.actuated):
                pybullet.resetJointState(arm, by_joint[name], q[c, k], physicsClientId=client)
            pybullet.resetJointState(arm, by_joint["panda_finger_joint2"], q[c, -1],
                                     physicsClientId=client)  # the mimic joint
            for j in joints:
                state = pybullet.getLinkState(arm, j[0], computeForwardKinematics=True,
                                              physicsClientId=client)
                rot = np.reshape(pybullet.getMatrixFromQuaternion(state[5]), (3, 3))
                mine = links[j[12].decode()][c]
                np.testing.assert_allclose(mine[:3, 3], state[4], atol=1e-6)
                np.testing.assert_allclose(mine[:3, :3], rot, atol=1e-6)
    finally:
        pybullet.disconnect(client)
    with pytest.raises(ValueError, match="need 8 joint values"):
        panda.poses(np.zeros((1, 7)))


def test_short_benchmark_run_agrees_with_exact_geometry():
    r = batch.run_batch(60, batch_sizes=(1, 30), sweep=30, single=5, truth=4, workers=())
    assert r["pairs_per_configuration"] == 55 and r["ray"] == []
    assert r["batch_equals_single"] == [5, 5]
    assert [b["batch_size"] for b in r["pycinder-batch"]] == [1, 30]
    t = r["truth"]["pycinder"]
    assert t["must"] > 0 and t["found"] == t["must"] and t["false"] == 0
    scored = r["agreement"]["scored_pairs"]
    assert scored["must_only_fcl"] == 0 and scored["separate_only_pycinder"] == 0
    assert r["agreement"]["configurations_equal"] > 40
    text = "\n".join(batch.markdown(r))
    assert "| python-fcl (DynamicAABBTree manager) | 60 |" in text
    assert "link6.obj: open mesh replaced by its convex hull" in text

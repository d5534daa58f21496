"""The robot behind ``pycinder bench batch``: its poses against pybullet's own forward
kinematics, and a short run of the benchmark scored against exact geometry."""

import numpy as np
import pytest

from benchmarks import batch
from pycinder.testing import robots as robot

pybullet = pytest.importorskip("pybullet", reason="the test and bench extras bring pybullet")


pytest.importorskip("yourdfpy", reason="pycinder.robot needs yourdfpy (the robot extra)")


@pytest.fixture(scope="module")
def panda():
    return robot.load("panda")


def test_panda_links_and_poses_match_pybullet(panda):
    """Every link frame of 5 random configurations, as pybullet computes it from the same URDF
    (its own parser and kinematics)."""
    import pybullet_data

    assert len(panda.bodies) == 11 and len(panda.joint_names) == 8
    assert [b.mesh.is_volume for b in panda.bodies].count(False) == 1  # link6.obj is open
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
            for k, name in enumerate(panda.joint_names):
                pybullet.resetJointState(arm, by_joint[name], q[c, k], physicsClientId=client)
            pybullet.resetJointState(arm, by_joint["panda_finger_joint2"], q[c, -1],
                                     physicsClientId=client)  # the mimic joint
            for j in joints:
                state = pybullet.getLinkState(arm, j[0], computeForwardKinematics=True,
                                              physicsClientId=client)
                rot = np.reshape(pybullet.getMatrixFromQuaternion(state[5]), (3, 3))
                mine = links[c, panda.links.index(j[12].decode())]
                np.testing.assert_allclose(mine[:3, 3], state[4], atol=1e-6)
                np.testing.assert_allclose(mine[:3, :3], rot, atol=1e-6)
    finally:
        pybullet.disconnect(client)
    with pytest.raises(ValueError, match=r"\(C, 8\) joint values"):
        panda.poses(np.zeros((1, 7)))


def test_short_benchmark_run_agrees_with_exact_geometry():
    r = batch.run_batch(60, batch_sizes=(1, 30), sweep=30, single=5, truth=20, workers=(),
                        robots=(), check_sizes=(1, 8), matrix_samples=10)
    assert r["pairs_per_configuration"] == 55 and r["ray"] == [] and r["robots"] == []
    assert r["batch_equals_single"] == [5, 5]
    assert [b["batch_size"] for b in r["pycinder-batch"]] == [1, 30]
    scored = r["agreement"]["scored"]
    assert scored["missed"] == 0 and scored["false"] == 0
    assert r["agreement"]["configurations_equal"] > 40
    text = "\n".join(batch.markdown(r))
    assert "| python-fcl (DynamicAABBTree manager) | 60 |" in text
    assert "open, tested as surfaces: link6.obj" in text
    sweep = r["check_sweep"]
    assert [row["batch_size"] for row in sweep["sizes"]] == [1, 8]
    assert sweep["matrix_samples"] == 10 and 0 < sweep["pairs"] < 121  # the matrix pruned
    assert all(row["per_s"] > 0 and row["host_cpu_ms"] > 0 for row in sweep["sizes"])
    assert sweep["python-fcl"]["per_s"] > 0 and sweep["trimesh"]["per_s"] > 0
    faster = [row["batch_size"] for row in sweep["sizes"]
              if row["per_s"] > sweep["python-fcl"]["per_s"]]
    assert sweep["overtakes"] == (faster[0] if faster else None)
    assert "configurations per second against the batch size" in text


def test_robot_rows_hold_trimesh_beside_python_fcl():
    """The four-robot comparison (one robot, a few configurations here) times trimesh's
    CollisionManager on the same configurations, and its answers are python-fcl's (both are FCL
    underneath, kept by the same matrix)."""
    rows = batch.run_robots(6, robots=("xarm",), samples=10)
    row = rows[0]
    assert row["trimesh"]["per_s"] > 0 and row["trimesh"]["equal_to_fcl"] == 6
    assert row["scored"]["missed"] == 0 and row["scored"]["false"] == 0
    text = "\n".join(batch.robots_markdown(rows))
    assert "| trimesh / s |" in text and " (6) |" in text


def test_front_sweep_times_both_paths_and_restores_the_threshold(monkeypatch):
    """run_front_sweep times each size through the host's poses and box test and through
    passes K1 and K2: K1 and K2 ran on every query of the GPU's path and on none of the host's;
    it leaves GPU_FRONT_FROM as it found it, also when a check fails."""
    from pycinder.robot import robot as robot_module

    paths = []  # (configurations, whether K1 and K2 ran) of every query
    real = robot_module.Robot._gpu_batch

    def noted(self, qs, *args):
        front = real(self, qs, *args)
        paths.append((len(qs), front is not None))
        return front

    monkeypatch.setattr(robot_module.Robot, "_gpu_batch", noted)
    before = robot_module.GPU_FRONT_FROM
    r = batch.run_front_sweep("xarm", (4,), rounds=1, samples=0)
    assert robot_module.GPU_FRONT_FROM == before and r["robot"] == "xarm"
    (row,) = r["sizes"]
    assert row["batch_size"] == 4 and row["configurations"] == 256
    assert row["host"]["k1k2"] == 0 and row["gpu"]["k1k2"] == 1
    for path in ("host", "gpu"):
        assert row[path]["per_s"] > 0 and row[path]["host_cpu_us"] > 0
    # 2 checks a path (untimed, timed) of 1 and 64 queries of 4 configurations
    assert sorted(set(paths)) == [(4, False), (4, True)]
    assert paths.count((4, False)) == paths.count((4, True)) == 65
    lines = batch.front_sweep_markdown([r], "here")
    assert len(lines) == 3 and lines[2].startswith("| xarm | 4 | ")
    assert "K1/K2 in" not in lines[2]
    row["gpu"]["k1k2"] = 0.5
    assert "K1/K2 in 50% of queries" in batch.front_sweep_markdown([r], "here")[2]

    def fails(self, *args, **kwargs):
        assert robot_module.GPU_FRONT_FROM != before
        raise RuntimeError("a check that fails")

    monkeypatch.setattr(robot_module.Robot, "check", fails)
    with pytest.raises(RuntimeError, match="a check that fails"):
        batch.run_front_sweep("xarm", (4,), rounds=1, samples=0)
    assert robot_module.GPU_FRONT_FROM == before
    with pytest.raises(ValueError, match="rounds at least 1"):
        batch.run_front_sweep("xarm", (4,), rounds=0, samples=0)


def test_paced_checks_time_each_cap_and_restore_it():
    """run_paced checks the same configurations paced under each cap of bodies a query and
    restores GPU_BODIES_PER_QUERY; on a CPU adapter, which keeps its own cap, both caps make
    the same queries."""
    from pycinder.robot import robot as robot_module

    before = robot_module.GPU_BODIES_PER_QUERY
    rows = batch.run_paced("xarm", 100, (12_000, 200_000), rounds=1, samples=0)
    assert robot_module.GPU_BODIES_PER_QUERY == before
    assert [r["cap"] for r in rows] == [12_000, 200_000]
    for r in rows:
        assert r["per_s"] > 0 and r["host_cpu_us"] > 0 and r["largest"] >= 8
        assert r["queries"] >= 2  # paced: 8 configurations first
    from pycinder.gpu.device import get_gpu

    if get_gpu().cpu_adapter:
        assert rows[0]["queries"] == rows[1]["queries"]

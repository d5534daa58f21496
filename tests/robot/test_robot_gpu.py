"""Robot checks on the GPU: forward kinematics (pass K1) against yourdfpy's, the pair list culled
by world boxes (pass K2) against float64 boxes of the exact vertices, and the checks' verdicts
against the host's path (float64 poses, the host's box test) and exact geometry."""

import warnings

import numpy as np
import pytest
import trimesh

pytest.importorskip("yourdfpy", reason="pycinder.robot needs yourdfpy (the robot extra)")
pytest.importorskip("pybullet_data", reason="the robots come from pybullet_data (pybullet)")
pytest.importorskip("fcl", reason="differences are scored with python-fcl")

import yourdfpy  # noqa: E402

import pycinder  # noqa: E402

from pycinder.testing import robots as R  # noqa: E402
from pycinder.focused.broad.broad_numpy import PairList  # noqa: E402
from pycinder.robot import Robot  # noqa: E402
from pycinder.robot import robot as robot_module  # noqa: E402
from pycinder.robot.k2_pair_cull import GpuPairCull  # noqa: E402
from pycinder.robot.k1_kinematics import GpuKinematics  # noqa: E402

from robot_helpers import adjacent_only, load_robots  # noqa: E402


@pytest.fixture(autouse=True)
def _quiet(monkeypatch):
    """Quiet; and every batch of a check starts on the GPU, however small."""
    monkeypatch.setattr(robot_module, "GPU_FRONT_FROM", 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # open meshes, yourdfpy's notes on table.urdf
        yield


@pytest.fixture(scope="module")
def robots():
    return load_robots()


def vertices_of(robot: Robot) -> list[np.ndarray]:
    """(V, 4) homogeneous vertices of each body (collision bodies, then attached objects)."""
    meshes = [b.mesh for b in robot.bodies] + [robot._attached[n].body.mesh
                                               for n in robot.attached]
    return [np.c_[m.vertices, np.ones(len(m.vertices))] for m in meshes]


@pytest.mark.parametrize("name", list(R.ROBOTS))
def test_kinematics_match_yourdfpy(robots, name):
    """Every body's pose on the GPU against yourdfpy's link transform times the body's
    origin, within 1e-6 of the robot's size (rotations within 1e-6), at random configurations
    and at the joint limits (the Panda's fingers: a prismatic joint and its mimic)."""
    robot = robots[name]
    urdf = yourdfpy.URDF.load(str(R.data_path() / R.ROBOTS[name]), load_meshes=False,
                              load_collision_meshes=False)
    k1 = GpuKinematics(robot)
    q = np.concatenate([robot.random_configurations(24, seed=4), robot.limits.T])
    poses = k1.read(q)
    assert poses.shape == (len(q), len(robot.bodies), 4, 4) and poses.dtype == np.float64
    reach = max(np.abs(j.origin[:3, 3]).sum() for j in robot.joints) * len(robot.joints)
    worst = 0.0
    for c in range(len(q)):
        urdf.update_cfg(dict(zip(robot.joint_names, q[c])))
        for b, body in enumerate(robot.bodies):
            want = urdf.get_transform(body.link, robot.root) @ body.origin
            np.testing.assert_allclose(poses[c, b, :3, :3], want[:3, :3], rtol=0, atol=1e-6)
            worst = max(worst, np.abs(poses[c, b, :3, 3] - want[:3, 3]).max())
            np.testing.assert_array_equal(poses[c, b, 3], [0, 0, 0, 1])
    assert worst <= 1e-6 * max(reach, 1.0), worst
    assert worst > 0  # single precision: the test would show a float64 path too


@pytest.mark.parametrize("name", list(R.ROBOTS))
def test_kinematics_error_estimate_holds_every_vertex(robots, name):
    """No vertex of any body lies farther from its float64 place than half of the estimate the
    checks rely on (measured: about a tenth)."""
    robot = robots[name]
    k1 = GpuKinematics(robot)
    q = robot.random_configurations(64, seed=9)
    gpu, host = k1.read(q), robot.poses(q)
    estimate = k1.error_estimate()
    assert estimate.shape == (len(robot.bodies),) and (estimate > 0).all()
    for b, v in enumerate(vertices_of(robot)):
        moved = np.einsum("cij,vj->cvi", gpu[:, b, :3] - host[:, b, :3], v)
        assert np.abs(moved).max() <= 0.5 * estimate[b], (robot.bodies[b].name,
                                                          np.abs(moved).max(), estimate[b])


def test_kinematics_of_attached_objects_and_empty_batches(robots):
    panda = robots["panda"]
    held = np.eye(4)
    held[2, 3] = 0.1
    panda.attach("box", trimesh.creation.box((0.05, 0.05, 0.12)), "panda_hand", held)
    try:
        k1 = GpuKinematics(panda)
        q = panda.random_configurations(5, seed=2)
        poses = k1.read(q)
        assert poses.shape == (5, len(panda.bodies) + 1, 4, 4)
        np.testing.assert_allclose(poses, panda.poses(q), rtol=0, atol=2e-6)
        assert k1.read(q[:0]).shape == (0, len(panda.bodies) + 1, 4, 4)
    finally:
        panda.detach("box")


def float64_boxes(robot: Robot, bodies: list, used: np.ndarray, poses: np.ndarray,
                  vertices: bool) -> tuple[np.ndarray, np.ndarray]:
    """(C, U, 3) world boxes of the used bodies in float64: of their transformed vertices
    (``vertices``), or of their body-space boxes placed as pass K2 places them."""
    lo = np.empty((len(poses), len(used), 3))
    hi = np.empty_like(lo)
    for u, i in enumerate(used):
        mesh = bodies[i].mesh
        if vertices:
            v = np.c_[mesh.vertices, np.ones(len(mesh.vertices))]
            w = np.einsum("cij,vj->cvi", poses[:, i, :3], v)
            lo[:, u], hi[:, u] = w.min(axis=1), w.max(axis=1)
        else:
            b = np.asarray(mesh.bounds)
            centre = np.einsum("cij,j->ci", poses[:, i, :3, :3], 0.5 * (b[0] + b[1]))
            centre += poses[:, i, :3, 3]
            half = np.einsum("cij,j->ci", np.abs(poses[:, i, :3, :3]), 0.5 * (b[1] - b[0]))
            lo[:, u], hi[:, u] = centre - half, centre + half
    return lo, hi


def overlapping(lo: np.ndarray, hi: np.ndarray, pairs: np.ndarray, grow: float = 0.0
                ) -> set[tuple[int, int, int]]:
    a, b = pairs[:, 0], pairs[:, 1]
    meet = ((lo[:, a] <= hi[:, b] + 2 * grow) & (lo[:, b] <= hi[:, a] + 2 * grow)).all(axis=2)
    c, p = np.nonzero(meet)
    return {(int(x), int(pairs[y, 0]), int(pairs[y, 1])) for x, y in zip(c, p)}


@pytest.mark.parametrize("name", ["panda", "a1"])
@pytest.mark.parametrize("grow", [0.0, 0.02])
def test_cull_keeps_every_overlapping_pair(robots, name, grow):
    """Pass K2 keeps every checked pair whose bodies' exact vertices (float64 poses) have
    boxes within ``grow`` of each other, and only pairs whose placed body-space boxes are
    within ``grow`` plus a hair (so the cull is not a pass-through)."""
    robot, env = robots[name], R.environment(name)
    robot.allowed = adjacent_only(robot)
    plan, bodies = robot._plan(env, True)
    front = robot._gpu_front(plan, bodies, grow or None)
    assert isinstance(front, GpuPairCull)
    q = robot.random_configurations(96, seed=12)
    rows, boxes, survivors = front.run(q, grow)
    poses = robot._check_poses(q, env)  # float64, the host's
    assert rows.shape == (len(q), len(robot.bodies), 3, 4) and rows.dtype == np.float32
    np.testing.assert_allclose(rows, poses[:, :len(robot.bodies), :3], rtol=0, atol=2e-6)
    # K1's boxes hold every vertex placed by K1's own poses, and no more than the placed
    # body-space box does (within a hair).
    assert boxes.shape == (len(q), len(robot.bodies), 2, 4)
    placed = rows.astype(np.float64)
    for b, body in enumerate(robot.bodies):
        v = np.c_[body.mesh.vertices, np.ones(len(body.mesh.vertices))]
        w = np.einsum("cij,vj->cvi", placed[:, b], v)
        assert (boxes[:, b, 0, None, :3] <= w).all() and (w <= boxes[:, b, 1, None, :3]).all()
    lo, hi = float64_boxes(robot, bodies, np.arange(len(robot.bodies)), poses, False)
    assert np.abs(boxes[..., 0, :3] - lo).max() < 1e-5
    assert np.abs(boxes[..., 1, :3] - hi).max() < 1e-5
    kept = {tuple(map(int, s)) for s in survivors}
    assert len(kept) == len(survivors)
    assert np.array_equal(survivors, survivors[np.lexsort((survivors[:, 2], survivors[:, 1],
                                                           survivors[:, 0]))])
    exact = overlapping(*float64_boxes(robot, bodies, plan.used, poses, True), plan.pairs, grow)
    loose = overlapping(*float64_boxes(robot, bodies, plan.used, poses, False), plan.pairs,
                        grow + 1e-4)
    assert exact <= kept <= loose
    assert len(kept) < 0.5 * len(q) * len(plan.pairs)


def test_culled_pair_list_tests_no_box_but_keeps_its_contract():
    lo, hi = np.zeros((3, 3)), np.zeros((3, 3))
    hi[:, 0] = 1
    lo[2] += 5
    hi[2] += 5
    pairs = np.array([[0, 1], [0, 2], [1, 2]])
    assert PairList(pairs).meeting(lo, hi).tolist() == [[0, 1]]
    assert PairList(pairs, culled=True).meeting(lo, hi).tolist() == pairs.tolist()
    with pytest.raises(ValueError, match="sorted"):
        PairList(pairs[::-1], culled=True).meeting(lo, hi)
    with pytest.raises(ValueError, match="names box 3"):
        PairList(np.array([[0, 3]]), culled=True).meeting(lo, hi)


def host_path(robot, monkeypatch):
    monkeypatch.setattr(type(robot), "_gpu_front", lambda self, plan, bodies, clearance: None)


@pytest.mark.parametrize("name", list(R.ROBOTS))
def test_verdicts_equal_the_host_path(robots, name, monkeypatch):
    """The GPU's kinematics and cull against the host's float64 poses and box test, on random
    configurations with the environment, self-collision and an attached object (the Panda):
    the same verdicts and pairs, or differences in the tolerance band (scored exactly)."""
    robot, env = robots[name], R.environment(name)
    robot.allowed = adjacent_only(robot)
    if name == "panda":
        held = np.eye(4)
        held[2, 3] = 0.1
        robot.attach("box", trimesh.creation.box((0.05, 0.05, 0.12)), "panda_hand", held,
                     touch_links=["panda_leftfinger", "panda_rightfinger"])
    try:
        q = robot.random_configurations(48 if name == "kuka" else 96, seed=21)
        plan, bodies = robot._plan(env, True)
        assert robot._gpu_front(plan, bodies, None) is not None
        gpu, gpu_pairs = robot.check(q, environment=env, return_pairs=True)
        with monkeypatch.context() as m:
            host_path(robot, m)
            host, host_pairs = robot.check(q, environment=env, return_pairs=True)
        assert gpu.any()
        s = R.score(robot, env, robot._check_poses(q, env), [set(p) for p in gpu_pairs],
                    [set(p) for p in host_pairs])
        assert s["missed"] == 0 and s["false"] == 0, s["examples"]
        assert s["differing"] == s["band"]
        assert sum(a == b for a, b in zip(gpu_pairs, host_pairs)) >= 0.97 * len(q)
    finally:
        if name == "panda":
            robot.detach("box")


def test_padded_checks_equal_the_host_path(robots, monkeypatch):
    """Padding grows K2's boxes by the clearance: pairs within the padding are not culled."""
    panda, env = robots["panda"], R.environment("panda")
    panda.allowed = adjacent_only(panda)
    q = panda.random_configurations(48, seed=5)
    gpu = panda.check(q, environment=env, padding=0.03, self_collision=False,
                      return_pairs=True)
    with monkeypatch.context() as m:
        host_path(panda, m)
        host = panda.check(q, environment=env, padding=0.03, self_collision=False,
                           return_pairs=True)
    assert gpu[0].tolist() == host[0].tolist() and gpu[1] == host[1]
    assert gpu[0].sum() > panda.check(q, environment=env, self_collision=False).sum()


def test_small_batches_take_the_host_path(robots, monkeypatch):
    """A batch of fewer than GPU_FRONT_FROM configurations computes its poses on the host."""
    panda, env = robots["panda"], R.environment("panda")
    monkeypatch.setattr(robot_module, "GPU_FRONT_FROM", 10)
    runs = []
    real = GpuPairCull.run
    monkeypatch.setattr(GpuPairCull, "run", lambda self, *a: runs.append(len(a[0])) or
                        real(self, *a))
    q = panda.random_configurations(13, seed=1)
    panda.check(q, environment=env, batch=9)  # batches of 9 and 4
    assert runs == []
    panda.check(q, environment=env, batch=13)
    assert runs == [13]


def test_fine_tolerances_take_the_host_path(robots):
    """Where K1's error estimates are more than a sixteenth of a pair's tolerance (the
    robot's, the detector's, or a padded check's quarter of its clearance), a check takes the
    host's float64 poses; so does a batch whose prismatic joints leave their limits."""
    panda = robots["panda"]
    plan, bodies = panda._plan(None, True)
    assert panda._gpu_front(plan, bodies, None) is not None
    assert panda._gpu_front(plan, bodies, 0.01) is not None
    assert panda._gpu_front(plan, bodies, 1e-5) is None  # tested within 2.5 micrometres
    panda.tolerance = 1e-6
    try:
        assert panda._gpu_front(plan, bodies, None) is None
    finally:
        panda.tolerance = None
    detector = panda._detector
    panda._detector = pycinder.Detector(records="none", broad_phase="numpy", tolerance=2e-6)
    try:
        assert panda._gpu_front(plan, bodies, None) is None
    finally:
        panda._detector = detector
    k1 = panda._gpu_front(plan, bodies, None).kinematics
    q = panda.random_configurations(4, seed=1)
    assert k1.reaches(q)
    q[2, -1] = 0.5  # the finger slides past its limit (0.04)
    assert not k1.reaches(q)


def test_checks_with_nothing_to_check_or_a_moved_environment(robots):
    """A check with no pair to test answers (no pass is made); an environment of the same
    meshes at new places is culled at its new places."""
    panda = robots["panda"]
    panda.allowed = adjacent_only(panda)
    q = panda.random_configurations(70, seed=2)
    assert not panda.check(q, self_collision=False).any()
    box = trimesh.creation.box((0.3, 0.3, 0.3))
    far, near = np.eye(4), np.eye(4)
    far[:3, 3] = (5.0, 5.0, 5.0)
    near[:3, 3] = (0.0, 0.0, 0.2)  # around the base
    away = panda.check(q, environment=R.Environment([("box", box, far)]),
                       self_collision=False)
    around = panda.check(q, environment=R.Environment([("box", box, near)]),
                         self_collision=False)
    assert not away.any() and around.all()


def test_kinematics_follow_objects_attached_while_matrices_are_computed(robots):
    """compute_allowed_collisions swaps the attached objects out and back: the next check's
    kinematics hold them again."""
    panda = robots["panda"]
    panda.attach("box", trimesh.creation.box((0.05, 0.05, 0.12)), "panda_hand")
    try:
        panda._kinematics = None
        panda.compute_allowed_collisions(samples=2, always_samples=2)
        q = panda.random_configurations(70, seed=3)
        panda.check(q)  # a batch of 70 on the GPU, with the box
        assert len(panda._kinematics.error_estimate()) == len(panda.bodies) + 1
    finally:
        panda.detach("box")
        panda.allowed = adjacent_only(panda)


def test_large_dispatches_cover_every_configuration(robots, monkeypatch):
    """Dispatches laid out in rows of ROW workgroups (here 2, so that a batch of 300
    configurations takes a grid) reach every configuration and word of K1 and K2."""
    from pycinder.gpu import bindings
    from pycinder.robot import k1_kinematics, k2_pair_cull

    panda, env = robots["panda"], R.environment("panda")
    panda.allowed = adjacent_only(panda)
    plan, bodies = panda._plan(env, True)
    q = panda.random_configurations(300, seed=6)
    rows, boxes, survivors = panda._gpu_front(plan, bodies, None).run(q)
    for module in (bindings, k2_pair_cull, k1_kinematics):
        monkeypatch.setattr(module, "ROW", 2)
    panda._forget_fronts()
    again = panda._gpu_front(plan, bodies, None).run(q)
    panda._forget_fronts()  # not kept for other tests
    assert np.array_equal(again[0], rows) and np.array_equal(again[2], survivors)
    assert len(survivors) > 300


def test_a_batch_the_device_refuses_is_split_on_the_gpu_path(robots, monkeypatch):
    """A batch whose query the device refuses is checked in halves, each half's poses and cull
    made on the GPU again, with the answers of one query."""
    from pycinder.errors import GpuMemoryError

    panda, env = robots["panda"], R.environment("panda")
    panda.allowed = adjacent_only(panda)
    q = panda.random_configurations(12, seed=21)
    whole = panda.check(q, environment=env, return_pairs=True, batch=12)
    real, runs = type(panda.detector)._find_within, []
    culls = []
    real_run = GpuPairCull.run
    monkeypatch.setattr(GpuPairCull, "run", lambda self, *a: culls.append(len(a[0])) or
                        real_run(self, *a))

    def refuse_large(det, scene, within, tolerance):
        runs.append(len(np.unique(scene.names.config)))
        if runs[-1] > 6:
            raise GpuMemoryError("too large for this test's device")
        return real(det, scene, within, tolerance)

    monkeypatch.setattr(type(panda.detector), "_find_within", refuse_large)
    split = panda.check(q, environment=env, return_pairs=True, batch=12)
    assert culls == [12, 6, 6] and runs[0] == 12 and len(runs) == 3
    assert split[0].tolist() == whole[0].tolist() and split[1] == whole[1]


def test_environment_and_attached_transforms_are_checked_when_given(robots):
    """A check may take an environment body's or an attached object's transform as it is: a
    singular, non-affine or non-finite one is refused when given, naming the body."""
    panda = robots["panda"]
    flat = np.diag([1.0, 1.0, 0.0, 1.0])
    skewed = np.eye(4)
    skewed[3, 0] = 0.5
    box = trimesh.creation.box((0.1, 0.1, 0.1))
    with pytest.raises(ValueError, match="environment body 'wall': transform is singular"):
        R.Environment([("wall", box, flat)])
    with pytest.raises(ValueError, match="environment body 'wall': transform is not affine"):
        R.Environment([("wall", box, skewed)])
    with pytest.raises(ValueError, match="attached 'cup': transform contains NaN"):
        panda.attach("cup", box, "panda_hand", np.full((4, 4), np.nan))
    with pytest.raises(ValueError, match=r"attached 'cup': transform must be a \(4, 4\)"):
        panda.attach("cup", box, "panda_hand", np.eye(3))
    assert "cup" not in panda.attached

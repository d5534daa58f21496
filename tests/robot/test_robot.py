"""pycinder.robot: URDF robots from pybullet_data, the allowed-collision matrix, and checks
against python-fcl's exact answers, disagreements scored by exact geometry."""

import warnings

import numpy as np
import pytest
import trimesh

pytest.importorskip("yourdfpy", reason="pycinder.robot needs yourdfpy (the robot extra)")
pytest.importorskip("pybullet_data", reason="the robots come from pybullet_data (pybullet)")
pytest.importorskip("fcl", reason="answers are compared with python-fcl's")

from pycinder.testing import robots as R  # noqa: E402
from pycinder.robot import AllowedCollisionMatrix, Environment, Robot, matrix_from_samples

from robot_helpers import TABLE_PLACE, adjacent_only, load_robots, write_panda_manifest

CONFIGURATIONS = {"panda": 100, "kuka": 25, "xarm": 100, "a1": 100}
"""Random configurations per robot here (the benchmark runs 1,000; the KUKA's open meshes of
1,100 to 3,000 triangles are tested as surfaces, the slowest on lavapipe)."""

PANDA_ADJACENT = sorted([
    ("panda_link0", "panda_link1"), ("panda_link1", "panda_link2"),
    ("panda_link2", "panda_link3"), ("panda_link3", "panda_link4"),
    ("panda_link4", "panda_link5"), ("panda_link5", "panda_link6"),
    ("panda_link6", "panda_link7"), ("panda_hand", "panda_link7"),  # through panda_link8
    ("panda_hand", "panda_leftfinger"), ("panda_hand", "panda_rightfinger")])
"""The Panda's adjacent links by hand: its chain, the hand joined to link7 through link8
(which has no collision geometry), and the fingers on the hand."""


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # open meshes, yourdfpy's notes on table.urdf
        yield


@pytest.fixture(scope="module")
def robots():
    return load_robots()


def test_robots_load_with_open_meshes_as_they_are(robots):
    yourdfpy = pytest.importorskip("yourdfpy")
    panda = robots["panda"]
    assert panda.dof == 8 and len(panda.bodies) == 11  # the second finger mimics the first
    by_link = {b.link: b for b in panda.bodies}
    assert not by_link["panda_link6"].mesh.is_volume  # open: kept, tested as a surface
    assert len(by_link["panda_link6"].mesh.faces) == 1308
    assert {b.source for b in robots["a1"].bodies} == {"box", "cylinder", "sphere"}
    assert (robots["kuka"].dof, robots["xarm"].dof, robots["a1"].dof) == (7, 6, 12)
    for name, robot in robots.items():
        u = yourdfpy.URDF.load(str(R.data_path() / R.ROBOTS[name]), load_meshes=False,
                               load_collision_meshes=False)
        q = robot.random_configurations(3, seed=1)
        world = robot.link_transforms(q)
        assert world.shape == (3, len(robot.links), 4, 4)
        for c in range(3):
            u.update_cfg(dict(zip(robot.joint_names, q[c])))
            for k, link in enumerate(robot.links):
                np.testing.assert_allclose(world[c, k], u.get_transform(link, robot.root),
                                           atol=1e-12, err_msg=f"{name} {link}")
        poses = robot.poses(q)
        assert poses.shape == (3, len(robot.bodies), 4, 4)


def test_errors_name_the_link_and_the_file(tmp_path):
    urdf = tmp_path / "arm.urdf"
    urdf.write_text("""<robot name="arm">
      <link name="base"><collision><geometry><mesh filename="package://arm/gone.stl"/>
      </geometry></collision></link></robot>""")
    with pytest.raises(FileNotFoundError, match=r"arm\.urdf: link 'base': mesh .*gone\.stl"):
        Robot.from_urdf(urdf)
    urdf.write_text("""<robot name="arm"><link name="base"/><link name="tip">
      <collision><geometry><box size="1 -1 1"/></geometry></collision></link>
      <joint name="j" type="revolute"><parent link="base"/><child link="tip"/>
      <limit lower="0" upper="1"/></joint></robot>""")
    with pytest.raises(ValueError, match=r"arm\.urdf: link 'tip': box size"):
        Robot.from_urdf(urdf)
    urdf.write_text("""<robot name="arm"><link name="base"/><link name="tip"/>
      <joint name="j" type="floating"><parent link="base"/><child link="tip"/></joint>
      </robot>""")
    with pytest.raises(ValueError, match=r"arm\.urdf: joint 'j' is 'floating'"):
        Robot.from_urdf(urdf)


def test_options_checked(robots):
    panda = robots["panda"]
    with pytest.raises(ValueError, match="padding must be non-negative"):
        panda.check(np.zeros((1, 8)), padding=-0.01)
    with pytest.raises(ValueError, match="neither links nor attached objects"):
        panda.check(np.zeros((1, 8)), padding={"panda_link99": 0.01})
    with pytest.raises(ValueError, match=r"\(C, 8\) joint values"):
        panda.check(np.zeros((2, 7)))
    with pytest.raises(ValueError, match="batch must be a positive"):
        panda.check(np.zeros((1, 8)), batch=0)
    with pytest.raises(ValueError, match="no such link"):
        panda.attach("cup", trimesh.creation.box((0.1, 0.1, 0.1)), "panda_link99")


def test_moveit_rules_on_the_panda_and_srdf_round_trip(robots, tmp_path):
    """Adjacent links by hand; Default, Always and Never from pycinder's checks equal those of
    python-fcl's exact checks on the same 150 samples, except for pairs whose only differing
    answers lie inside the tolerance band; the matrix written as SRDF reads back equal and
    makes a robot honour it."""
    panda = robots["panda"]
    assert panda.adjacent_links() == PANDA_ADJACENT
    samples = 150
    acm = panda.compute_allowed_collisions(samples, seed=3)
    assert sorted((a, b) for a, b, _ in acm.pairs("Adjacent")) == PANDA_ADJACENT
    assert acm.pairs("Never") and len(acm) < 55

    # The same rules from python-fcl's answers on the same configurations.
    q = panda.random_configurations(max(samples, 100), seed=3)
    default = panda.default_configuration()[None]
    everything = AllowedCollisionMatrix()
    fcl = R.FclRobot(Robot(panda.name, panda.root, panda.links, panda.joints, panda.bodies,
                           panda.joint_names, panda.limits, everything))
    theirs = fcl.check(q)
    saved = panda.allowed
    panda.allowed = everything
    try:
        _, ours = panda.check(q, return_pairs=True)
        _, ours_default = panda.check(default, return_pairs=True)
    finally:
        panda.allowed = saved
    links = sorted({b.link for b in panda.bodies})
    fcl_acm = matrix_from_samples(PANDA_ADJACENT, fcl.check(default)[0], theirs, links,
                                  samples=samples)
    ours_acm = matrix_from_samples(PANDA_ADJACENT, ours_default[0], ours, links,
                                   samples=samples)
    assert ours_acm == acm  # compute_allowed_collisions is these rules on these samples
    s = R.score(panda, None, fcl.poses(q), [set(p) for p in ours], theirs)
    assert s["missed"] == 0 and s["false"] == 0, s["examples"]
    differ = {(a, b) for a, b, r in acm.pairs() if fcl_acm.reason(a, b) != r} | \
        {(a, b) for a, b, r in fcl_acm.pairs() if acm.reason(a, b) != r}
    banded = {p for c in range(len(q)) for p in set(ours[c]) ^ theirs[c]}
    assert differ <= banded, differ - banded

    path = tmp_path / "panda.srdf"
    panda.allowed = acm
    try:
        panda.write_srdf(path)
    finally:
        panda.allowed = saved
    assert AllowedCollisionMatrix.from_srdf(path) == acm
    text = path.read_text()
    assert '<disable_collisions link1="panda_hand" link2="panda_leftfinger" reason="Adjacent"' \
        in text
    again = Robot.from_urdf(R.data_path() / R.ROBOTS["panda"], srdf=path)
    assert again.allowed == acm
    assert len(again.checked_pairs()) == 55 - len(acm)
    bad = tmp_path / "bad.srdf"
    bad.write_text('<robot name="x"><disable_collisions link1="panda_link1" link2="elbow" '
                   'reason="User"/></robot>')
    with pytest.raises(ValueError, match=r"bad\.srdf: .*'elbow'"):
        Robot.from_urdf(R.data_path() / R.ROBOTS["panda"], srdf=bad)


@pytest.mark.parametrize("name", list(R.ROBOTS))
def test_agrees_with_python_fcl(robots, name):
    """Random configurations with the environment, adjacent links allowed: every pair on which
    pycinder and python-fcl differ is scored by exact geometry; none is a miss (2 t deep) or a
    false report (t apart)."""
    robot = robots[name]
    robot.allowed = adjacent_only(robot)
    env = R.environment(name)
    q = robot.random_configurations(CONFIGURATIONS[name], seed=11)
    collides, ours = robot.check(q, environment=env, return_pairs=True)
    assert collides.tolist() == [bool(p) for p in ours]
    fcl = R.FclRobot(robot, env)
    theirs = fcl.check(q)
    s = R.score(robot, env, fcl.poses(q), [set(p) for p in ours], theirs)
    assert s["missed"] == 0 and s["false"] == 0, s["examples"]
    assert collides.any() and not collides.all() or name == "a1"
    same = sum(set(a) == b for a, b in zip(ours, theirs))
    assert same >= 0.9 * len(q), (same, s)
    # One configuration alone answers as in the batch.
    c = int(np.flatnonzero(collides)[0])
    assert robot.in_collision(q[c], environment=env)


def test_environment_only_and_self_only(robots):
    panda = robots["panda"]
    panda.allowed = adjacent_only(panda)
    env = R.environment("panda")
    q = panda.random_configurations(40, seed=5)
    _, both = panda.check(q, environment=env, return_pairs=True)
    _, env_only = panda.check(q, environment=env, self_collision=False, return_pairs=True)
    _, self_only = panda.check(q, return_pairs=True)
    names = set(env.names)
    for b, e, s in zip(both, env_only, self_only):
        assert set(e) == {p for p in b if names & set(p)}
        assert set(s) == {p for p in b if not names & set(p)}


def test_attached_object_in_both_checks(robots):
    """A box held between the fingers: allowed to touch the hand and fingers, checked against
    the other links and the environment, as python-fcl checks it."""
    panda = robots["panda"]
    panda.allowed = adjacent_only(panda)
    env = R.environment("panda")
    held = np.eye(4)
    held[2, 3] = 0.1
    panda.attach("box", trimesh.creation.box((0.05, 0.05, 0.12)), "panda_hand", held,
                 touch_links=["panda_leftfinger", "panda_rightfinger"])
    try:
        assert "box" in panda.attached
        pairs = panda.checked_pairs(env)
        assert ("box", "panda_link0") in pairs and ("box", "table/baseLink") in pairs
        assert ("box", "panda_hand") not in pairs and ("box", "panda_leftfinger") not in pairs
        q = panda.random_configurations(60, seed=8)
        _, ours = panda.check(q, environment=env, return_pairs=True)
        fcl = R.FclRobot(panda, env)
        theirs = fcl.check(q)
        s = R.score(panda, env, fcl.poses(q), [set(p) for p in ours], theirs)
        assert s["missed"] == 0 and s["false"] == 0, s["examples"]
        held_hits = {p for per in ours for p in per if "box" in p}
        assert held_hits, "the held box never collided: the test shows nothing"
    finally:
        panda.detach("box")
    assert "box" not in panda.attached


def test_padding_against_exact_distances(robots):
    """MoveIt's padding through the clearance mode: per configuration, every checked pair of a
    link and the environment whose exact surfaces (python-fcl) are closer than the link's
    padding is reported, and none farther than that plus an eighth of the largest padding; the
    robot's own pairs are checked unpadded, as MoveIt checks them."""
    from pycinder.testing import surface_distance

    panda = robots["panda"]
    panda.allowed = adjacent_only(panda)
    env = R.environment("panda")
    padding = {"panda_hand": 0.03, "panda_leftfinger": 0.03, "panda_rightfinger": 0.03,
               "panda_link7": 0.02, "panda_link6": 0.02, "panda_link5": 0.01}
    largest = 0.03
    q = panda.random_configurations(12, seed=21)
    _, ours = panda.check(q, environment=env, return_pairs=True, padding=padding)
    _, plain = panda.check(q, environment=env, return_pairs=True)
    poses = R.FclRobot(panda, env).poses(q)
    names = panda.checked_pairs(env)
    env_names = set(env.names)
    padded_only = 0
    for c in range(len(q)):
        world = R.world_meshes(panda, env, poses[c])
        for a, b in names:
            against_environment = a in env_names or b in env_names
            if not against_environment:
                pair = tuple(sorted((a, b)))
                assert (pair in set(ours[c])) == (pair in set(plain[c])), (c, pair)
                continue
            pad = padding.get(a, 0.0) + padding.get(b, 0.0)
            if pad == 0.0:
                continue
            d = surface_distance(world[a], world[b])
            reported = tuple(sorted((a, b))) in set(ours[c])
            if d < pad:
                assert reported, f"configuration {c}: {a}-{b} {d:.4f} apart, padding {pad}"
            if d > pad + largest / 8:
                assert not reported, f"configuration {c}: {a}-{b} {d:.4f} apart reported"
            padded_only += reported and tuple(sorted((a, b))) not in set(plain[c])
        assert set(plain[c]) <= set(ours[c])
    assert padded_only, "no pair was reported for its padding alone: the test shows nothing"


def test_a_batch_too_large_for_the_device_is_split_and_answers_the_same(robots, monkeypatch):
    """A batch whose one query the device refuses (GpuMemoryError) is checked in halves, down
    to single configurations, with the same verdicts and pairs as one query of them all (its
    bodies copied once per configuration from bodies prepared once); the copies are named by
    their configuration for messages."""
    from pycinder.errors import GpuMemoryError
    from pycinder.robot.robot import _CopyNames

    panda = robots["panda"]
    panda.allowed = adjacent_only(panda)
    env = R.environment("panda")
    q = panda.random_configurations(12, seed=21)
    whole, whole_pairs = panda.check(q, environment=env, return_pairs=True, batch=12)
    assert whole.any() and not whole.all()
    real = type(panda.detector)._find_within
    queries = []

    def refuse_large(det, scene, within, tolerance):
        configurations = len(np.unique(scene.names.config))
        queries.append(configurations)
        if configurations > 3:
            raise GpuMemoryError("too large for this test's device")
        return real(det, scene, within, tolerance)

    monkeypatch.setattr(type(panda.detector), "_find_within", refuse_large)
    split, split_pairs = panda.check(q, environment=env, return_pairs=True, batch=12)
    assert queries == [12, 6, 3, 3, 6, 3, 3]  # refused, refused, answered in four quarters
    assert split.tolist() == whole.tolist() and split_pairs == whole_pairs
    names = _CopyNames(panda.bodies, np.array([2, 0] * 3), np.repeat(np.arange(3), 2), 40)
    assert len(names) == 6 and names[3] == f"configuration 41: {panda.bodies[0].name}"
    assert names[-1] == names[5] and names[:2] == [names[0], names[1]]
    assert list(names) == [names[k] for k in range(6)]  # iteration ends
    with pytest.raises(IndexError):
        names[6]


def test_an_environment_of_new_bodies_is_checked_with_its_own_meshes(robots):
    """Checks against one environment, then another of as many bodies (a box over the whole
    arm in place of the table), then the first again: each answers with its own meshes (the
    bodies a check prepares belong to its bodies, not to the environment's size), as a robot
    that never saw the others answers."""
    xarm = robots["xarm"]
    xarm.allowed = adjacent_only(xarm)
    table = R.environment("xarm")
    engulf = Environment([(b.name, trimesh.creation.box((0.3, 0.3, 0.3)), np.eye(4))
                          for b in table.bodies])
    q = xarm.random_configurations(6, seed=2)
    first = xarm.check(q, environment=table, self_collision=False)
    inside = xarm.check(q, environment=engulf, self_collision=False)
    again = xarm.check(q, environment=table, self_collision=False)
    assert inside.all() and first.tolist() == again.tolist()
    fresh = R.load("xarm")
    fresh.allowed = adjacent_only(fresh)
    assert fresh.check(q, environment=engulf, self_collision=False).tolist() == inside.tolist()
    assert fresh.check(q, environment=table, self_collision=False).tolist() == first.tolist()
    assert not first.all()
    kept = list(table.bodies)
    # The same environment object, its bodies replaced by as many far away, where they were.
    far = Environment([(b.name, trimesh.creation.box((0.1, 0.1, 0.1)).apply_translation(
        (100.0, 0.0, 0.0)), b.origin) for b in kept])
    table.bodies[:] = far.bodies
    try:
        assert not xarm.check(q, environment=table, self_collision=False).any()
    finally:
        table.bodies[:] = kept


def test_a_detector_of_the_scene_strategy_is_refused_for_a_batch(robots):
    import pycinder

    with pytest.raises(ValueError, match="strategy='focused'"):
        pycinder.Detector(strategy="scene")._find_within(None, np.zeros(0), None)


def test_check_path_finds_the_first_colliding_index(robots):
    """A scripted path from above the table down into it: the index check_path returns is where
    the exact checks say the contact starts, up to the tolerance band: no configuration before
    it penetrates by 2 t, and the one at it is not t apart."""
    panda = robots["panda"]
    panda.allowed = adjacent_only(panda)
    env = R.environment("panda")
    up = np.array([0.0, -0.3, 0.0, -1.8, 0.0, 1.6, 0.8, 0.02])
    down = np.array([0.0, 1.6, 0.0, -0.4, 0.0, 1.6, 0.8, 0.02])
    for resolution in (0.05, 0.02):
        path = panda.interpolate([up, down], resolution)
        assert np.allclose(path[0], up) and np.allclose(path[-1], down)
        assert np.abs(np.diff(path, axis=0)).max() <= resolution + 1e-12
        index = panda.check_path([up, down], resolution, environment=env, self_collision=False)
        assert index is not None and 0 < index < len(path) - 1
        fcl = R.FclRobot(panda, env, self_collision=False)
        theirs = fcl.check(path)
        first = next(k for k, p in enumerate(theirs) if p)
        poses = fcl.poses(path)
        for k in range(min(index, first), max(index, first) + 1):
            world = R.world_meshes(panda, env, poses[k])
            verdicts = [R.exact_verdict(world[a], world[b], panda.tolerance)
                        for a, b in panda.checked_pairs(env, self_collision=False)]
            if k < index:
                assert "deep" not in verdicts, (k, index, first)
            if k == index:
                assert any(v != "apart" for v in verdicts), (k, index, first)
        assert abs(index - first) <= 2
    assert panda.check_path([up, up], 0.1, environment=env, self_collision=False) is None


def test_batch_runs_a_robot_manifest_with_resume(robots, tmp_path, capsys):
    """``pycinder batch ROBOT.json``: one row per configuration, as Robot.check answers; a run
    cut short goes on from where it stopped."""
    import json

    from pycinder.cli import main

    panda = robots["panda"]
    q = panda.random_configurations(12, seed=21)
    manifest, table = write_panda_manifest(tmp_path, panda, q)
    place = TABLE_PLACE
    out = tmp_path / "out.jsonl"
    assert main(["batch", str(manifest), "--out", str(out), "--robot-batch", "5"]) == 0
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["id"] for r in rows] == list(range(12))
    env = Environment([("table", table, place)])
    collides, pairs = panda.check(q, environment=env, return_pairs=True)
    assert [r["collides"] for r in rows] == collides.tolist()
    assert [[tuple(p) for p in r["names"]] for r in rows] == pairs
    assert collides.any()
    out.write_text("".join(line + "\n" for line in out.read_text().splitlines()[:7]))
    capsys.readouterr()
    assert main(["batch", str(manifest), "--out", str(out)]) == 0
    assert "5 configurations" in capsys.readouterr().out
    again = [json.loads(line) for line in out.read_text().splitlines()]
    assert again == rows
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"robot": "x.urdf", "configurations": "q.npy", "speed": 2}))
    assert main(["batch", str(bad), "--out", str(tmp_path / "o.jsonl")]) == 2
    assert "unknown keys ['speed']" in capsys.readouterr().err


def test_paced_queries_grow_to_the_adapters_cap(robots, monkeypatch):
    """Without ``batch``, a check's queries start at FIRST_BATCH configurations and at most
    double, up to GPU_BODIES_PER_QUERY bodies a query on a GPU and DEFAULT_BODIES_PER_QUERY on
    a CPU adapter (queries that take no time here: each doubles)."""
    from types import SimpleNamespace

    from pycinder.robot import DEFAULT_BODIES_PER_QUERY, FIRST_BATCH, GPU_BODIES_PER_QUERY

    panda = robots["panda"]
    plan, _ = panda._plan(R.environment("panda"), True)
    for cpu, most in ((True, DEFAULT_BODIES_PER_QUERY), (False, GPU_BODIES_PER_QUERY)):
        monkeypatch.setattr(panda.detector, "gpu", SimpleNamespace(cpu_adapter=cpu))
        sizes = [stop - start for start, stop in panda._batches(40_000, None, plan)]
        cap = most // plan.bodies
        assert sum(sizes) == 40_000 and sizes[0] == FIRST_BATCH
        assert max(sizes) == cap and all(b <= 2 * a for a, b in zip(sizes, sizes[1:]))
        assert sizes[:-1] == [min(FIRST_BATCH * 2**k, cap) for k in range(len(sizes) - 1)]
    assert GPU_BODIES_PER_QUERY // plan.bodies >= 4096  # thousands of Panda configurations


def test_a_check_with_nothing_to_query_starts_no_device():
    """A check with no pair to test (self-collision off, no environment) or no configuration
    answers without making the robot's detector (which would ask for a GPU)."""
    robot = R.load("xarm")
    q = robot.random_configurations(5, seed=1)
    assert robot.check(q, self_collision=False).tolist() == [False] * 5
    assert robot.check(q[:0]).shape == (0,)
    collides, pairs = robot.check(q, self_collision=False, return_pairs=True)
    assert not collides.any() and pairs == [[]] * 5
    assert robot._detector is None
    with pytest.raises(ValueError, match="batch must be a positive whole number"):
        robot.check(q, self_collision=False, batch=0)  # the option is checked all the same


def test_pairs_that_collide_in_nearly_every_configuration_are_warned_of_once(robots):
    """The Panda with nothing allowed (loaded without its SRDF): a check of at least
    ALWAYS_SAMPLES configurations warns, once, of the pairs that collide in at least
    ALWAYS_FRACTION of them, naming them and the way out (an SRDF, compute_allowed_collisions);
    python-fcl's exact answers on the same configurations have those pairs colliding nearly
    always too. Fewer configurations, or the pairs allowed, say nothing."""
    from pycinder.robot import AlwaysCollidingWarning
    from pycinder.robot.acm import ALWAYS_FRACTION, ALWAYS_SAMPLES

    panda = robots["panda"]
    bare = Robot(panda.name, panda.root, panda.links, panda.joints, panda.bodies,
                 panda.joint_names, panda.limits, AllowedCollisionMatrix())
    q = bare.random_configurations(ALWAYS_SAMPLES, seed=5)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        bare.check(q[:ALWAYS_SAMPLES - 1])  # too few to tell
        _, ours = bare.check(q, return_pairs=True)
        bare.check(q)  # said once
    said = [w for w in caught if issubclass(w.category, AlwaysCollidingWarning)]
    assert len(said) == 1, [str(w.message) for w in said]
    message = str(said[0].message)
    assert "compute_allowed_collisions" in message and "srdf" in message
    counts: dict[tuple[str, str], int] = {}
    for found in ours:
        for pair in found:
            counts[pair] = counts.get(pair, 0) + 1
    always = sorted(p for p, n in counts.items() if n >= ALWAYS_FRACTION * len(q))
    assert always and all(f"{a}-{b}" in message for a, b in always)
    assert all(p in PANDA_ADJACENT for p in always)  # the chain's neighbours touch at rest
    theirs = R.FclRobot(bare).check(q)
    for pair in always:
        assert sum(pair in t for t in theirs) >= 0.9 * len(q), pair

    bare.allowed = adjacent_only(bare)  # what an SRDF allows: nothing is always in collision
    bare._warned_always.clear()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        bare.check(q)
    assert not [w for w in caught if issubclass(w.category, AlwaysCollidingWarning)]


def test_batch_options_apply_to_a_robot_manifest_or_are_refused(robots, tmp_path, capsys):
    """``pycinder batch ROBOT.json``: every option applies or is refused, none is ignored.
    --batch-size, --attempts and --unordered are refused, naming the option; --tolerance gives
    the checks their tolerance (a bad one is the run's error; a good one gives Robot.check's
    rows at it); --strict makes the Panda's open meshes errors; and --robot-batch is refused
    for a scene manifest."""
    import json

    from pycinder.cli import main

    panda = robots["panda"]
    q = panda.random_configurations(6, seed=4)
    manifest, table = write_panda_manifest(tmp_path, panda, q)
    out = tmp_path / "out.jsonl"
    for option in (["--batch-size", "4"], ["--attempts", "3"], ["--unordered"]):
        assert main(["batch", str(manifest), "--out", str(out), *option]) == 2
        err = capsys.readouterr().err
        assert option[0] in err and "robot manifest" in err, err
        assert not out.exists()
    assert main(["batch", str(manifest), "--out", str(out), "--tolerance", "-1"]) == 2
    assert "tolerance" in capsys.readouterr().err and not out.exists()
    assert main(["batch", str(manifest), "--out", str(out), "--tolerance", "0.02"]) == 0
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    coarse = Robot(panda.name, panda.root, panda.links, panda.joints, panda.bodies,
                   panda.joint_names, panda.limits, adjacent_only(panda), tolerance=0.02)
    collides, pairs = coarse.check(q, environment=Environment([("table", table, TABLE_PLACE)]),
                                   return_pairs=True)
    assert [r["collides"] for r in rows] == collides.tolist()
    assert [[tuple(p) for p in r["names"]] for r in rows] == pairs
    strict = tmp_path / "strict.jsonl"
    assert main(["batch", str(manifest), "--out", str(strict), "--strict"]) == 2
    assert "panda_link" in capsys.readouterr().err
    scenes = tmp_path / "scenes.jsonl"
    scenes.write_text(json.dumps({"id": 0, "bodies": [{"mesh": "table.stl"}]}) + "\n")
    assert main(["batch", str(scenes), "--out", str(tmp_path / "s.jsonl"),
                 "--robot-batch", "4"]) == 2
    assert "--robot-batch" in capsys.readouterr().err


def test_padding_on_self_collision_against_exact_distances(robots):
    """``pad_self_collision``: the robot's own checked pairs are padded too, by the sum of both
    bodies' paddings: per configuration, every pair of links whose exact surfaces (python-fcl)
    are closer than that sum is reported, and none farther than it plus an eighth of the largest
    sum; environment pairs are kept as without it; check_path takes the same padding."""
    from pycinder.testing import surface_distance

    panda = robots["panda"]
    panda.allowed = adjacent_only(panda)
    env = R.environment("panda")
    padding = {"panda_hand": 0.03, "panda_leftfinger": 0.01, "panda_rightfinger": 0.01,
               "panda_link7": 0.02, "panda_link6": 0.02, "panda_link5": 0.02,
               "panda_link4": 0.02, "panda_link3": 0.02, "panda_link2": 0.02}
    largest = 0.05  # hand and a link: the largest sum of two paddings of a checked pair
    q = panda.random_configurations(16, seed=8)
    _, ours = panda.check(q, environment=env, return_pairs=True, padding=padding,
                          pad_self_collision=True)
    _, moveit = panda.check(q, environment=env, return_pairs=True, padding=padding)
    poses = R.FclRobot(panda, env).poses(q)
    env_names = set(env.names)
    padded_only = 0
    for c in range(len(q)):
        world = R.world_meshes(panda, env, poses[c])
        mine, theirs = set(ours[c]), set(moveit[c])
        for a, b in panda.checked_pairs(env):
            pair = tuple(sorted((a, b)))
            if a in env_names or b in env_names:
                continue
            pad = padding.get(a, 0.0) + padding.get(b, 0.0)
            d = surface_distance(world[a], world[b])
            if d < pad or (pad == 0.0 and pair in theirs):
                assert pair in mine, f"configuration {c}: {a}-{b} {d:.4f} apart, padding {pad}"
            if d > pad + largest / 8:
                assert pair not in mine, f"configuration {c}: {a}-{b} {d:.4f} apart reported"
            padded_only += pair in mine and pair not in theirs
        assert {p for p in mine if p[0] in env_names or p[1] in env_names} == \
            {p for p in theirs if p[0] in env_names or p[1] in env_names}
    assert padded_only, "no pair of links was reported for its padding alone"
    path = np.stack([q[0], q[1]])
    first = panda.check_path(path, 0.2, environment=env, padding=padding,
                             pad_self_collision=True)
    steps = panda.interpolate(path, 0.2)
    hits = panda.check(steps, environment=env, padding=padding, pad_self_collision=True)
    assert first == (int(np.flatnonzero(hits)[0]) if hits.any() else None)

"""The host CPU benchmark's instruments (benchmarks.hostcpu): per-thread CPU clocks over
the process's Python threads, wgpu-py calls counted per query, the stages' breakdown, and their
report. No time is asserted: what the figures are belongs to the benchmark."""

import threading

import numpy as np
import pytest
import trimesh

import pycinder
from benchmarks import hostcpu, report
from pycinder.focused.focused_strategy import FocusedStrategy


def test_every_python_thread_is_read_on_its_own_clock():
    started, release = threading.Event(), threading.Event()

    def work() -> None:
        sum(i * i for i in range(300_000))                     # CPU on this thread only
        started.set()
        release.wait()

    worker = threading.Thread(target=work, name="pycinder-test-worker")
    before = hostcpu.python_thread_clocks()
    worker.start()
    started.wait()
    after = hostcpu.python_thread_clocks()
    release.set()
    worker.join()
    assert worker.ident in after and worker.ident not in before
    groups = hostcpu.cpu_by_group(before, after)
    assert groups["pycinder pool"] > 0                         # a thread started in between
    assert abs(sum(groups.values()) - hostcpu.cpu_ms(before, after)) < 1e-9


def _two_touching():
    meshes = [trimesh.creation.box((1, 1, 1)), trimesh.creation.icosphere(radius=0.4)]
    poses = np.tile(np.eye(4), (2, 1, 1))
    poses[1, 0, 3] = 0.6
    return meshes, poses


def test_wgpu_calls_are_counted_and_the_classes_given_back():
    det = pycinder.Detector(records="none")
    meshes, poses = _two_touching()
    det.find_collisions(meshes, poses)
    queue = type(det.gpu.device.queue)
    submit = queue.__dict__["submit"]
    with hostcpu.count_wgpu_calls(det.gpu.device) as counts:
        assert det.find_collisions(meshes, poses).pairs.tolist() == [[0, 1]]
    assert queue.__dict__["submit"] is submit
    calls = hostcpu.summarise_calls(counts, 1)
    assert calls["submissions"] >= 1 and calls["maps"] >= 1
    assert calls["wgpu_calls"] == sum(calls["by_method"].values()) > calls["submissions"]
    assert calls["native_calls"] > 0


def test_a_case_is_measured_with_its_stages_and_reported():
    pack = FocusedStrategy.__dict__["pack"]
    rows = hostcpu.measure(hostcpu.CASES["two-small"], ["numpy"], repeats=2, batch=2, warmup=1,
                           counted=1)
    assert FocusedStrategy.__dict__["pack"] is pack            # the stages' wrappers are gone
    (row,) = rows
    assert row["queries"] == 4 and row["candidates"] == 1 and row["submissions"] >= 1
    assert row["host_cpu_ms"] > 0 and row["wall_ms"] > 0
    stages = row["stages_ms"]
    assert {"validate", "broad phase", "tiles (plan)", "encode and submit"} <= set(stages)
    assert all(ms >= 0 for ms in stages.values())
    assert abs(sum(stages.values()) - row["staged_total_ms"]) < 1e-9
    text = "\n".join(hostcpu.markdown_lines(rows))
    assert "| two-small | numpy |" in text and "| encode and submit |" in text
    machine = {"date": "today", "adapter": "test", "cpu": "cpu", "cores": 1, "python": "3",
               "versions": {}, "command": "pycinder bench hostcpu"}
    written = report.markdown({"machine": machine, "hostcpu": rows})
    assert "## Host CPU per query" in written and "| two-small | numpy |" in written


def test_a_fresh_process_measures_this_checkout():
    rows = hostcpu.run_fresh(["two-small-prepared"], ["numpy"], repeats=1, batch=1,
                             stages=False)
    assert [(r["scene"], r["planner"]) for r in rows] == [("two-small-prepared", "numpy")]
    assert "stages_ms" not in rows[0] and rows[0]["wgpu_calls"] > 0


def test_the_floor_skeleton_runs_its_shader_and_is_measured():
    """The floor's skeleton (upload, dispatches, a render bundle, one submission, one map)
    really runs: its shader's answer is the largest body index; the measure reports its calls,
    more with pycinder's watch than without, and a positive host CPU."""
    from benchmarks import hostfloor
    from pycinder.gpu.device import get_gpu

    skeleton = hostfloor.Skeleton(get_gpu().device, 300, 3, True, 64)
    for direct in (False, True, False):
        answer = skeleton.query(direct=direct)
        assert answer[0] == 0 and answer[1] == 299
    watched = hostfloor.measure(2, 2, False, 64, True, batches=2, per_batch=3)
    bare = hostfloor.measure(2, 2, False, 64, False, batches=2, per_batch=3)
    direct = hostfloor.measure(2, 2, False, 64, True, True, batches=2, per_batch=3)
    assert watched["cpu_ms"] > 0 and bare["cpu_ms"] > 0 and direct["cpu_ms"] > 0
    assert watched["calls"] > bare["calls"] >= 13
    # the watch copies its marker through the C functions: five calls a submission
    assert bare["direct_calls"] == 0 < watched["direct_calls"] < direct["direct_calls"]
    assert watched["direct_calls"] % 5 == 0
    lines = "\n".join(hostfloor.markdown_lines([watched, direct], "x"))
    assert "| 2 | 2 | no | 64 | yes | no |" in lines and "| 2 | 2 | no | 64 | yes | yes |" in lines


def test_a_shaped_skeleton_makes_the_calls_of_its_shape_and_a_scene_has_its_floor():
    """A query of a CommandShape makes exactly the calls the shape counts (read back from its
    counted calls by CommandShape.of_calls, the watch's own left out) through the C functions,
    as pycinder's queries make them (through wgpu-py, its maps for reading add a submission of
    their own); its shader runs either way (the answer is the largest body index); a scene's
    floor is measured on the shape of its own counted calls."""
    from benchmarks import hostfloor
    from pycinder.gpu.device import get_gpu

    device = get_gpu().device
    shape = hostfloor.CommandShape(submissions=2, compute_passes=3, dispatches=7,
                                   render_passes=2, clears=3, copies=2, writes=4)
    skeleton = hostfloor.Skeleton(device, 300, 0, False, 64, shape)
    for direct in (False, True):
        skeleton.query(direct=direct)
        device.queue.write_buffer(skeleton.answer, 0, np.zeros(16, np.uint32))
        with hostcpu.count_wgpu_calls(device) as counts:
            answer = skeleton.query(direct=direct)
        assert answer[0] == 0 and answer[1] == 299          # written by this query's shader
        by_method = hostcpu.summarise_calls(counts, 1)["by_method"]
        if direct:
            assert hostfloor.CommandShape.of_calls(by_method) == shape, by_method
    with pytest.raises(ValueError, match="2 maps"):                 # not one map a submission
        hostfloor.CommandShape.of_calls({**by_method, "C wgpuBufferMapAsync": 2.0,
                                         "GPUQueue.submit": 1.0})
    with pytest.raises(ValueError, match="compute pass for any dispatch"):
        hostfloor.CommandShape(compute_passes=0, dispatches=3)
    rows = hostfloor.scene_floors(["two-small-prepared"], ["numpy"], repeats=1, batches=2,
                                  per_batch=2)
    assert len(rows) == 1 and rows[0]["floor_ms"] > 0 and rows[0]["one_submission_ms"] > 0
    assert rows[0]["shape"]["submissions"] == 1 and rows[0]["shape"]["dispatches"] > 3
    assert rows[0]["shape"]["render_passes"] >= 1
    lines = "\n".join(hostfloor.scene_lines(rows, "x"))
    assert "| two-small-prepared | numpy |" in lines
    costs = hostfloor.command_costs(repeats=1, batches=1, per_batch=2)
    assert costs[0]["each_ms"] is None and costs[-1]["each_ms"] is None
    assert costs[-1]["shape"] == vars(hostfloor.MINIMAL_FRAME)
    assert all(r["cpu_ms"] > 0 for r in costs) and len(costs) == 9
    assert "| the least query |" in "\n".join(hostfloor.cost_lines(costs, "x"))


def test_a_child_process_finds_this_ones_python_path_after_the_tree(monkeypatch):
    """The fresh processes of the benchmarks import the tree given first and still find what
    this process finds on its PYTHONPATH (wheels installed with ``--target`` on a machine without
    a package index): the GPU machine's run of the fresh-process test lost wgpu without it."""
    import os

    from pycinder.util.environ import path_first

    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(["/opt/site", "", "/opt/more"]))
    assert path_first("/tree/src").get("PYTHONPATH", "").split(os.pathsep) == \
        ["/tree/src", "/opt/site", "/opt/more"]
    monkeypatch.delenv("PYTHONPATH")
    assert path_first("/a", "/b")["PYTHONPATH"] == os.pathsep.join(["/a", "/b"])


def test_a_robots_host_cpu_per_configuration_is_measured(monkeypatch):
    """``--robot``: host CPU per configuration of Robot.check in checks of a batch each, one
    query a check (the batch's configurations in one scene of copies)."""
    pytest.importorskip("yourdfpy")
    pytest.importorskip("pybullet_data")
    queries = []
    real = pycinder.Detector._find_within
    monkeypatch.setattr(pycinder.Detector, "_find_within",
                        lambda det, *a: queries.append(len(a[0])) or real(det, *a))
    r = hostcpu.robot_configurations("xarm", batch=64, batches=1)  # on the GPU: passes K1, K2
    assert r["robot"] == "xarm" and r["batch"] == 64
    assert r["host_cpu_us"] > 0 and r["wall_ms"] > 0
    # One query a check (two untimed ones, the timed one, the one timed by stage), each of the
    # copies of 64 configurations' bodies (those of the pairs pass K2 kept).
    assert len(queries) == 4 and min(queries) > 64
    stages = r["stages_us"]
    assert {"kinematics and cull (K1, K2)", "broad phase", "tiles (plan)"} <= set(stages)
    assert all(v >= 0 for v in stages.values()) and sum(stages.values()) > 0


def test_a_robots_host_cpu_with_moveits_matrix(monkeypatch, capsys):
    """``--robot NAME --matrix-samples N``: the same measure with MoveIt's allowed-collision
    matrix made from N samples (fewer pairs to check than the matrix the robot loads with)."""
    pytest.importorskip("yourdfpy")
    pytest.importorskip("pybullet_data")
    from pycinder.robot import Robot

    made = []
    real = Robot.compute_allowed_collisions
    monkeypatch.setattr(Robot, "compute_allowed_collisions",
                        lambda self, n, **kw: made.append(n) or real(self, n, **kw))
    hostcpu.main(["--robot", "xarm", "--batch", "64", "--matrix-samples", "20"])
    out = capsys.readouterr().out
    assert made == [20] and out.startswith("xarm (MoveIt's matrix from 20 samples), batches of 64")
    assert "host CPU" in out and "kinematics and cull (K1, K2)" in out
    with pytest.raises(SystemExit):
        hostcpu.main(["--robot", "xarm", "--matrix-samples", "-1"])
    assert "--matrix-samples" in capsys.readouterr().err

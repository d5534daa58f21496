"""The paper's demos (section 5), run headless, checked against exact geometry."""

import numpy as np
import pytest
import trimesh

from pycinder.demos import normals, snow, stairs
from pycinder.demos.run import run


@pytest.mark.parametrize("name,out", [("stairs", "stairs.mp4"), ("snow-bunny", "snow.gif"),
                                      ("normals", "frames")])
def test_demo_writes_its_output(tmp_path, name, out):
    target = tmp_path / out
    summary = run(name, frames=4, out=str(target), quiet=True)
    assert len(summary["counts"]) == 4 and len(summary["ms"]) == 4
    assert "median detection" in summary["summary"]
    if target.suffix:
        assert target.stat().st_size > 1000
    else:
        assert len(list(target.glob("*.png"))) == 4


def test_same_seed_same_run():
    a = run("stairs", frames=30, seed=3, quiet=True)
    b = run("stairs", frames=30, seed=3, quiet=True)
    assert a["counts"] == b["counts"]
    assert np.array_equal(a["sim"].position, b["sim"].position)


def test_stairs_no_sphere_ends_a_frame_inside_a_step():
    sim = stairs.StairsSim(spheres=50, seed=1)  # the default speed and resolution
    boxes = stairs.step_boxes()
    hits = 0
    for _ in range(200):
        info = sim.step()
        hits += info["pairs"]
        centres = sim.position[sim.active]
        inside = ((centres[:, None, :] > boxes[None, :, 0]) &
                  (centres[:, None, :] < boxes[None, :, 1])).all(axis=2)
        assert not inside.any(), f"frame {sim.frame_index}: a sphere centre is inside a step"
    assert hits > 50  # the spheres did bounce on the steps


def test_snow_frozen_flakes_lie_on_the_bunny_or_the_floor():
    sim = snow.SnowSim(flakes=80, seed=2)
    for _ in range(70):
        sim.step()
    assert len(sim.frozen) >= 10
    on_bunny = [f.transform[:3, 3] for f in sim.frozen if f.on_bunny]
    on_floor = [f.transform[:3, 3] for f in sim.frozen if not f.on_bunny]
    assert on_bunny and on_floor
    # tolerance: the flake's size, one frame of fall, and a pixel of the view
    tol = snow.FLAKE_SIZE + 0.7 * snow.DT + 0.01
    d = np.abs(trimesh.proximity.signed_distance(sim.bunny, np.array(on_bunny)))
    assert d.max() < tol, d.max()
    floor_top = 0.0
    assert np.abs(np.array(on_floor)[:, 1] - floor_top).max() < tol


def test_snow_open_scan_warns_and_repair_closes_it():
    open_sim = snow.SnowSim(flakes=10, seed=0, scan=True)
    assert not open_sim.bunny.is_watertight
    open_sim.step()
    assert open_sim.warnings and "not a closed" in open_sim.warnings[0]
    fixed = snow.SnowSim(flakes=10, seed=0, scan=True, close_holes=True)
    assert fixed.bunny.is_watertight
    fixed.step()
    assert not fixed.warnings


def test_normals_from_records_match_the_bunny_faces():
    sim = normals.NormalsSim(spheres=24, seed=4)
    for _ in range(90):
        sim.step()
    points = np.concatenate([p for p, _ in sim.contacts if len(p)])
    got = np.concatenate([n for p, n in sim.contacts if len(p)])
    assert len(points) > 20 and sim.bounces > 3
    _, _, tri = trimesh.proximity.closest_point(sim.bunny, points)
    true = sim.bunny.face_normals[tri]
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", got, true), -1, 1)))
    # An edge's normal is the mean of its two faces: within half the dihedral angle of either.
    assert np.median(angle) < 20, np.median(angle)
    assert np.percentile(angle, 90) < 45, np.percentile(angle, 90)

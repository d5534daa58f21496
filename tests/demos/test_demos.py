"""The paper's demos (section 5): the simulations checked against exact geometry, and the frames
checked for what a person would see (not blank, round spheres, the staircase in view, as many
marks as the overlay says)."""

import itertools
import sys

import numpy as np
import pytest
import trimesh

from pycinder.demos import edge_colours as normals
from pycinder.demos import snow, stairs
from pycinder.demos.run import run


def needs_pygfx():
    """pygfx comes with the test extra: a missing one fails the frame tests, never skips them."""
    import pygfx

    return pygfx


def read_frames(target):
    """The frames a run wrote to an .mp4, a .gif or a folder of PNGs, as (H, W, 3) uint8."""
    if target.suffix == ".mp4":
        import imageio.v2 as imageio

        with imageio.get_reader(target) as reader:
            return [np.asarray(f)[..., :3] for f in reader]
    from PIL import Image, ImageSequence

    if target.suffix == ".gif":
        with Image.open(target) as gif:
            return [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(gif)]
    return [np.asarray(Image.open(p).convert("RGB")) for p in sorted(target.glob("*.png"))]


def assert_not_blank(image):
    """The scene is drawn: in the middle of the frame (the text and legend sit in its corners),
    a good part of the pixels differ from the background, a vertical gradient (each row's most
    common colour)."""
    assert image.shape == (480, 640, 3)
    middle = image[120:360, 160:480].astype(int)
    background = np.median(middle, axis=1, keepdims=True)
    away = np.abs(middle - background).max(axis=2) > 24
    assert away.mean() > 0.05, away.mean()


@pytest.mark.parametrize("name,out", [("stairs", "stairs.mp4"), ("snow-bunny", "snow.gif"),
                                      ("normals", "frames")])
def test_demo_writes_frames_that_are_not_blank(tmp_path, name, out):
    needs_pygfx()
    target = tmp_path / out
    summary = run(name, frames=4, out=str(target), quiet=True)
    assert len(summary["counts"]) == 4 and len(summary["ms"]) == 4
    assert "median detection" in summary["summary"]
    frames = read_frames(target)
    assert len(frames) == 4
    assert_not_blank(frames[-1])
    # pygfx drew on the device the detector computed on.
    import wgpu

    assert summary["sim"].detector.gpu.device is wgpu.get_default_device()


def test_an_mp4_without_imageio_ffmpeg_is_refused_naming_the_package(tmp_path, monkeypatch):
    """Without imageio-ffmpeg, an MP4 is refused at once, saying how to install it (imageio
    would otherwise write it with another plugin, which fails on the first frame), and the
    suite's skip for missing packages names it."""
    import imageio  # noqa: F401  (without imageio itself, the skip names imageio)
    from conftest import missing_optional

    from pycinder.demos.output import FrameWriter

    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # imports as if not installed
    with pytest.raises(ImportError, match=r"pip install imageio-ffmpeg.*pycinder\[demo\]") as info:
        FrameWriter(tmp_path / "stairs.mp4", fps=30)
    assert missing_optional(info.value) == "imageio-ffmpeg (test, demo)"
    assert not (tmp_path / "stairs.mp4").exists()


def test_same_seed_same_run():
    a = run("stairs", frames=30, seed=3, quiet=True)
    b = run("stairs", frames=30, seed=3, quiet=True)
    assert a["counts"] == b["counts"]
    assert np.array_equal(a["sim"].position, b["sim"].position)


def test_stairs_spheres_bounce_down_every_step_and_never_end_inside_one():
    needs_pygfx()
    from pycinder.demos.display import Display

    sim = stairs.StairsSim(spheres=50, seed=1)  # the default speed and resolution
    display = Display(stairs.LOOK)
    boxes = stairs.step_boxes()
    contacts = 0
    landed = np.zeros(stairs.STEPS, bool)  # steps a sphere landed on (a contact facing up)
    for _ in range(120):  # the default frame count
        info = sim.step()
        contacts += info["contacts_count"]
        c = info["contacts"]
        on_top = (c.pair[:, 0] < stairs.STEPS) & (c.normal[:, 1] > 0.5)
        landed[c.pair[on_top, 0]] = True
        assert len(info["marks"]) == len(info["normals"]) == info["contacts_count"]
        assert info["contacts_count"] >= info["pairs"]  # at least one contact per pair
        centres = sim.position[sim.active]
        inside = ((centres[:, None, :] > boxes[None, :, 0]) &
                  (centres[:, None, :] < boxes[None, :, 1])).all(axis=2)
        assert not inside.any(), f"frame {sim.frame_index}: a sphere centre is inside a step"
        over_floor = ((centres[:, [0, 2]] > stairs.FLOOR_BOX[0, [0, 2]]) &
                      (centres[:, [0, 2]] < stairs.FLOOR_BOX[1, [0, 2]])).all(axis=1)
        assert (centres[over_floor, 1] > stairs.FLOOR_TOP).all(), "a sphere fell through the floor"
        # The camera keeps every sphere in play in view.
        display.follow(sim.view_box(), sim.view_direction)
        _, shown = display.project(centres)
        assert shown.all(), f"frame {sim.frame_index}: {int((~shown).sum())} spheres out of view"
    # Spheres land on every step, and spheres of the first volleys bounce on all 11 in turn
    # (how many depends on how the sphere-sphere collisions scatter them: 6 to 18 for seeds
    # 0-3 with two detections a frame; with one, a centre sometimes went into a step).
    assert landed.all(), landed
    assert sim.descents >= 5, sim.descents
    assert contacts > 400 and sim.sphere_contacts > 20


def test_stairs_spheres_collide_as_equal_masses():
    """Two spheres meeting head on along x: the impulse response exchanges their approach
    speed times the restitution (equal masses), and pushes them apart by the overlap."""
    sim = stairs.StairsSim(spheres=2, seed=0, emit_per_frame=0)
    sim.active[:] = True
    # in the air above the steps; after this frame's move they overlap by 0.03
    sim.position[:] = [[3.0, 0.8, 0.0], [3.27, 0.8, 0.0]]
    sim.velocity[:] = [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]
    before_v, before_p = sim.velocity.copy(), sim.position.copy()
    sim.velocity[:, 1] -= stairs.GRAVITY * stairs.DT  # cancel this frame's gravity
    sim.step()
    assert sim.sphere_contacts == 1
    e = stairs.SPHERE_RESTITUTION
    # exact: v_a' = (1 - e)/2 v_a + (1 + e)/2 v_b along the normal, and the other way round
    expected = np.array([(1 - e) / 2 * 1 + (1 + e) / 2 * -1, (1 + e) / 2 * 1 + (1 - e) / 2 * -1])
    assert np.allclose(sim.velocity[:, 0], expected, atol=0.05 * abs(expected).max()), \
        sim.velocity
    assert np.allclose(sim.velocity[:, 1:], 0, atol=0.05)
    moved = sim.position - before_p - before_v * stairs.DT
    gap = (sim.position[1, 0] - sim.position[0, 0]) - 2 * stairs.RADIUS
    assert abs(gap) < 0.01, gap  # the overlap is undone (within a tolerance of the contact)
    assert moved[0, 0] < 0 < moved[1, 0]


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
        info = sim.step()
        assert len(info["marks"]) == len(info["normals"]) >= info["pairs"]
    points = np.concatenate([p for p, _ in sim.contacts if len(p)])
    got = np.concatenate([n for p, n in sim.contacts if len(p)])
    assert len(points) > 20 and sim.bounces > 3
    _, _, tri = trimesh.proximity.closest_point(sim.bunny, points)
    true = sim.bunny.face_normals[tri]
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", got, true), -1, 1)))
    # An edge's normal is the mean of its two faces: within half the dihedral angle of either.
    assert np.median(angle) < 20, np.median(angle)
    assert np.percentile(angle, 90) < 45, np.percentile(angle, 90)


def test_normals_edges_are_coloured_by_the_encoded_normals():
    sim = normals.NormalsSim(spheres=2, seed=0)
    lines = sim.edges
    mesh_edges = sim.bunny.edges_unique
    assert len(lines.segments) == len(mesh_edges)
    # Colour 0.5 + 0.5 n, n the mean of the edge's two face normals (what encode="normal" uses).
    n = lines.colours * 2 - 1
    mid = lines.segments.mean(axis=1)
    _, _, tri = trimesh.proximity.closest_point(sim.bunny, mid)
    cos = np.einsum("ij,ij->i", n / np.linalg.norm(n, axis=1, keepdims=True),
                    sim.bunny.face_normals[tri])
    assert np.median(cos) > 0.95


# -- what a person sees --------------------------------------------------------------------


def silhouette(display, layers):
    """Pixels where ``layers`` change the rendered frame, as an (H, W) bool mask."""
    empty = display.render()
    display.update(layers)
    shown = display.render()
    return np.abs(shown.astype(int) - empty.astype(int)).max(axis=2) > 6


@pytest.mark.parametrize("demo", [stairs, normals])
def test_a_sphere_looks_round(demo):
    needs_pygfx()
    from pycinder.demos.display import Display, Layer

    display = Display(demo.LOOK)
    distance = np.linalg.norm(np.subtract(demo.LOOK.eye, demo.LOOK.target))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=distance * 0.06)
    where = np.eye(4)
    where[:3, 3] = demo.LOOK.target
    mask = silhouette(display, {"probe": Layer(ball, where[None], np.array([0.9, 0.5, 0.2]))})
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    height, width = rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1
    assert height > 60  # big enough to measure to a few percent
    assert abs(width / height - 1) < 0.03, (width, height)
    # Its outline is a circle: every boundary pixel at the same distance from the centre.
    y, x = np.nonzero(mask)
    cy, cx = y.mean(), x.mean()
    edge = mask & ~np.pad(mask[1:-1, 1:-1] & mask[:-2, 1:-1] & mask[2:, 1:-1] &
                          mask[1:-1, :-2] & mask[1:-1, 2:], 1)
    ey, ex = np.nonzero(edge)
    r = np.hypot(ey - cy, ex - cx)
    assert r.std() / r.mean() < 0.03, (r.mean(), r.std())
    assert abs(mask.sum() / (np.pi * r.mean() ** 2) - 1) < 0.05


def test_the_whole_staircase_and_floor_are_in_view_at_the_start():
    needs_pygfx()
    from pycinder.demos.display import Display

    display = Display(stairs.LOOK)
    box = stairs.VIEW_BOX
    corners = np.array(list(itertools.product(*box.T)))
    xy, inside = display.project(corners)
    assert inside.all(), xy
    # What is drawn: the steps and the floor touch no edge of the frame.
    sim = stairs.StairsSim(spheres=1)
    layers = sim.layers()
    mask = silhouette(display, {"steps": layers["steps"], "floor": layers["floor"]})
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    assert rows[0] > 2 and cols[0] > 2 and rows[-1] < 477 and cols[-1] < 637, \
        (rows[0], rows[-1], cols[0], cols[-1])
    # and fill a good part of it
    assert cols[-1] - cols[0] > 0.7 * 640


def test_overlay_count_equals_the_marks_drawn(tmp_path):
    needs_pygfx()
    from scipy import ndimage

    from pycinder.demos.overlay import MARK_EDGE, MARK_FILL, MARK_HALF

    out = tmp_path / "frames"
    result = run("stairs", frames=16, out=str(out), quiet=True)
    frames = read_frames(out)
    assert sum(len(m) for m in result["marks"]) > 10
    for k, (image, marks, lines) in enumerate(zip(frames, result["marks"], result["lines"])):
        # The text says how many marks there are; there is one per contact.
        assert lines[-1] == f"contacts: {len(marks)}", (k, lines[-1])
        assert len(marks) == result["counts"][k]
        # The frame shows exactly those marks: each mark's square is where it should be, and the
        # purple outlines form one blob per group of touching marks, plus the legend's mark.
        edge = (image == MARK_EDGE).all(axis=2)
        fill = (image == MARK_FILL).all(axis=2)
        for x, y in np.round(marks).astype(int):
            square = (slice(y - MARK_HALF, y + MARK_HALF + 1),
                      slice(x - MARK_HALF, x + MARK_HALF + 1))
            assert (edge[square] | fill[square]).mean() > 0.9, (k, x, y)
        _, blobs = ndimage.label(edge, structure=np.ones((3, 3)))
        groups = _touching_groups(np.round(marks).astype(int), 2 * MARK_HALF + 1)
        assert blobs == groups + 1, (k, blobs, groups)


@pytest.mark.parametrize("name", ["snow-bunny", "normals"])
@pytest.mark.parametrize("seed", [0, 1])
def test_contacts_show_within_the_first_30_frames(name, seed):
    from pycinder.demos.run import make_demo

    demo = make_demo(name, seed=seed)
    counts = [len(demo.sim.step()["marks"]) for _ in range(30)]
    assert sum(counts) >= 3, counts


def purple(pixels):
    """Pixels in the hue of the stairs' touching colour (purple), as an (...,) bool mask."""
    r, g, b = (pixels[..., k].astype(int) for k in range(3))
    return (b > g + 40) & (r > g + 25) & (b > r)


def orange(pixels):
    r, g, b = (pixels[..., k].astype(int) for k in range(3))
    return (r > g + 20) & (g > b + 20)


def test_colliding_bodies_are_drawn_in_the_touching_colour():
    """What a person sees: spheres in a colliding pair are purple, the others orange, and no
    purple shows while nothing collides."""
    needs_pygfx()
    from pycinder.demos.display import Display

    display = Display(stairs.LOOK)
    sim = stairs.StairsSim(spheres=50, seed=1)
    sim.step()  # the first volley, in the air
    assert not sim.touching.any() and not sim.static_touched.any()
    display.follow(sim.view_box(), sim.view_direction)
    display.update(sim.layers())
    assert not purple(display.render()).any()
    while not (sim.touching.sum() >= 3 and sim.static_touched.any()):
        sim.step()
    display.follow(sim.view_box(), sim.view_direction)
    display.update(sim.layers())
    image = display.render()
    xy, inside = display.project(sim.position)
    px = np.round(xy).astype(int)
    shown = sim.active & inside
    at = image[px[shown, 1], px[shown, 0]]
    touching = sim.touching[shown]
    # a sphere's centre pixel shows its own colour unless another sphere is in front of it
    assert purple(at[touching]).mean() >= 0.75, at[touching]
    assert orange(at[~touching]).mean() >= 0.75
    # the step a sphere touches is tinted too
    assert purple(image).sum() > 10 * touching.sum()


def test_normals_spheres_are_white_while_touching():
    sim = normals.NormalsSim(spheres=24, seed=0)
    for _ in range(60):
        info = sim.step()
        colours = sim.layers()["spheres"].colours
        white = (colours == normals.TOUCH_COLOUR).all(axis=1)
        assert white.sum() == sim.touching.sum() == info["pairs"]


def _touching_groups(centres, size):
    """How many groups squares of ``size`` pixels at ``centres`` (n, 2) form when touching
    squares (8-connected) join."""
    n = len(centres)
    parent = list(range(n))

    def root(i):
        while parent[i] != i:
            i = parent[i]
        return i

    for i, j in itertools.combinations(range(n), 2):
        if np.abs(centres[i] - centres[j]).max() <= size:
            parent[root(i)] = root(j)
    return len({root(i) for i in range(n)})


def test_window_without_a_display_says_so(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    with pytest.raises(RuntimeError, match="needs a display"):
        run("stairs", frames=1, window=True)


def test_missing_pygfx_says_what_to_install(monkeypatch):
    from pycinder.demos.shared import import_pygfx

    monkeypatch.setitem(sys.modules, "pygfx", None)
    with pytest.raises(ImportError, match=r"pip install 'pycinder\[demo\]'"):
        import_pygfx()


def test_example_writes_a_labelled_montage(tmp_path, capsys):
    from PIL import Image
    from scipy import ndimage

    from pycinder.cli import main
    from pycinder.debug.pass_buffers import id_colours
    from pycinder.debug.montage import PANEL_OUTLINE

    assert main(["example", "--out", str(tmp_path)]) == 0
    assert "montage.png" in capsys.readouterr().out
    assert len(list(tmp_path.glob("0*.png"))) == 6  # the buffers one by one, as before
    montage = np.asarray(Image.open(tmp_path / "montage.png").convert("RGB"))
    # Six framed panels, three a row ...
    labels, n = ndimage.label((montage == PANEL_OUTLINE).all(axis=2), structure=np.ones((3, 3)))
    boxes = [b for b in ndimage.find_objects(labels)
             if b[0].stop - b[0].start > 100 and b[1].stop - b[1].start > 100]
    assert len(boxes) == 6, boxes
    assert len({b[0].start for b in boxes}) == 2 and len({b[1].start for b in boxes}) == 3
    # ... showing the boxes' colours, which the legend explains.
    below = max(b[0].stop for b in boxes)
    for colour in id_colours(np.arange(1, 4)):
        assert (montage[:below] == colour).all(axis=2).sum() > 50
        assert (montage[below:] == colour).all(axis=2).sum() > 50

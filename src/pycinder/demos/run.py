"""``pycinder demo {stairs,snow-bunny,normals}``: run a demo headless or in a window.

Each frame the simulation steps (detection and response), the display shows its layers (bodies
recoloured while they touch), and an overlay marks every contact (one per contact region of each
colliding pair, from :meth:`~pycinder.CollisionResult.contacts`) with a purple square and a short
arrow along its normal, says how many it drew and explains the marks in a legend.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .display import Display, Look
from .output import FrameWriter, display_available, summary
from .overlay import LegendEntry, composite, overlay_layer

DEMOS = ("stairs", "snow-bunny", "normals")


@dataclass
class Demo:
    """A simulation and how to show it.

    Attributes
    ----------
    name : str
    sim : StairsSim or SnowSim or NormalsSim
        Has ``step() -> dict`` and ``layers() -> dict``.
    look : Look
    title : str
    fps : int
        Playback rate of written videos.
    arrow : float
        World length of the normal arrow drawn from each contact mark.
    counted : str
        What one mark stands for, in the text panel: "<counted>: N".
    legend : list of LegendEntry
    """

    name: str
    sim: Any
    look: Look
    title: str
    fps: int
    arrow: float
    counted: str = "contacts"
    legend: list[LegendEntry] = field(default_factory=list)


def make_demo(name: str, *, seed: int = 0, tolerance: float | None = None,
              spheres: int | None = None, scan: bool = False, close_holes: bool = False) -> Demo:
    """The demo ``name`` (one of :data:`DEMOS`), its simulation set up."""
    if name == "stairs":
        from . import stairs

        sim = stairs.StairsSim(spheres or 50, seed, tolerance)
        return Demo(name, sim, stairs.LOOK, f"Stairs: {sim.spheres} spheres, {stairs.STEPS} steps",
                    stairs.FPS, 1.6 * stairs.RADIUS, legend=[
                        LegendEntry("contact, with its normal (from the first body into the "
                                    "second)", "normal"),
                        _swatch("sphere touching a step, the floor or a sphere",
                                stairs.TOUCH_COLOUR),
                        _swatch("step touched by a sphere", stairs.STEP_TOUCH_COLOUR)])
    if name == "snow-bunny":
        from . import snow

        sim = snow.SnowSim(spheres or 150, seed, tolerance, scan=scan, close_holes=close_holes)
        return Demo(name, sim, snow.LOOK, f"Snow Bunny: {sim.note}", snow.FPS,
                    4 * snow.FLAKE_SIZE, legend=[
                        LegendEntry("a flake landing on the bunny or the floor: its contact "
                                    "and normal", "normal"),
                        _swatch("frozen flake (no longer checked)", snow.FROZEN_COLOUR)])
    if name == "normals":
        from . import edge_colours as normals

        sim = normals.NormalsSim(spheres or 24, seed, tolerance)
        return Demo(name, sim, normals.LOOK, "Edges coloured by normals", normals.FPS,
                    1.5 * normals.RADIUS, legend=[
                        LegendEntry("contact of a sphere with the bunny, with the normal read "
                                    "from", "normal"),
                        LegendEntry("  the bunny's records (encode='normal'): the bounce",
                                    "none"),
                        _swatch("sphere touching the bunny", normals.TOUCH_COLOUR)])
    raise ValueError(f"unknown demo {name!r}; choose from {DEMOS}")


def _swatch(text: str, colour: tuple[float, float, float]) -> LegendEntry:
    return LegendEntry(text, "swatch", tuple(int(round(255 * c)) for c in colour))


def draw_overlay(demo: Demo, display: Display, info: dict, lines: list[str]
                 ) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The overlay of one frame.

    Parameters
    ----------
    demo : Demo
    display : Display
        Its camera places the marks.
    info : dict
        What ``sim.step()`` returned: ``marks`` (M, 3) contact points and ``normals`` (M, 3)
        their normals.
    lines : list of str
        The text panel's first lines; the count of marks drawn is added.

    Returns
    -------
    layer : (H, W, 4) uint8
        RGBA overlay.
    drawn : (m, 2) float
        Pixel centres of the marks drawn (those inside the frame), m <= M.
    lines : list of str
        The text panel as drawn.
    """
    marks = np.asarray(info["marks"], float).reshape(-1, 3)
    xy, inside = display.project(marks)
    drawn = xy[inside]
    count = f"{demo.counted}: {len(drawn)}"
    if not inside.all():
        count += f" (+{int((~inside).sum())} outside the frame)"
    lines = lines + [count]
    normals = np.asarray(info["normals"], float).reshape(-1, 3)
    ends = display.project(marks + demo.arrow * normals)[0][inside]
    legend = list(demo.legend)
    if demo.name == "normals":
        legend.append(LegendEntry("edge colour: its encoded normal n as 0.5 + 0.5 n",
                                  "image", image=display.normal_ball()))
        legend.append(LegendEntry("  (x red, y green, z blue; the ball shows this view)", "none"))
    layer = overlay_layer(display.size, lines=lines, legend=legend, marks=drawn, normal_ends=ends,
                          legend_right=demo.look.legend_right)
    return layer, drawn, lines


def run(name: str, *, frames: int = 120, out: str | None = None, window: bool = False,
        tolerance: float | None = None, seed: int = 0, spheres: int | None = None,
        scan: bool = False, close_holes: bool = False, size: tuple[int, int] = (640, 480),
        quiet: bool = False, progress: Any = None) -> dict[str, Any]:
    """Run ``frames`` frames; write them to ``out`` (.mp4, .gif or a folder) and return a summary.

    Returns
    -------
    dict
        ``sim``, ``counts`` (contacts per frame), ``ms`` (detection time per frame),
        ``summary`` (one line), and when frames were drawn ``marks`` (per frame, the (m, 2)
        pixel centres of the marks drawn) and ``lines`` (per frame, the text panel).
    """
    if window:
        if not display_available():
            raise RuntimeError("--window needs a display (no DISPLAY or WAYLAND_DISPLAY is set); "
                               "run headless with --out FILE.mp4 instead")
        return run_window(name, frames=frames, tolerance=tolerance, seed=seed, spheres=spheres,
                          scan=scan, close_holes=close_holes, size=size)
    display = None
    if out:
        from .shared import shared_device

        shared_device()  # before the simulation's detector takes a device of its own
    demo = make_demo(name, seed=seed, tolerance=tolerance, spheres=spheres, scan=scan,
                     close_holes=close_holes)
    if out:
        display = Display(demo.look, size)
    writer = FrameWriter(out, fps=demo.fps)
    counts, times, marks, panels = [], [], [], []
    t_start = time.perf_counter()
    for k in range(frames):
        info = demo.sim.step()
        counts.append(len(info["marks"]))
        times.append(info["ms"])
        if display is not None:
            if hasattr(demo.sim, "view_box"):  # a camera that keeps the moving bodies in view
                display.follow(demo.sim.view_box(), demo.sim.view_direction)
            display.update(demo.sim.layers())
            image = display.render()
            layer, drawn, lines = draw_overlay(
                demo, display, info,
                [demo.title, f"frame {k + 1}/{frames}, detection {info['ms']:.1f} ms"])
            writer.add(composite(image, layer))
            marks.append(drawn)
            panels.append(lines)
        if progress:
            progress(k + 1, frames)
    writer.close()
    extra = {"wall s": round(time.perf_counter() - t_start, 1)}
    if out:
        extra["wrote"] = out
    extra.update(_extra(demo))
    text = summary(name, counts, times, extra)
    if not quiet:
        print(text)
    result = {"sim": demo.sim, "counts": counts, "ms": times, "summary": text}
    if display is not None:
        result.update(marks=marks, lines=panels)
    return result


def _extra(demo: Demo) -> dict[str, Any]:
    sim = demo.sim
    if demo.name == "stairs":
        return {"descents (a sphere on all 11 steps)": sim.descents,
                "sphere-sphere contacts resolved": sim.sphere_contacts}
    if demo.name == "snow-bunny":
        extra = {"flakes landed": sim.landed}
        if sim.warnings:
            extra["warning"] = sim.warnings[0]
        return extra
    return {"bounces": sim.bounces}


def run_window(name: str, frames: int | None = None, size: tuple[int, int] = (640, 480),
               **kwargs: Any) -> dict[str, Any]:
    """An interactive window through rendercanvas: drag to orbit the camera, scroll to zoom;
    in the snow-bunny demo the a and d keys turn the bunny. Closes after ``frames`` frames if
    given, else when closed."""
    from .shared import shared_device

    shared_device()
    demo = make_demo(name, **kwargs)
    display = Display(demo.look, size, window=True, title=f"pycinder - {demo.title}")
    from rendercanvas.auto import loop

    state: dict[str, list] = {"counts": [], "ms": []}

    def on_key(event: dict) -> None:
        if name == "snow-bunny" and event.get("key") in ("a", "d"):
            demo.sim.angle += 0.2 if event["key"] == "d" else -0.2

    display.renderer.add_event_handler(on_key, "key_down")

    def animate() -> None:
        if frames is not None and len(state["counts"]) >= frames:
            display.canvas.close()
            return
        info = demo.sim.step()
        state["counts"].append(len(info["marks"]))
        state["ms"].append(info["ms"])
        display.update(demo.sim.layers())
        layer, _, _ = draw_overlay(demo, display, info, [
            demo.title, f"detection {info['ms']:.1f} ms (drag to orbit, scroll to zoom)"])
        display.draw_window(layer)

    display.canvas.request_draw(animate)
    loop.run()
    text = summary(name, state["counts"], state["ms"], _extra(demo))
    print(text, file=sys.stderr)
    return {"sim": demo.sim, "counts": state["counts"], "ms": state["ms"], "summary": text}

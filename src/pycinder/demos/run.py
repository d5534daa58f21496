"""``pycinder demo {stairs,snow-bunny,normals}``: run a demo headless or in a window."""

from __future__ import annotations

import sys
import time
from typing import Any

import numpy as np

from .render import FrameWriter, Renderer, display_available, mark_points, overlay, summary

DEMOS = ("stairs", "snow-bunny", "normals")


def make_sim(name: str, *, seed: int, tolerance: float | None, spheres: int | None = None,
             scan: bool = False, close_holes: bool = False) -> tuple[Any, Any, str]:
    """The simulation, its display view and a title."""
    if name == "stairs":
        from . import stairs

        sim = stairs.StairsSim(spheres or 50, seed, tolerance)
        return sim, stairs.display_view(), f"Stairs, {sim.spheres} spheres"
    if name == "snow-bunny":
        from . import snow

        sim = snow.SnowSim(spheres or 150, seed, tolerance, scan=scan,
                           close_holes=close_holes)
        return sim, snow.display_view(), f"Snow Bunny ({sim.note})"
    if name == "normals":
        from . import normals

        sim = normals.NormalsSim(spheres or 24, seed, tolerance)
        return sim, normals.display_view(), "Edges coloured by normals"
    raise ValueError(f"unknown demo {name!r}; choose from {DEMOS}")


def display_scene(name: str, sim: Any, info: dict) -> tuple[list, np.ndarray, np.ndarray]:
    if name == "stairs":
        from .stairs import colours

        return info["bodies"], info["transforms"], colours(len(info["bodies"]))
    return sim.scene_for_display()


def run(name: str, *, frames: int = 120, out: str | None = None, window: bool = False,
        tolerance: float | None = None, seed: int = 0, spheres: int | None = None, scan: bool = False,
        close_holes: bool = False, size: tuple[int, int] = (640, 480), quiet: bool = False,
        progress: Any = None) -> dict[str, Any]:
    """Run ``frames`` frames; write them to ``out`` (.mp4, .gif or a folder) and return a summary."""
    if window:
        if not display_available():
            raise RuntimeError("--window needs a display (no DISPLAY or WAYLAND_DISPLAY is set); "
                               "run headless with --out FILE.mp4 instead")
        return run_window(name, frames=frames, tolerance=tolerance, seed=seed, spheres=spheres,
                          scan=scan, close_holes=close_holes)
    sim, view, title = make_sim(name, seed=seed, tolerance=tolerance, spheres=spheres, scan=scan,
                                close_holes=close_holes)
    renderer = Renderer(sim.detector, *size) if out else None
    writer = FrameWriter(out)
    counts, times = [], []
    t_start = time.perf_counter()
    for k in range(frames):
        info = sim.step()
        counts.append(info["pairs"])
        times.append(info["ms"])
        if renderer is not None:
            bodies, transforms, colours = display_scene(name, sim, info)
            image = renderer.render(bodies, transforms, colours, view)
            marks = info["marks"] if "marks" in info else info["result"].points()
            mark_points(image, view, marks)
            image = overlay(image, [title, f"frame {k + 1}/{frames}",
                                    f"collisions {info['pairs']}",
                                    f"detection {info['ms']:.1f} ms"])
            writer.add(image)
        if progress:
            progress(k + 1, frames)
    writer.close()
    extra = {"wall s": round(time.perf_counter() - t_start, 1)}
    if out:
        extra["wrote"] = out
    if name == "snow-bunny":
        extra["frozen flakes"] = len(sim.frozen)
        if sim.warnings:
            extra["warning"] = sim.warnings[0]
    if name == "normals":
        extra["bounces"] = sim.bounces
    text = summary(name, counts, times, extra)
    if not quiet:
        print(text)
    return {"sim": sim, "counts": counts, "ms": times, "summary": text}


def run_window(name: str, frames: int | None = None, **kwargs: Any) -> dict[str, Any]:
    """An interactive window through rendercanvas: the arrow keys turn the display camera, and in
    the snow-bunny demo the a and d keys turn the bunny. Closes after ``frames`` frames if given."""
    from rendercanvas.auto import RenderCanvas, loop

    sim, view, title = make_sim(name, **kwargs)
    renderer = Renderer(sim.detector, 640, 480)
    canvas = RenderCanvas(title=f"pycinder - {title}", size=(640, 480))
    context = canvas.get_context("bitmap")
    state = {"yaw": 0.0, "counts": [], "ms": []}

    def on_key(event: dict) -> None:
        if event.get("key") == "ArrowLeft":
            state["yaw"] -= 0.1
        elif event.get("key") == "ArrowRight":
            state["yaw"] += 0.1
        if name == "snow-bunny" and event.get("key") in ("a", "d"):
            sim.angle += 0.2 if event["key"] == "d" else -0.2

    canvas.add_event_handler(on_key, "key_down")

    @canvas.request_draw
    def draw() -> None:
        if frames is not None and len(state["counts"]) >= frames:
            canvas.close()
            return
        info = sim.step()
        state["counts"].append(info["pairs"])
        state["ms"].append(info["ms"])
        bodies, transforms, colours = display_scene(name, sim, info)
        rot = np.eye(4)
        c, s = np.cos(state["yaw"]), np.sin(state["yaw"])
        rot[[0, 0, 2, 2], [0, 2, 0, 2]] = [c, s, -s, c]
        from ..view import View

        v = View(view.view @ rot, view.projection)
        image = renderer.render(bodies, transforms, colours, v)
        mark_points(image, v, info["marks"] if "marks" in info else info["result"].points())
        image = overlay(image, [title, f"collisions {info['pairs']}", f"{info['ms']:.1f} ms"])
        context.set_bitmap(np.dstack([image, np.full(image.shape[:2], 255, np.uint8)]))
        canvas.request_draw()

    loop.run()
    text = summary(name, state["counts"], state["ms"])
    print(text, file=sys.stderr)
    return {"sim": sim, "counts": state["counts"], "ms": state["ms"], "summary": text}

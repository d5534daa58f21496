"""Headless display of a demo scene on the detector's own device, plus video/GIF/PNG output."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import wgpu

from ..detector import Detector
from ..gpu.buffers import SceneBuffers
from ..gpu.device import shader_source
from ..scene import ShapeCache, prepare_scene, repack
from ..view import View

COLOUR_FORMAT = "rgba8unorm"


class Renderer:
    """Draws bodies lit through a display camera, on the detector's device.

    The display camera is independent of the views CInDeR renders through (paper 4.2), and the
    display may show bodies that detection no longer checks (frozen snowflakes).
    """

    def __init__(self, detector: Detector, width: int = 640, height: int = 480) -> None:
        self.det, self.width, self.height = detector, width, height
        device = detector.gpu.device
        self.buffers = SceneBuffers(device)
        self._shapes = ShapeCache()
        module = device.create_shader_module(label="shade", code=shader_source("shade"))
        self.pipeline = device.create_render_pipeline(
            label="display", layout="auto",
            vertex={"module": module, "entry_point": "vs_main"},
            primitive={"topology": "triangle-list", "cull_mode": "back", "front_face": "ccw"},
            depth_stencil={"format": "depth24plus", "depth_write_enabled": True,
                           "depth_compare": "less"},
            fragment={"module": module, "entry_point": "fs_main",
                      "targets": [{"format": COLOUR_FORMAT}]})
        tex = wgpu.TextureUsage
        self.colour = device.create_texture(size=(width, height, 1), format=COLOUR_FORMAT,
                                            usage=tex.RENDER_ATTACHMENT | tex.COPY_SRC)
        self.depth = device.create_texture(size=(width, height, 1), format="depth24plus",
                                           usage=tex.RENDER_ATTACHMENT)
        self.bodies = None
        self._bind_key: tuple | None = None
        self._bind_group = None

    def render(self, bodies: list[Any], transforms: np.ndarray, colours: np.ndarray,
               view: View) -> np.ndarray:
        """(H, W, 3) uint8 image.

        bodies : trimesh meshes or (vertices, faces) pairs
        transforms : (N, 4, 4) world from body
        colours : (N, 3) float in [0, 1]
        """
        device = self.det.gpu.device
        scene = prepare_scene(bodies, transforms, cache=self._shapes)
        self.buffers.upload(repack(self.buffers.scene, scene, normals=True))
        buffers = self.buffers
        transforms = np.asarray(transforms, dtype=np.float64)
        n = len(transforms)
        data = np.zeros((n, 36), np.float32)
        clip = np.einsum("ij,njk->nik", view.projection @ view.view, transforms)
        data[:, :16] = np.transpose(clip, (0, 2, 1)).reshape(n, 16)
        data[:, 16:32] = np.transpose(transforms, (0, 2, 1)).reshape(n, 16)
        data[:, 32:35] = colours
        data[:, 35] = 1.0
        if self.bodies is None or self.bodies.size < data.nbytes:
            self.bodies = device.create_buffer(size=max(data.nbytes, 256) * 2,
                                               usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_DST)
        device.queue.write_buffer(self.bodies, 0, data)
        key = (buffers.generation, id(self.bodies))
        if key != self._bind_key:
            s = buffers.storage
            self._bind_group = device.create_bind_group(
                layout=self.pipeline.get_bind_group_layout(0),
                entries=[{"binding": 0, "resource": {"buffer": s["positions"].buffer}},
                         {"binding": 1, "resource": {"buffer": s["vertex_body"].buffer}},
                         {"binding": 2, "resource": {"buffer": s["vertex_normals"].buffer}},
                         {"binding": 3, "resource": {"buffer": self.bodies}}])
            self._bind_key = key
        enc = device.create_command_encoder()
        rp = enc.begin_render_pass(
            color_attachments=[{"view": self.colour.create_view(), "load_op": "clear",
                                "store_op": "store", "clear_value": (0.93, 0.94, 0.97, 1)}],
            depth_stencil_attachment={"view": self.depth.create_view(), "depth_clear_value": 1.0,
                                      "depth_load_op": "clear", "depth_store_op": "discard"})
        rp.set_pipeline(self.pipeline)
        rp.set_bind_group(0, self._bind_group)
        rp.set_index_buffer(buffers.index.buffer, wgpu.IndexFormat.uint32)
        rp.draw_indexed(len(buffers.scene.indices))
        rp.end()
        device.queue.submit([enc.finish()])
        row = -(-self.width * 4 // 256) * 256
        raw = device.queue.read_texture({"texture": self.colour},
                                        {"bytes_per_row": row, "rows_per_image": self.height},
                                        (self.width, self.height, 1))
        img = np.frombuffer(raw, np.uint8).reshape(self.height, row)[:, :self.width * 4]
        return img.reshape(self.height, self.width, 4)[..., :3].copy()


def mark_points(image: np.ndarray, view: View, points: np.ndarray, *, size: int = 3,
                colour: tuple[int, int, int] = (150, 40, 200)) -> int:
    """Draw the paper's purple rectangles at world ``points`` (n, 3); returns how many landed."""
    if len(points) == 0:
        return 0
    h, w = image.shape[:2]
    p = view.project(points, w, h)
    ok = (p[:, 2] > 0) & (p[:, 2] < 1) & (p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)
    for x, y in p[ok, :2].astype(int):
        image[max(y - size, 0):y + size + 1, max(x - size, 0):x + size + 1] = colour
        image[max(y - size + 1, 0):y + size, max(x - size + 1, 0):x + size] = (240, 220, 255)
    return int(ok.sum())


def overlay(image: np.ndarray, lines: list[str]) -> np.ndarray:
    """Text in the top-left corner (Pillow)."""
    from PIL import Image, ImageDraw

    img = Image.fromarray(image)
    draw = ImageDraw.Draw(img)
    draw.rectangle((4, 4, 8 + 7 * max(len(s) for s in lines), 8 + 13 * len(lines)),
                   fill=(255, 255, 255))
    for i, s in enumerate(lines):
        draw.text((7, 6 + 13 * i), s, fill=(20, 20, 30))
    return np.asarray(img)


class FrameWriter:
    """Writes frames to an MP4 (imageio-ffmpeg), a GIF, or a folder of PNGs."""

    def __init__(self, out: str | Path | None, fps: int = 30) -> None:
        self.out = Path(out) if out else None
        self.fps, self.count, self._writer, self._gif = fps, 0, None, []
        if self.out is None:
            return
        suffix = self.out.suffix.lower()
        if suffix in (".mp4", ".gif"):
            self.out.parent.mkdir(parents=True, exist_ok=True)
        else:
            self.out.mkdir(parents=True, exist_ok=True)
        if suffix == ".mp4":
            import imageio.v2 as imageio

            self._writer = imageio.get_writer(self.out, fps=fps, codec="libx264", quality=7,
                                              macro_block_size=8)

    def add(self, image: np.ndarray) -> None:
        if self.out is None:
            return
        suffix = self.out.suffix.lower()
        if suffix == ".mp4":
            self._writer.append_data(image)
        elif suffix == ".gif":
            self._gif.append(image)
        else:
            from ..debug import png_bytes

            (self.out / f"frame_{self.count:04d}.png").write_bytes(png_bytes(image))
        self.count += 1

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
        if self._gif:
            from PIL import Image

            frames = [Image.fromarray(f) for f in self._gif]
            frames[0].save(self.out, save_all=True, append_images=frames[1:],
                           duration=int(1000 / self.fps), loop=0)


def display_available() -> bool:
    import os

    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or \
        __import__("sys").platform in ("win32", "darwin")


def summary(name: str, counts: list[int], ms: list[float], extra: dict[str, Any] | None = None) -> str:
    parts = [f"{name}: {len(counts)} frames",
             f"collisions per frame: mean {np.mean(counts):.1f}, max {max(counts) if counts else 0}",
             f"median detection {np.median(ms):.1f} ms" if ms else "no detections"]
    for k, v in (extra or {}).items():
        parts.append(f"{k}: {v}")
    return "; ".join(parts)

"""``pycinder debug-buffers``: the buffers after each pass, as in the paper's Figures 9 to 13.

Each stage is rendered in its own render pass, so that depth, stencil and colour can be captured
between passes; the normal path records passes 1-4 and 5-7 as two passes of replayed bundles.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
import wgpu

from .detector import Detector
from .gpu.device import shader_source
from .passes.raycast import RaycastPasses
from .passes.states import RenderStep
from .view import View


def three_boxes() -> tuple[list[trimesh.Trimesh], list[str], View]:
    """The paper's test scene (Figure 7): three equal boxes at different depths, red in front.

    Red overlaps green and green overlaps blue; red and blue are apart. Returns the boxes, their
    names and a perspective view from the front, as in the paper's figures.
    """
    centres = [(-0.45, -0.3, 0.6), (0.0, 0.0, 0.0), (0.45, 0.3, -0.6)]
    boxes = [trimesh.creation.box((1, 1, 1), trimesh.transformations.translation_matrix(c))
             for c in centres]
    view = View.look_at(eye=(1.2, 1.0, 4.0), target=(0, 0, 0), fov_y=50.0, near=1.5, far=8.0)
    return boxes, ["red", "green", "blue"], view


def png_bytes(image: np.ndarray) -> bytes:
    """Encode an (H, W, 3) uint8 or (H, W) uint8 image as PNG."""
    image = np.ascontiguousarray(image, dtype=np.uint8)
    h, w = image.shape[:2]
    colour = 2 if image.ndim == 3 else 0
    raw = b"".join(b"\x00" + image[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", w, h, 8, colour, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 6)) \
        + chunk(b"IEND", b"")


def id_colours(ids: np.ndarray) -> np.ndarray:
    """A distinct colour per id (0 is black): (..., 3) uint8."""
    palette = np.array([[0, 0, 0], [230, 50, 50], [60, 200, 60], [60, 90, 230], [240, 200, 40],
                        [200, 60, 220], [40, 210, 220], [250, 140, 30], [150, 150, 150]], np.uint8)
    ids = np.asarray(ids, dtype=np.int64)
    out = palette[np.where(ids == 0, 0, 1 + (ids - 1) % (len(palette) - 1))]
    return out


def stencil_image(stencil: np.ndarray) -> np.ndarray:
    """Counts as colours: 0 black, +n green, -n (wrapped) red."""
    signed = np.where(stencil > 127, stencil.astype(np.int64) - 256, stencil.astype(np.int64))
    img = np.zeros(stencil.shape + (3,), np.uint8)
    img[..., 1] = np.clip(signed, 0, 3) * 85
    img[..., 0] = np.clip(-signed, 0, 3) * 85
    return img


def record_image(records: np.ndarray) -> np.ndarray:
    """Colour after passes 4 and 7: left half of each pixel's hue from r, shown as a blend."""
    r = id_colours(records[..., 0]).astype(np.uint16)
    g = id_colours(records[..., 1]).astype(np.uint16)
    both = (records[..., 1] > 0)[..., None]
    return np.where(both, (r + g) // 2, r).astype(np.uint8)


class BufferCapture:
    """Runs the passes one render pass at a time and reads the buffers between them."""

    def __init__(self, detector: Detector) -> None:
        self.det = detector
        device = detector.gpu.device
        module = device.create_shader_module(label="debug", code=shader_source("debug"))
        self.pipeline = device.create_compute_pipeline(
            layout="auto", compute={"module": module, "entry_point": "dump"})
        t = detector.targets
        usage = wgpu.BufferUsage
        self.depth_buf = device.create_buffer(size=4 * t.pixels, usage=usage.STORAGE | usage.COPY_SRC)
        self.stencil_buf = device.create_buffer(size=4 * t.pixels,
                                                usage=usage.STORAGE | usage.COPY_SRC)
        params = device.create_buffer(size=16, usage=usage.UNIFORM | usage.COPY_DST)
        device.queue.write_buffer(params, 0, np.array([t.width, t.height, 0, 0], np.uint32))
        self.bind_group = device.create_bind_group(
            layout=self.pipeline.get_bind_group_layout(0),
            entries=[{"binding": 0, "resource": t.depth_view},
                     {"binding": 1, "resource": t.stencil_view},
                     {"binding": 2, "resource": {"buffer": self.depth_buf}},
                     {"binding": 3, "resource": {"buffer": self.stencil_buf}},
                     {"binding": 4, "resource": {"buffer": params}}])

    def _dump_depth_stencil(self) -> tuple[np.ndarray, np.ndarray]:
        t, device = self.det.targets, self.det.gpu.device
        enc = device.create_command_encoder()
        cpass = enc.begin_compute_pass()
        cpass.set_pipeline(self.pipeline)
        cpass.set_bind_group(0, self.bind_group)
        cpass.dispatch_workgroups(-(-t.width // 8), -(-t.height // 8))
        cpass.end()
        device.queue.submit([enc.finish()])
        depth = np.frombuffer(device.queue.read_buffer(self.depth_buf), np.float32)
        stencil = np.frombuffer(device.queue.read_buffer(self.stencil_buf), np.uint32)
        return depth.reshape(t.height, t.width), stencil.reshape(t.height, t.width)

    def _records(self) -> np.ndarray:
        t, device = self.det.targets, self.det.gpu.device
        return np.asarray(device.queue.read_texture(
            {"texture": t.records}, {"bytes_per_row": 16 * t.width, "rows_per_image": t.height},
            (t.width, t.height, 1))).view(np.uint32).reshape(t.height, t.width, 4)

    def capture(self, bodies: list[Any], transforms: Any = None, view: View | None = None
                ) -> dict[str, np.ndarray]:
        """Buffers after each stage, keyed by a file-name stem."""
        det = self.det
        scene, transforms_arr, views = det.prepare(bodies, transforms, view=view)
        det.set_view(views[0], transforms_arr)
        device = det.gpu.device
        raycast = det.raycast
        bind_group = raycast.bind_group(det.buffers, det.targets)
        out: dict[str, np.ndarray] = {}
        names = {1: "pass1_depth", 2: "pass2_stencil", 3: "pass3_stencil", 4: "pass4_colour",
                 7: "pass7_colour"}
        for step in raycast.plan:
            # Split each step where a buffer is captured; the steps' own starts stay as they are.
            chunks, current = [], []
            for n in step.passes:
                current.append(n)
                if n in names:
                    chunks.append(tuple(current))
                    current = []
            for k, passes in enumerate(chunks):
                enc = device.create_command_encoder()
                if k == 0:
                    rp = RaycastPasses.begin_step(enc, det.targets, step)
                else:
                    rp = RaycastPasses.begin_step(enc, det.targets, RenderStep(passes, False, False))
                raycast.record(rp, passes, det.buffers, bind_group)
                rp.end()
                device.queue.submit([enc.finish()])
                name = names[passes[-1]]
                if name.endswith("colour"):
                    out[name] = self._records()
                else:
                    depth, stencil = self._dump_depth_stencil()
                    out[name] = depth if name.endswith("depth") else stencil
        enc = device.create_command_encoder()
        det.filter.encode(enc, det.targets)
        device.queue.submit([enc.finish()])
        if det.filter.output == "full":
            data = np.frombuffer(device.queue.read_buffer(det.filter.out.buffer), np.uint32)
            out["filtered_colour"] = data[: 4 * det.targets.pixels].reshape(
                det.targets.height, det.targets.width, 4)
        return out


def to_image(name: str, data: np.ndarray) -> np.ndarray:
    if name.endswith("depth"):
        return np.repeat((np.clip(data, 0, 1) * 255).astype(np.uint8)[..., None], 3, axis=2)
    if name.endswith("stencil"):
        return stencil_image(data)
    return record_image(data)


def write_debug_buffers(bodies: list[Any] | None, out_dir: str | Path, *, resolution: int = 512,
                        transforms: Any = None, view: View | None = None,
                        self_interference: str = "filter") -> list[Path]:
    """Write PNGs of the buffers after passes 1, 2, 3, 4, 7 and after filtering.

    Without bodies, the paper's three-box scene is used.
    """
    if bodies is None:
        bodies, _, view = three_boxes()
    det = Detector(resolution, self_interference=self_interference, readback="full")
    buffers = BufferCapture(det).capture(bodies, transforms, view)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for k, (name, data) in enumerate(buffers.items()):
        path = out / f"{k + 1:02d}_{name}.png"
        path.write_bytes(png_bytes(to_image(name, data)))
        paths.append(path)
    return paths

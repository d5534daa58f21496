"""``pycinder debug-buffers``: the buffers after each pass, as in the paper's Figures 9 to 13.

The whole-scene strategy's frame runs each pass in its own render pass when given a hook, so that
depth, stencil and colour can be captured between passes; the normal path replays one bundle per
render step.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
import wgpu

from ..detector import Detector
from ..gpu.bindings import Stage
from ..gpu.states import STENCIL_MASK
from ..result import Stats
from ..scene import prepare_scene
from ..view import View


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
    """Runs the whole-scene strategy's passes one render pass at a time (the frame's hook) and
    reads the buffers between them, on any backend.

    The depth buffer after pass 1 is read from the colour target's b channel, which pass 1 fills
    with the same edges' depth bits during a capture; the stencil buffer with one stencil-equal
    full-screen draw per value (``debug_stencil.wgsl``).
    """

    def __init__(self, detector: Detector) -> None:
        if detector.request.strategy != "scene":
            raise ValueError("debug-buffers shows the paper's whole-scene passes: use a Detector "
                             "with strategy='scene'")
        self.det = detector
        self.strategy = detector.strategy
        device = detector.gpu.device
        t = self.strategy.targets
        equal = {"compare": "equal", "fail_op": "keep", "depth_fail_op": "keep", "pass_op": "keep"}
        self.pipeline = Stage(detector.gpu, "debug_stencil", label="stencil readout", render={
            "primitive": {"topology": "triangle-list"},
            "depth_stencil": {"format": detector.gpu.depth_format, "depth_write_enabled": False,
                              "depth_compare": "always", "stencil_front": equal,
                              "stencil_back": equal, "stencil_read_mask": STENCIL_MASK,
                              "stencil_write_mask": 0},
            "targets": [{"format": "r8uint"}]}).pipeline
        self.stencil = device.create_texture(
            size=(t.width, t.height, 1), format="r8uint",
            usage=wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC)

    def _read(self, texture: wgpu.GPUTexture, bytes_per_pixel: int, dtype: type,
              channels: int) -> np.ndarray:
        t = self.strategy.targets
        row = -(-t.width * bytes_per_pixel // 256) * 256
        raw = self.det.gpu.device.queue.read_texture(
            {"texture": texture}, {"bytes_per_row": row, "rows_per_image": t.height},
            (t.width, t.height, 1))
        data = np.frombuffer(raw, np.uint8).reshape(t.height, row)[:, :t.width * bytes_per_pixel]
        return data.copy().view(dtype).reshape(t.height, t.width, channels)

    def _stencil(self) -> np.ndarray:
        device = self.det.gpu.device
        encoder = device.create_command_encoder()
        rp = encoder.begin_render_pass(
            color_attachments=[{"view": self.stencil.create_view(), "load_op": "clear",
                                "store_op": "store", "clear_value": (0, 0, 0, 0)}],
            depth_stencil_attachment={"view": self.strategy.targets.depth_stencil_view,
                                      "depth_load_op": "load", "depth_store_op": "store",
                                      "stencil_load_op": "load", "stencil_store_op": "store"})
        rp.set_pipeline(self.pipeline)
        for value in range(1, 256):
            rp.set_stencil_reference(value)
            rp.draw(3, 1, 0, value)
        rp.end()
        device.queue.submit([encoder.finish()])
        return self._read(self.stencil, 1, np.uint8, 1)[..., 0].astype(np.uint32)

    def capture(self, bodies: list[Any], transforms: Any = None, view: View | None = None
                ) -> dict[str, np.ndarray]:
        """Buffers after each stage, keyed by a file-name stem."""
        strategy = self.strategy
        scene = prepare_scene(bodies, transforms, cache=self.det.shapes)
        stats = Stats(strategy="scene")
        _, views = strategy.prepare(scene, view, stats)
        strategy.set_view(views[0], scene)
        out: dict[str, np.ndarray] = {}
        names = {"pass 1": "pass1_depth", "pass 2": "pass2_stencil", "pass 3": "pass3_stencil",
                 "pass 4": "pass4_colour", "pass 7": "pass7_colour"}

        def hook(stage: str) -> None:
            name = names.get(stage)
            if name == "pass1_depth":
                colour = self._read(strategy.targets.records, 16, np.uint32, 4)
                out[name] = colour[..., 2].view(np.float32)
            elif name is not None and name.endswith("stencil"):
                out[name] = self._stencil()
            elif name is not None:
                out[name] = self._read(strategy.targets.records, 16, np.uint32, 4)

        strategy.frame.run(stats, hook)
        if strategy.filter.output == "full":
            data = np.frombuffer(self.det.gpu.device.queue.read_buffer(strategy.filter.out.buffer),
                                 np.uint32)
            t = strategy.targets
            out["filtered_colour"] = data[: 4 * t.pixels].reshape(t.height, t.width, 4)
        return out


DEPTH_NEAR, DEPTH_FAR = 0.3, 1.0
"""Grey levels of the nearest and the farthest edge in a depth image."""


def depth_image(depth: np.ndarray) -> np.ndarray:
    """Depth after pass 1 ((H, W) float32, 0 where no edge was drawn) as (H, W, 3) uint8 grey.

    A perspective depth buffer puts every edge close to 1, so the depths are stretched over the
    range the edges span: the nearest edge grey :data:`DEPTH_NEAR`, the farthest white, no edge
    black.
    """
    edge = depth > 0
    grey = np.zeros(depth.shape, np.float64)
    if edge.any():
        lo, hi = float(depth[edge].min()), float(depth[edge].max())
        t = (depth[edge] - lo) / (hi - lo) if hi > lo else np.ones(int(edge.sum()))
        grey[edge] = DEPTH_NEAR + (DEPTH_FAR - DEPTH_NEAR) * t
    return np.repeat(np.round(grey * 255).astype(np.uint8)[..., None], 3, axis=2)


def to_image(name: str, data: np.ndarray) -> np.ndarray:
    """A captured buffer as an (H, W, 3) uint8 image: depth as grey, stencil counts as colours,
    records by body colour."""
    if name.endswith("depth"):
        return depth_image(data)
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
    det = Detector(strategy="scene", resolution=resolution, self_interference=self_interference,
                   readback="full")
    buffers = BufferCapture(det).capture(bodies, transforms, view)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for k, (name, data) in enumerate(buffers.items()):
        path = out / f"{k + 1:02d}_{name}.png"
        path.write_bytes(png_bytes(to_image(name, data)))
        paths.append(path)
    return paths

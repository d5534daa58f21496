"""Where demo frames go (an MP4 through imageio-ffmpeg, a GIF, or a folder of PNGs), whether a
window can open, and the one-line summary of a run."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

import numpy as np


class FrameWriter:
    """Writes frames to an MP4 (imageio-ffmpeg), a GIF, or a folder of PNGs.

    Parameters
    ----------
    out : str or Path or None
        ``*.mp4``, ``*.gif``, or a folder (created) for ``frame_0000.png``, ...; None writes
        nothing.
    fps : int
        Frames per second of the MP4 or GIF.
    """

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
        """Append one (H, W, 3) uint8 frame."""
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
        """Finish the file (the GIF is written here)."""
        if self._writer is not None:
            self._writer.close()
        if self._gif:
            from ..montage import pillow

            Image = pillow().Image

            frames = [Image.fromarray(f) for f in self._gif]
            frames[0].save(self.out, save_all=True, append_images=frames[1:],
                           duration=int(1000 / self.fps), loop=0)


def display_available() -> bool:
    """Whether a window can open: a display is set, or the platform always has one."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or \
        sys.platform in ("win32", "darwin")


def summary(name: str, counts: list[int], ms: list[float], extra: dict[str, Any] | None = None
            ) -> str:
    """One line: frames, contacts per frame, median detection time, then ``extra`` items."""
    parts = [f"{name}: {len(counts)} frames",
             f"contacts per frame: mean {np.mean(counts):.1f}, max {max(counts) if counts else 0}",
             f"median detection {np.median(ms):.1f} ms" if ms else "no detections"]
    for k, v in (extra or {}).items():
        parts.append(f"{k}: {v}")
    return "; ".join(parts)

"""Where demo frames go (an MP4 through imageio-ffmpeg, a GIF, or a folder of PNGs), whether a
window can open, and the one-line summary of a run.

An output path is a video when it ends in one of :data:`VIDEO_SUFFIXES`, and a folder of PNGs
when it has no suffix, ends in a path separator or is a folder already; any other suffix
(``st.avi``) is an error that names the suffixes written (see :func:`output_kind`).
"""

from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..util.text import plural

VIDEO_SUFFIXES = (".mp4", ".gif")
"""The video files written: an MP4 (imageio-ffmpeg, H.264) and an animated GIF (Pillow)."""


def output_kind(out: str | os.PathLike[str]) -> str:
    """What ``out`` names: ``".mp4"``, ``".gif"`` or ``"folder"`` (of PNG frames).

    Raises
    ------
    ValueError
        For a suffix that is not a video written here (``st.avi``), naming the suffixes that are.
    """
    text = os.fspath(out)
    path = Path(text)
    suffix = path.suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        return suffix
    if not suffix or path.is_dir() or text.endswith(("/", os.sep)):
        return "folder"
    raise ValueError(f"{text}: cannot write {suffix} videos: give a file ending in "
                     f"{' or '.join(VIDEO_SUFFIXES)}, or a folder (a path with no suffix or "
                     "ending in /) for PNG frames")


MP4_HINT = "pip install imageio-ffmpeg, or pip install 'pycinder[demo]', which brings it"
"""How to install what writes MP4 videos."""


def mp4_writer(out: Path, fps: int) -> Any:
    """An imageio writer of H.264 MP4 video at ``out``, through its ffmpeg plugin only.

    Without imageio-ffmpeg, imageio would pick another plugin for ``.mp4`` (its TIFF writer),
    which fails on the first frame with an error that names neither ffmpeg nor a fix.

    Raises
    ------
    ImportError
        imageio or imageio-ffmpeg is not installed: the message says how to install them (and
        the error it is raised from names the missing module).
    """
    for module, package in (("imageio", "imageio"), ("imageio_ffmpeg", "imageio-ffmpeg")):
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise ImportError(f"{out.name}: writing MP4 videos needs {package} (imageio's ffmpeg "
                              f"plugin), which is not installed: {MP4_HINT}; or write a .gif or "
                              "a folder of PNG frames instead") from exc
    import imageio.v2 as imageio

    return imageio.get_writer(out, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                              quality=7, macro_block_size=8)


class FrameWriter:
    """Writes frames to an MP4 (imageio-ffmpeg), a GIF, or a folder of PNGs.

    Parameters
    ----------
    out : str or Path or None
        ``*.mp4``, ``*.gif``, or a folder (created) for ``frame_0000.png``, ... (see
        :func:`output_kind`); None writes nothing.
    fps : int
        Frames per second of the MP4 or GIF.

    Raises
    ------
    ValueError
        For an output path with a suffix that is not a video written here.
    ImportError
        For an MP4 where imageio-ffmpeg is not installed (see :func:`mp4_writer`).
    """

    def __init__(self, out: str | Path | None, fps: int = 30) -> None:
        self.kind = output_kind(out) if out else None
        self.out = Path(out) if out else None
        self.fps, self.count, self._writer, self._gif = fps, 0, None, []
        if self.out is None:
            return
        if self.kind == "folder":
            self.out.mkdir(parents=True, exist_ok=True)
        else:
            self.out.parent.mkdir(parents=True, exist_ok=True)
        if self.kind == ".mp4":
            self._writer = mp4_writer(self.out, fps)

    def add(self, image: np.ndarray) -> None:
        """Append one (H, W, 3) uint8 frame."""
        if self.out is None:
            return
        if self.kind == ".mp4":
            self._writer.append_data(image)
        elif self.kind == ".gif":
            self._gif.append(image)
        else:
            from ..debug.pass_buffers import png_bytes

            (self.out / f"frame_{self.count:04d}.png").write_bytes(png_bytes(image))
        self.count += 1

    def close(self) -> None:
        """Finish the file (the GIF is written here)."""
        if self._writer is not None:
            self._writer.close()
        if self._gif:
            from ..debug.montage import pillow

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
    parts = [f"{name}: {plural(len(counts), 'frame')}",
             f"contacts per frame: mean {np.mean(counts):.1f}, max {max(counts) if counts else 0}",
             f"median detection {np.median(ms):.1f} ms" if ms else "no detections"]
    for k, v in (extra or {}).items():
        parts.append(f"{k}: {v}")
    return "; ".join(parts)

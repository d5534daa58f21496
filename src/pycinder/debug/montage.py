"""One labelled picture of the scene strategy's buffers, to put beside the paper's Figures 9-13.

:class:`~pycinder.debug.pass_buffers.BufferCapture` reads the depth, stencil and colour buffers
after passes 1, 2, 3, 4 and 7 and after the self-interference filter; :func:`buffer_montage` lays
the six out in a grid, each titled with the paper's figure and what the pass did, above a legend of
the colours (the scheme of :func:`pycinder.debug.pass_buffers.to_image`). ``pycinder example``
writes it for the paper's three boxes as ``montage.png``.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from ..detector import Detector
from ..util.optional import require
from ..view import View
from .pass_buffers import (DEPTH_FAR, DEPTH_NEAR, BufferCapture, id_colours, png_bytes,
    stencil_image, three_boxes, to_image)

PANELS = (
    ("pass1_depth", "Figure 9b: depth after pass 1",
     "edges drawn with depth written (brighter: farther, stretched)"),
    ("pass2_stencil", "Figure 10: stencil after pass 2",
     "+1 per front face in front of an edge pixel"),
    ("pass3_stencil", "Figure 11: stencil after pass 3",
     "-1 per back face: non-zero = edge inside a box"),
    ("pass4_colour", "Figure 12: colour after pass 4",
     "edge pixels with a non-zero count, in their box's colour"),
    ("pass7_colour", "Figure 13: colour after pass 7",
     "mixed with the colour of the box they are in"),
    ("filtered_colour", "Filtered result",
     "a box's edges inside itself removed: the contacts"),
)
"""(buffer key, title, what it shows), in the order of the passes."""

BOX_NAMES = ("red", "green", "blue")
"""The three boxes' names; their ids 1, 2, 3 draw in these colours."""

GAP = 14
CAPTION = 40
BACKGROUND = (255, 255, 255)
INK = (25, 28, 36)
MUTED = (90, 94, 104)
PANEL_OUTLINE = (150, 150, 150)


def pillow() -> Any:
    """Pillow's ``PIL`` package, or an ImportError that says what to install."""
    for module in ("PIL.Image", "PIL.ImageDraw", "PIL.ImageFont"):
        require(module, "drawing the montage and the demos' overlays", "demo", "pillow")
    import PIL

    return PIL


@lru_cache(maxsize=8)
def font(size: int) -> Any:
    """Pillow's bundled sans-serif at ``size`` pixels (its bitmap font on Pillow < 10.1)."""
    ImageFont = pillow().ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # pragma: no cover - Pillow < 10.1
        return ImageFont.load_default()


def content_box(images: list[np.ndarray], pad: int = 12) -> tuple[int, int, int, int]:
    """(top, bottom, left, right) of the pixels that are not black in any of ``images``
    ((H, W, 3) uint8 each, the same size), grown by ``pad`` and clipped to the image."""
    lit = np.zeros(images[0].shape[:2], bool)
    for image in images:
        lit |= image.any(axis=2)
    if not lit.any():
        return 0, lit.shape[0], 0, lit.shape[1]
    rows, cols = np.flatnonzero(lit.any(axis=1)), np.flatnonzero(lit.any(axis=0))
    h, w = lit.shape
    return (max(rows[0] - pad, 0), min(rows[-1] + 1 + pad, h),
            max(cols[0] - pad, 0), min(cols[-1] + 1 + pad, w))


def legend_entries() -> list[tuple[str, list[tuple[tuple[int, int, int], str]]]]:
    """The legend: per row a heading and its (colour, label) swatches, from debug.py's scheme."""
    ids = id_colours(np.arange(1, 4))
    mix = (id_colours(np.array([1, 2])).astype(int).sum(axis=0) // 2,
           id_colours(np.array([2, 3])).astype(int).sum(axis=0) // 2)
    stencil = stencil_image(np.array([1, 2, 3, 255, 254, 253], np.uint32))
    levels = np.linspace(DEPTH_NEAR, DEPTH_FAR, 3)
    grey = [np.full(3, int(round(v * 255))) for v in levels]
    black = np.zeros(3, int)
    return [
        ("Colour (Figures 12, 13, filtered):",
         [(ids[k], f"edge of the {BOX_NAMES[k]} box (id {k + 1})") for k in range(3)] +
         [(mix[0], "red and green mixed: one inside the other"),
          (mix[1], "green and blue mixed")]),
        ("Stencil (Figures 10, 11):",
         [(stencil[k], f"+{k + 1}") for k in range(3)] +
         [(stencil[3 + k], f"-{k + 1}") for k in range(3)] + [(black, "0")]),
        ("Depth (Figure 9b):",
         [(grey[0], "nearest edge"), (grey[1], "halfway"), (grey[2], "farthest edge")] +
         [(black, "no edge (cleared to 0)")]),
    ]


LEGEND_INDENT = 230
"""Where the swatches of a legend row start, right of its heading."""


def _legend_rows(entries: list, width: int) -> list[tuple[str, list]]:
    """The legend laid out in rows at most ``width`` pixels wide: (heading, [(x, colour,
    label), ...]) per row; a row that does not fit goes on in the next, without a heading."""
    rows: list[tuple[str, list]] = []
    for heading, swatches in entries:
        row: list = []
        x = GAP + LEGEND_INDENT
        for colour, label in swatches:
            step = 19 + int(font(13).getlength(label)) + 16
            if row and x + step > GAP + width:
                rows.append((heading, row))
                heading, row, x = "", [], GAP + LEGEND_INDENT
            row.append((x, colour, label))
            x += step
        rows.append((heading, row))
    return rows


def buffer_montage(buffers: dict[str, np.ndarray], *, title: str | None = None) -> np.ndarray:
    """The six buffers side by side, titled, with a legend.

    Parameters
    ----------
    buffers : dict of str to ndarray
        What :meth:`pycinder.debug.pass_buffers.BufferCapture.capture` returns: ``pass1_depth`` (H,
        W) float32, ``pass2_stencil`` and ``pass3_stencil`` (H, W) uint32, ``pass4_colour``,
        ``pass7_colour`` and ``filtered_colour`` (H, W, 4) uint32. Missing keys are skipped.
    title : str, optional
        A line above the grid.

    Returns
    -------
    (height, width, 3) uint8
        The montage: three panels a row, each cropped to where any buffer shows something.
    """
    PIL = pillow()
    Image, ImageDraw = PIL.Image, PIL.ImageDraw

    panels = [(key, head, note) for key, head, note in PANELS if key in buffers]
    images = [to_image(key, buffers[key]) for key, _, _ in panels]
    top, bottom, left, right = content_box(images)
    images = [im[top:bottom, left:right] for im in images]
    h, w = images[0].shape[:2]
    cols = 3
    rows = -(-len(images) // cols)
    legend = _legend_rows(legend_entries(), cols * w + (cols - 1) * GAP)
    title_h = 34 if title else 0
    legend_h = 26 + 22 * len(legend)
    width = cols * w + (cols + 1) * GAP
    height = title_h + rows * (CAPTION + h + GAP) + GAP + legend_h
    canvas = Image.new("RGB", (width, height), BACKGROUND)
    draw = ImageDraw.Draw(canvas)
    if title:
        draw.text((GAP, 10), title, font=font(17), fill=INK)
    for k, ((_, head, note), image) in enumerate(zip(panels, images)):
        x = GAP + (k % cols) * (w + GAP)
        y = title_h + GAP + (k // cols) * (CAPTION + h + GAP)
        draw.text((x, y), head, font=font(15), fill=INK)
        draw.text((x, y + 19), note, font=font(12), fill=MUTED)
        canvas.paste(Image.fromarray(image), (x, y + CAPTION))
        draw.rectangle((x - 1, y + CAPTION - 1, x + w, y + CAPTION + h), outline=PANEL_OUTLINE)
    y = title_h + rows * (CAPTION + h + GAP) + GAP
    draw.text((GAP, y), "Legend", font=font(15), fill=INK)
    y += 24
    for heading, swatches in legend:
        draw.text((GAP, y), heading, font=font(13), fill=INK)
        for x, colour, label in swatches:
            draw.rectangle((x, y + 1, x + 14, y + 15), fill=tuple(int(c) for c in colour),
                           outline=(120, 120, 120))
            draw.text((x + 19, y), label, font=font(13), fill=INK)
        y += 22
    return np.asarray(canvas)


def capture_three_boxes(resolution: int = 512) -> dict[str, np.ndarray]:
    """The paper's three boxes (Figure 7) through the scene strategy, buffers after each pass."""
    boxes, _, view = three_boxes()
    return capture(boxes, view, resolution=resolution)


def capture(bodies: list[Any], view: View | None = None, *, resolution: int = 512,
            transforms: Any = None) -> dict[str, np.ndarray]:
    """Buffers after passes 1, 2, 3, 4, 7 and the filter for ``bodies`` seen through ``view``."""
    det = Detector(strategy="scene", resolution=resolution, self_interference="filter",
                   readback="full")
    return BufferCapture(det).capture(bodies, transforms, view)


def write_montage(path: str | Path, buffers: dict[str, np.ndarray] | None = None, *,
                  resolution: int = 512) -> Path:
    """Write :func:`buffer_montage` of ``buffers`` (default: the three boxes) as a PNG."""
    if buffers is None:
        buffers = capture_three_boxes(resolution)
    title = (f"The paper's three boxes (Figure 7) through the scene strategy's passes, "
             f"{resolution} x {resolution} pixels: pycinder's buffers beside Figures 9-13")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(png_bytes(buffer_montage(buffers, title=title)))
    return path

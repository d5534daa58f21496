"""What the demos draw over the 3-D view: the paper's purple contact marks with normal arrows, a
text panel and a legend (Pillow).

Everything is drawn on one transparent RGBA layer of the frame's size. Headless, the layer is
composited onto the rendered frame on the CPU (:func:`composite`), so the marks keep their exact
colours; in a window the same layer is shown over the view as a screen-space image.

A mark is a 7 x 7 pixel square, :data:`MARK_EDGE` with a :data:`MARK_FILL` centre, centred on the
pixel of a contact point, small enough to leave the bodies it marks in view; a short arrow from it
shows the contact's normal. The demos draw one mark per contact, and the count in the text panel
is the number of marks drawn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..debug.montage import font, pillow

MARK_EDGE = (150, 40, 200)
"""The paper's purple: the border of a mark."""
MARK_FILL = (245, 232, 255)
"""The inside of a mark."""
MARK_HALF = 3
"""A mark covers the pixels within this many pixels of its centre (a 7 x 7 square)."""
NORMAL_LINE = (255, 255, 255)
NORMAL_OUTLINE = (40, 10, 70)
"""A contact normal is a white arrow with a dark outline, from the mark outwards: it shows on
light and dark backgrounds alike."""
ARROW_HEAD = 6.0
"""Length in pixels of the two strokes of an arrow's head."""
TEXT = (25, 28, 36)
PANEL = (255, 255, 255, 215)
PAD = 6


@dataclass(frozen=True)
class LegendEntry:
    """One line of the legend: a glyph and what it means.

    Attributes
    ----------
    text : str
        What the glyph stands for.
    glyph : str
        ``"mark"`` (a contact mark), ``"normal"`` (a mark with its normal line), ``"swatch"``
        (a square of ``colour``), ``"image"`` (``image`` pasted as it is) or ``"none"`` (a
        line that goes on from the one above).
    colour : (3,) int, optional
        The swatch colour, 0-255.
    image : (h, w, 4) uint8, optional
        An RGBA glyph.
    """

    text: str
    glyph: str = "mark"
    colour: tuple[int, int, int] | None = None
    image: np.ndarray | None = None


def draw_mark(draw, x: float, y: float) -> None:
    """One contact mark centred on pixel (x, y) of a Pillow ImageDraw."""
    x, y = int(round(x)), int(round(y))
    h = MARK_HALF
    draw.rectangle((x - h, y - h, x + h, y + h), fill=MARK_FILL + (255,),
                   outline=MARK_EDGE + (255,), width=2)


def _normal_line(draw, xy: tuple[float, float, float, float]) -> None:
    """An arrow from (x0, y0) to (x1, y1): a shaft and a two-stroke head, outlined."""
    x0, y0, x1, y1 = xy
    d = np.array([x1 - x0, y1 - y0], float)
    length = float(np.hypot(*d))
    strokes = [(x0, y0, x1, y1)]
    if length > 1.0:
        d /= length
        for angle in (0.45, -0.45):
            c, s = np.cos(angle), np.sin(angle)
            back = -np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]]) * min(ARROW_HEAD, length)
            strokes.append((x1, y1, x1 + back[0], y1 + back[1]))
    for width, colour in ((4, NORMAL_OUTLINE), (2, NORMAL_LINE)):
        for stroke in strokes:
            draw.line(stroke, fill=colour + (255,), width=width)


def _text_size(draw, text: str, size: int) -> tuple[int, int]:
    left, top, right, bottom = draw.textbbox((0, 0), text, font=font(size))
    return right - left, bottom - top


def overlay_layer(size: tuple[int, int], *, lines: list[str], legend: list[LegendEntry],
                  marks: np.ndarray, normal_ends: np.ndarray | None = None,
                  legend_right: bool = False) -> np.ndarray:
    """The overlay of one frame.

    Parameters
    ----------
    size : (width, height)
        The frame's size in pixels.
    lines : list of str
        The text panel, top left; the first line is set larger as a title.
    legend : list of LegendEntry
        The legend, bottom left (bottom right with ``legend_right``).
    marks : (M, 2) float
        Pixel centres (x right, y down) of the marks to draw, all inside the frame.
    normal_ends : (M, 2) float, optional
        Where each mark's normal arrow ends, in pixels.
    legend_right : bool
        Put the legend in the bottom-right corner.

    Returns
    -------
    (height, width, 4) uint8
        RGBA, transparent where nothing is drawn.
    """
    PIL = pillow()
    Image, ImageDraw = PIL.Image, PIL.ImageDraw

    width, height = size
    img = Image.new("RGBA", (width, height), (0, 0, 0, 0))
    draw = ImageDraw.Draw(img)
    _panel(draw, lines, (PAD, PAD))
    _legend(img, draw, legend, (width, height), legend_right)
    if normal_ends is not None:
        for (x0, y0), (x1, y1) in zip(np.asarray(marks), np.asarray(normal_ends)):
            _normal_line(draw, (x0, y0, x1, y1))
    for x, y in np.asarray(marks):
        draw_mark(draw, x, y)
    return np.asarray(img)


def _panel(draw, lines: list[str], origin: tuple[int, int]) -> None:
    if not lines:
        return
    sizes = [15] + [13] * (len(lines) - 1)
    dims = [_text_size(draw, s, z) for s, z in zip(lines, sizes)]
    step = [z + 5 for z in sizes]
    w = max(d[0] for d in dims) + 2 * PAD
    h = sum(step) + 2 * PAD - 3
    x0, y0 = origin
    draw.rounded_rectangle((x0, y0, x0 + w, y0 + h), radius=5, fill=PANEL)
    y = y0 + PAD
    for s, z, dy in zip(lines, sizes, step):
        draw.text((x0 + PAD, y), s, font=font(z), fill=TEXT + (255,))
        y += dy


def _legend(img, draw, legend: list[LegendEntry], size: tuple[int, int], right: bool) -> None:
    if not legend:
        return
    Image = pillow().Image

    glyph_w = max([22] + [e.image.shape[1] for e in legend if e.image is not None])
    rows = [max(18, (e.image.shape[0] + 4) if e.image is not None else 0) for e in legend]
    title_h = 18
    w = glyph_w + 8 + max(_text_size(draw, e.text, 13)[0] for e in legend) + 2 * PAD
    w = max(w, _text_size(draw, "Legend", 13)[0] + 2 * PAD)
    h = title_h + sum(rows) + 2 * PAD
    x0, y0 = (size[0] - PAD - w if right else PAD), size[1] - PAD - h
    draw.rounded_rectangle((x0, y0, x0 + w, y0 + h), radius=5, fill=PANEL)
    draw.text((x0 + PAD, y0 + PAD), "Legend", font=font(13), fill=TEXT + (255,))
    y = y0 + PAD + title_h
    for entry, row in zip(legend, rows):
        cx, cy = x0 + PAD + glyph_w // 2, y + row // 2
        if entry.glyph in ("mark", "normal"):
            if entry.glyph == "normal":
                _normal_line(draw, (cx, cy, cx + 10, cy - 9))
            draw_mark(draw, cx, cy)
        elif entry.glyph == "swatch":
            draw.rectangle((cx - 6, cy - 6, cx + 6, cy + 6), fill=tuple(entry.colour) + (255,),
                           outline=(90, 90, 90, 255))
        elif entry.glyph == "image":
            glyph = Image.fromarray(entry.image)
            img.alpha_composite(glyph, (cx - glyph.width // 2, cy - glyph.height // 2))
        text_h = _text_size(draw, entry.text, 13)[1]
        draw.text((x0 + PAD + glyph_w + 8, cy - text_h // 2 - 2), entry.text, font=font(13),
                  fill=TEXT + (255,))
        y += row


def composite(frame: np.ndarray, layer: np.ndarray) -> np.ndarray:
    """``layer`` (H, W, 4) over ``frame`` (H, W, 3), both uint8; opaque pixels keep their
    exact colour. Returns (H, W, 3) uint8."""
    alpha = layer[..., 3:4].astype(np.uint16)
    out = (layer[..., :3] * alpha + frame[..., :3] * (255 - alpha) + 127) // 255
    return out.astype(np.uint8)

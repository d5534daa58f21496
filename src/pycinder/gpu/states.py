"""The pipeline state of every CInDeR pass, in one place: the paper's whole-scene passes 1-7
(strategy ``"scene"``) and the focused strategy's one rasterised pass, F3 (strategy
``"focused"``, the default).

This is Appendix A of the paper (with its swap of lines 34/37 and 35/38) and the OpenGL state of
section 4.2.1, written as WebGPU state. A reader holding the paper should be able to check every
row against it:

======  =========  ======  ===========  =====  =============  ============  =======  ==========
pass    draws      cull    depth test   depth  stencil test   stencil op    colour   per body
                                        write  (ref 0)        on pass       writes
======  =========  ======  ===========  =====  =============  ============  =======  ==========
1       edges      none    always       yes    always         keep          -        no
2       faces      back    less         no     always         incr (wrap)   -        no
3       faces      front   less-equal   no     always         decr (wrap)   -        no
4       edges      none    (always)     no     not-equal 0    keep          r, b, a  no
5       faces      back    less         no     always         incr (wrap)   -        yes
6       faces      front   less-equal   no     always         decr (wrap)   -        yes
7       faces      none    (always)     no     not-equal 0    zero          g        yes
======  =========  ======  ===========  =====  =============  ============  =======  ==========

The depth buffer is cleared to 0.0 before pass 1 (paper line 5), so passes 2, 3, 5 and 6 only
count where an edge was drawn. "cull back" draws front faces; "cull front" draws back faces; the
front face is counter-clockwise, trimesh's outward winding. Stencil values are 8 bit and wrap, so
a count of -1 (a back face at the edge's own depth) reads 255, which is non-zero as it should be.

Where we differ from the paper, and why:

* Pass 4 and pass 7 disable the depth test (compare ``always``, no write), as the paper's own
  implementation does for pass 4 (its line 36). For pass 7 we also draw both faces: the paper's
  listing keeps the back-face cull and ``LEQUAL`` of pass 6, which only reaches pixels with a back
  face of the body in front of the edge. Drawing every face of the body with the depth test off
  reaches every pixel the body covers, so each non-zero stencil value is identified and reset to 0.
* Pass 7 resets the stencil with ``zero`` where the paper decrements; the result is the same for a
  count of 1, and ``zero`` also resets counts that self-interference pushed to 2 or 255.
* The colour target is ``rgba32uint``; see ``result.py`` for what each channel holds.

``self_interference="prevent"`` (paper 4.3.1.3, done inside the shader) changes three rows, see
``PREVENT``: pass 1 also writes the id of the body that owns each edge pixel; that image is copied
to a texture (the paper's intermediate texture); the colour target is cleared again before pass 2;
and passes 2, 3, 5 and 6 discard a body's faces at pixels where the edge is that body's own. A
closed body can never contain its own edge, so this loses nothing real, and a body's edge is never
counted inside itself: no self-interference is registered, none can overwrite a real collision,
and none can cancel a real count at a silhouette. ``self_interference="offset"`` (4.3.1.1) moves
the edges of passes 1 and 4 outward along their vertex normals in the vertex stage; WebGPU does
not allow depth bias on line primitives.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

Primitive = Literal["edges", "faces"]


def write_mask(color_writes: str) -> int:
    """The WebGPU colour write mask of a subset of "rgba" (R=1, G=2, B=4, A=8)."""
    return sum({"r": 1, "g": 2, "b": 4, "a": 8}[c] for c in color_writes)


@dataclass(frozen=True)
class PassState:
    """Fixed-function state of one pass."""

    number: int
    purpose: str
    draws: Primitive
    cull: Literal["none", "back", "front"]
    depth_compare: str
    depth_write: bool
    stencil_compare: str
    stencil_pass_op: str
    color_writes: str  # subset of "rgba"; "" writes no colour
    per_body: bool
    skip_own_faces: bool = False  # discard a body's faces where the edge pixel is its own
    name: str = ""  # a short name, for the pass table and labels

    @property
    def write_mask(self) -> int:
        return write_mask(self.color_writes)

    @property
    def summary(self) -> str:
        """Depth, stencil and cull state in a line, for the pass table."""
        depth = f"depth {self.depth_compare}{', write' if self.depth_write else ''}"
        stencil = f"stencil {self.stencil_compare}, {self.stencil_pass_op}"
        colour = f"writes {', '.join(self.color_writes) or '-'}"
        return f"{self.draws}; cull {self.cull}; {depth}; {stencil}; {colour}"


PASSES: dict[int, PassState] = {
    1: PassState(1, "draw the edges into the depth buffer",
                 "edges", "none", "always", True, "always", "keep", "", False,
                 name="edges into depth"),
    2: PassState(2, "count front faces in front of each edge",
                 "faces", "back", "less", False, "always", "increment-wrap", "", False,
                 name="count front faces"),
    3: PassState(3, "subtract back faces in front of each edge",
                 "faces", "front", "less-equal", False, "always", "decrement-wrap", "", False,
                 name="subtract back faces"),
    4: PassState(4, "identify the penetrating body where the count is non-zero",
                 "edges", "none", "always", False, "not-equal", "keep", "rba", False,
                 name="identify penetrating"),
    5: PassState(5, "count this body's front faces in front of each edge",
                 "faces", "back", "less", False, "always", "increment-wrap", "", True,
                 name="count front faces per body"),
    6: PassState(6, "subtract this body's back faces in front of each edge",
                 "faces", "front", "less-equal", False, "always", "decrement-wrap", "", True,
                 name="subtract back faces per body"),
    7: PassState(7, "identify this body as penetrated and reset the stencil",
                 "faces", "none", "always", False, "not-equal", "zero", "g", True,
                 name="identify penetrated"),
}

PREVENT: dict[int, PassState] = {
    **PASSES,
    1: replace(PASSES[1], color_writes="rba"),
    2: replace(PASSES[2], skip_own_faces=True),
    3: replace(PASSES[3], skip_own_faces=True),
    5: replace(PASSES[5], skip_own_faces=True),
    6: replace(PASSES[6], skip_own_faces=True),
}
"""The table for ``self_interference="prevent"``."""


@dataclass(frozen=True)
class RenderStep:
    """Passes recorded into one render pass, and what happens at its start."""

    passes: tuple[int, ...]
    clear_depth_stencil: bool
    clear_colour: bool
    copy_owner_before: bool = False  # copy the colour target to the edge-owner texture first

    @property
    def title(self) -> str:
        """How labels and profiles name the step: ``"pass 1"``, ``"passes 2-4"``."""
        if not self.passes:
            return "clear"
        first, last = self.passes[0], self.passes[-1]
        return f"pass {first}" if first == last else f"passes {first}-{last}"


PLAN = (RenderStep((1, 2, 3, 4), True, True), RenderStep((5, 6, 7), False, False))
PREVENT_PLAN = (RenderStep((1,), True, True),
                RenderStep((2, 3, 4), False, True, copy_owner_before=True),
                RenderStep((5, 6, 7), False, False))

# The depth buffer's clear value before pass 1 (paper line 5).
DEPTH_CLEAR = 0.0
STENCIL_MASK = 0xFF


# -- The focused strategy ---------------------------------------------------------------------
#
# A tile per candidate pair replaces the one image of the whole scene. Per tile the pair's two
# bodies are the only ones drawn, so the penetrated body of any edge inside a solid is simply the
# other one: passes 5-7 go away, and with them self-interference (a body's edges are only ever
# tested against the other body's faces). The counting of passes 2 and 3 moves from the stencil
# buffer to per-pixel lists written with storage atomics, so that every edge sample is tested at
# its own depth: no edge hides another in its pixel.
#
# The focused passes are listed, in the order they run, in pycinder.focused.frame.frames.PASSES, and the
# docs' table is generated from their classes (pycinder.gpu.table). F3 is the only pass with
# fixed-function state, below: no depth or stencil attachment, no culling, no colour writes.
#
# F3 is the only rasterised pass. It has no depth or stencil attachment: a face crossing a pixel's
# ray in front of the tile's box (for tiles counting towards the back: behind it) adds +1 (front
# face) or -1 (back face) to that body's winding at the pixel, as passes 2 and 3 do; a face crossing
# it within the box's depth range is listed with its depth, facing and face. F4 then tests every
# listed crossing (a point exactly on one body's surface) and F5 every edge sample at depth z by
# counting the other body's listed crossings between z and the counting side.


@dataclass(frozen=True)
class FocusedPassState:
    """Fixed-function state of the focused strategy's rasterised pass."""

    number: str
    purpose: str
    draws: str
    cull: Literal["none", "back", "front"]
    depth_stencil: None
    color_writes: str

    @property
    def write_mask(self) -> int:
        return write_mask(self.color_writes)


FOCUSED_CROSSINGS = FocusedPassState(
    "F3", "list every face crossing of each pixel ray, per body", "clipped faces of both bodies",
    "none", None, "")

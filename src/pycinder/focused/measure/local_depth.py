"""Local depth: a pair with a non-convex body measured where its bodies overlap.

Pass H1's figure along a line is how far one body must move to leave the other behind on every
ray parallel to it. For convex bodies that is the shortest separating translation along the
line. Where a body is non-convex it also counts what lies beyond a gap: a pipe grazing the inside
of a ring-shaped sleeve by 0.5 mm must, on a ray across the sleeve, move past the sleeve's far
wall as well, so the pair's figure is the sleeve's width (0.28 m), not the graze.

Here such a pair is measured part by part instead. The solids' intersection ``A ∩ B`` is computed
in float64 (manifold3d's exact boolean) and split into its connected parts; for each part, both
bodies are cut to the part's box grown by :data:`LOCAL_GROW` ``d`` (solids closed by the box's
walls) and measured there by pass H1 (:mod:`~pycinder.focused.measure.regions`). The pair's local
depth is its deepest part's figure. A translation that separates the bodies separates their parts
within any box, so the local depth never exceeds the whole pair's figure; and a ray across a box
around the graze meets only the near wall of the sleeve, so the graze is measured as a graze.

Which pairs: those with a closed body that is not convex (:func:`shape_convex`), both bodies
solids manifold3d takes (a solid whose closed parts share edges, a stair of boxes meeting along
their edges, as the union of its parts: :class:`~pycinder.focused.measure.regions.SolidCutter`).
A pair of convex bodies keeps its whole figure, which is its penetration depth (see
:mod:`~pycinder.focused.modes.hardclash`). A pair with an open body, or a body
manifold3d cannot take as a solid, keeps its whole figure too (an upper bound of its local depth:
such a pair may be reported where a local measure would not, never the other way).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .regions import SolidCutter, placed_cutter

if TYPE_CHECKING:
    from ...scene import Scene
    from ...scene.bodies import Shape

LOCAL_GROW = 1.0
"""The boxes of the overlap's parts are grown by this many ``d`` on every side before the bodies
are cut to them: enough that a body wholly inside the other part's box is more than ``d`` from
its walls, so that it is measured deeper than ``d``."""

CONVEX_SLACK = 1e-6
"""A closed body whose volume is within this fraction of its convex hull's is taken as convex
(vertices rounded to single precision dent flat faces by less; a body dented by less is measured
whole, which can only report it, never miss it)."""

@dataclass(frozen=True)
class SolidFacts:
    """What manifold3d says of a shape as a solid (:func:`solid_facts`)."""

    solid: bool
    """A solid (:attr:`~pycinder.scene.Topology.solid`) manifold3d takes, whole or as the union
    of its closed parts, wound outward (positive volume)."""
    pieces: int
    """Its connected pieces (0 where not a solid)."""
    convex: bool
    """One piece whose volume is its convex hull's, within :data:`CONVEX_SLACK`."""


_facts: weakref.WeakKeyDictionary[Shape, SolidFacts] = weakref.WeakKeyDictionary()


def solid_facts(shape: Shape) -> SolidFacts:
    """A shape's :class:`SolidFacts`, kept per shape (a deforming body's new vertices are a new
    shape). A body wound inside out is not a solid here: cut as one, its inside would be its
    outside.

    Parameters
    ----------
    shape : Shape

    Returns
    -------
    SolidFacts
    """
    if shape in _facts:
        return _facts[shape]
    facts = SolidFacts(False, 0, False)
    if shape.topology.solid and len(shape.topology.faces):
        cutter = SolidCutter(np.asarray(shape.vertices, np.float64),
                             np.asarray(shape.topology.faces, np.int64))
        if cutter.ok:
            volume = cutter.solid.volume()
            pieces = len(cutter.solid.decompose())
            hull = cutter.solid.hull().volume()
            facts = SolidFacts(True, pieces, pieces == 1 and hull - volume <= CONVEX_SLACK * hull)
    _facts[shape] = facts
    return facts


def shape_convex(shape: Shape) -> bool | None:
    """Whether a shape is convex (:attr:`SolidFacts.convex`); None where it is not a solid
    manifold3d can cut (open, not a two-manifold, or wound inside out)."""
    facts = solid_facts(shape)
    return facts.convex if facts.solid else None


def one_outward_solid(shape: Shape) -> bool:
    """Whether a shape is one solid wound outward (a ray from outside enters it on a face
    facing against the ray: what pass H1's culling by facing relies on)."""
    facts = solid_facts(shape)
    return facts.solid and facts.pieces == 1


def pair_kinds(scene: Scene, pairs: np.ndarray) -> np.ndarray:
    """Which pairs are measured locally: a body not convex, both solids manifold3d takes.

    Parameters
    ----------
    scene : Scene
    pairs : (K, 2) int

    Returns
    -------
    (K,) bool
    """
    shapes = scene.body_shape[np.asarray(pairs, np.int64)]
    kinds = {int(s): shape_convex(scene.shapes[int(s)]) for s in np.unique(shapes)}
    convex = np.array([[kinds[int(s)] for s in row] for row in shapes], dtype=object)
    if len(pairs) == 0:
        return np.zeros(0, bool)
    solid = np.all(convex != None, axis=1)
    flat = np.all(convex == True, axis=1)
    return solid & ~flat


def convex_pairs(scene: Scene, pairs: np.ndarray) -> np.ndarray:
    """Which pairs have two convex solids (:func:`shape_convex`).

    Parameters
    ----------
    scene : Scene
    pairs : (K, 2) int

    Returns
    -------
    (K,) bool
    """
    shapes = scene.body_shape[np.asarray(pairs, np.int64)].reshape(-1, 2)
    kinds = {int(s): shape_convex(scene.shapes[int(s)]) is True for s in np.unique(shapes)}
    return np.array([kinds[int(a)] and kinds[int(b)] for a, b in shapes], bool)


def overlap_parts(scene: Scene, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                             np.ndarray]:
    """The world boxes of the connected parts of each pair's intersection (in float64, about
    where the pair's world boxes meet, so that far and large models keep their precision).

    Parameters
    ----------
    scene : Scene
    pairs : (K, 2) int
        Pairs of solids (:func:`pair_kinds`).

    Returns
    -------
    owner : (P,) int64
        The row of ``pairs`` of each part (a pair that does not overlap in volume has none).
    lo, hi : (P, 3) float64
        Each part's world box.

    Raises
    ------
    ValueError
        A body that manifold3d takes as a solid in its own space but not as placed, naming the
        pair (never an overlap silently lost).
    """
    lo_w, hi_w = scene.world_boxes()
    owner: list[int] = []
    boxes: list[np.ndarray] = []
    for k, (a, b) in enumerate(np.asarray(pairs, np.int64)):
        origin = 0.5 * (np.maximum(lo_w[a], lo_w[b]) + np.minimum(hi_w[a], hi_w[b]))
        cutters = [placed_cutter(scene, int(body), origin) for body in (a, b)]
        for body, cutter in zip((a, b), cutters):
            if not cutter.ok:  # a solid in its own space, not where it is placed
                raise ValueError(
                    f"{scene.label(int(body))} is a solid, but not as placed (its transform "
                    f"nearly flattens it), so its pair with "
                    f"{scene.label(int(b if body == a else a))} cannot be measured where they "
                    f"overlap; give it a transform that keeps its shape")
        for part in (cutters[0].solid ^ cutters[1].solid).decompose():
            if part.is_empty() or part.volume() <= 0.0:
                continue
            box = np.asarray(part.bounding_box(), np.float64)
            boxes.append(np.concatenate([box[:3], box[3:]]) + np.tile(origin, 2))
            owner.append(k)
    table = np.array(boxes, np.float64).reshape(-1, 6)
    return np.array(owner, np.int64), table[:, :3], table[:, 3:]


__all__ = ["CONVEX_SLACK", "LOCAL_GROW", "SolidFacts", "convex_pairs", "one_outward_solid",
           "overlap_parts",
           "pair_kinds", "shape_convex", "solid_facts"]

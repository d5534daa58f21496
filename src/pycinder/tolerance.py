"""The tolerance policy of the focused strategy, in one place.

A tolerance comes in three shapes, and each has its own name everywhere in the package:

- ``tolerance``: the request's (a float, or None for the default), ``CollisionRequest.tolerance``;
- ``body_tolerances``: (N,) float, one per body, NaN where the request's applies (a batch gives
  each scene's to its bodies);
- ``pair_tolerances``: (K,) float, one per candidate pair, what the tiles' pixels are sized by
  (:func:`pair_tolerances`).

A pair's tolerance ``t`` (world units) is the width of its tiles' pixels, and what the contract
promises is stated in it (a pair at least ``t`` apart is never reported, one at least ``2 t``
deep always is). It is, in order:

- the tolerance given for the pair's first body (a batch of scenes gives each scene's to its
  bodies);
- else the request's ``tolerance``;
- else :data:`DEFAULT_RELATIVE_TOLERANCE` of the smaller body's size (its bounding-box
  diagonal in the world), from the pair's own bodies only.

Single precision bounds it from below (:func:`resolvable_tolerance`): a body at most
:data:`MAX_PIXELS_ACROSS` pixels across and :data:`MAX_PIXELS_FROM_ORIGIN` pixels from the
origin. A default below that floor is raised to it, with a
:class:`~pycinder.errors.PrecisionWarning`; a tolerance given below it is an error. The request's
``max_pixels`` bounds from above how many pixels one query's tiles may hold.
"""

from __future__ import annotations

import numpy as np

from .errors import PrecisionWarning, warn_at_caller
from .scene import Scene
from .util.arrays import sum3
from .util.text import plural

DEFAULT_RELATIVE_TOLERANCE = 0.01
"""Default tolerance of a pair, as a fraction of the smaller body's bounding-box diagonal."""

def body_sizes(local_lo: np.ndarray, local_hi: np.ndarray, transforms: np.ndarray
               ) -> np.ndarray:
    """(N,) each body's size: the world length of its bounding-box diagonal.

    Parameters
    ----------
    local_lo, local_hi : (N, 3) float
        Corners of each body's bounding box in its own coordinates.
    transforms : (N, 4, 4) float
        Each body's world-from-body transform (its linear part scales the diagonal).
    """
    diag = np.asarray(local_hi, np.float64) - np.asarray(local_lo, np.float64)
    linear = np.asarray(transforms, np.float64)[:, :3, :3]
    placed = np.einsum("nij,nj->ni", linear, diag)
    # The norm along an axis of 3 added as NumPy reduces it (sum3: the same bits, faster).
    return np.sqrt(sum3(placed * placed))


def default_pair_tolerances(size_a: np.ndarray, size_b: np.ndarray,
                            tolerance: float | None = None) -> np.ndarray:
    """(K,) tolerance of pairs of bodies ``size_a`` and ``size_b`` ((K,) :func:`body_sizes`)
    across: ``tolerance`` where given, else :data:`DEFAULT_RELATIVE_TOLERANCE` of the smaller
    body's size."""
    smaller = np.minimum(np.asarray(size_a, np.float64), np.asarray(size_b, np.float64))
    if tolerance is not None:
        return np.full(smaller.shape, float(tolerance))
    return DEFAULT_RELATIVE_TOLERANCE * smaller


MAX_PIXELS_ACROSS = 2.0**20
"""Most pixels a pair's body may span: single-precision tile coordinates then stay within a
sixteenth of a pixel (2**20 * 2**-24), well inside the contract's margins."""
MAX_PIXELS_FROM_ORIGIN = 2.0**48
"""Most pixels a pair's body may lie from the world origin: the double-precision planning then
places its tiles within a sixteenth of a pixel (2**48 * 2**-52)."""
SMALLEST_TOLERANCE = 1e-30
"""A pair of bodies of no size (all vertices at one point) at the origin still gets a pixel."""


def resolvable_tolerance(scene: Scene, pairs: np.ndarray, size: np.ndarray | None = None
                         ) -> np.ndarray:
    """(K,) the smallest tolerance at which each pair's tiles are resolved in single precision:
    each body at most :data:`MAX_PIXELS_ACROSS` pixels across and :data:`MAX_PIXELS_FROM_ORIGIN`
    pixels from the origin."""
    if size is None:
        size = body_sizes(scene.local_lo, scene.local_hi, scene.transforms)
    centre = np.abs(scene.box_centres())
    far = np.maximum(np.maximum(centre[:, 0], centre[:, 1]), centre[:, 2]) + size
    a, b = pairs[:, 0], pairs[:, 1]
    return np.maximum(np.maximum(np.maximum(size[a], size[b]) / MAX_PIXELS_ACROSS,
                                 np.maximum(far[a], far[b]) / MAX_PIXELS_FROM_ORIGIN),
                      SMALLEST_TOLERANCE)


def pair_tolerances(scene: Scene, pairs: np.ndarray, tolerance: float | None = None,
                    body_tolerances: np.ndarray | None = None) -> np.ndarray:
    """(K,) tolerance of each candidate pair, in world units, by the policy above.

    Parameters
    ----------
    scene : Scene
    pairs : (K, 2) int
    tolerance : float, optional
        The request's tolerance.
    body_tolerances : (N,) float, optional
        A tolerance per body, used for a pair from its first body where not NaN.

    Raises
    ------
    ValueError
        A tolerance given below what single precision resolves for some pair.
    """
    size = body_sizes(scene.local_lo, scene.local_hi, scene.transforms)
    a, b = pairs[:, 0], pairs[:, 1]
    floor = resolvable_tolerance(scene, pairs, size)
    tol = default_pair_tolerances(size[a], size[b], tolerance)
    chosen = np.full(len(pairs), tolerance is not None)
    if body_tolerances is not None:
        g = np.asarray(body_tolerances, dtype=np.float64)[a]
        chosen |= ~np.isnan(g)
        tol = np.where(np.isnan(g), tol, g)
    bad = np.flatnonzero(chosen & (tol < floor))
    if len(bad):
        k = bad[np.argmax(floor[bad])]
        raise ValueError(
            f"tolerance {tol[k]:g} is too fine for {plural(len(bad), 'candidate pair')} in "
            f"single precision (first: {scene.label(int(a[k]))} and {scene.label(int(b[k]))}, "
            f"{size[a[k]]:.3g} and {size[b[k]]:.3g} across): the GPU resolves them at "
            f"{floor[bad].max():.3g} or coarser; use a coarser tolerance, or test those "
            "bodies in a query of their own scale")
    raised = np.flatnonzero(~chosen & (tol < floor))
    if len(raised):
        k = raised[np.argmax(floor[raised] / np.maximum(tol[raised], 1e-300))]
        warn_at_caller(
            f"{plural(len(raised), 'candidate pair')} {'is' if len(raised) == 1 else 'are'} "
            f"too far apart in size (or too far from the origin) for their default tolerance in "
        f"single precision: their tolerance was "
            f"raised to what the GPU resolves (first: {scene.label(int(a[k]))} and "
            f"{scene.label(int(b[k]))}, {size[a[k]]:.3g} and {size[b[k]]:.3g} across, "
            f"tolerance {tol[k]:.3g} -> {floor[k]:.3g}); see stats.tolerance",
            PrecisionWarning)
    return np.maximum(tol, floor)


__all__ = ["DEFAULT_RELATIVE_TOLERANCE", "MAX_PIXELS_ACROSS", "MAX_PIXELS_FROM_ORIGIN",
           "SMALLEST_TOLERANCE", "body_sizes", "default_pair_tolerances", "pair_tolerances",
           "resolvable_tolerance"]

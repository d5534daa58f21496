"""The broad phase on the GPU: world boxes, a bitonic sort and a sweep, in one submission.

The GPU equivalent of :func:`pycinder.scene.bodies.world_boxes` followed by
:func:`pycinder.focused.broad.broad_numpy.sweep_and_prune` (and the focused strategy's filter to
pairs of bodies in different groups): :class:`GpuBroadPhase`. Its passes, one class each, all in one
command buffer (:data:`PASSES`; the table is generated from them by :func:`pass_table`):

- B1-B3 (:mod:`~pycinder.focused.broad.b1_boxes`): each body's world box; the grid across the sweep
  axis, from which the widest boxes (at most 32) are kept out; each box's sort element (within
  key, column, start on the sweep axis, body);
- B4, B5 (:mod:`~pycinder.focused.broad.b4_sort`): the bitonic sort of the elements;
- B6-B8 (:mod:`~pycinder.focused.broad.b6_sweep`): the boxes in sorted order, then their pairs:
  within columns, and against the wide boxes.

What the passes share with their shaders (the ``Body`` they read, the frame's ``Params``, the
grid's and the counts' words, the constants) is declared once in
:mod:`~pycinder.focused.broad.broad_common` and generated into the shaders
(``shaders/broad_*.wgsl``).

Boxes that are not wide and overlap have centres at most the widest of them apart, so they lie in
the same or neighbouring columns; of each such pair, the box that starts first finds the other, so
every pair is found once. A sweep along the whole axis would test, in a dense 3D scene, every box
against the O(N^(2/3)) boxes beside it along the axis; within columns it tests a few. Keeping the
widest boxes out of the grid keeps one floor (or a few) from making the cells as wide as the
scene.

llvmpipe (lavapipe, and Mesa's OpenGL on the CPU) silently stops an invocation's loops after 65535
steps in all. No pass loops that long: the wide boxes are tested by one thread per box rather
than one per wide box, and a sweep that meets more than 4096 boxes stops, is listed, and is
finished on the host from the GPU's boxes (a second round trip).

One readback maps the pair count and the first pairs (as many as the last call found, and a
quarter more). More pairs are read by a second copy; more pairs than the pairs buffer holds make it
grow and the sweep (B7, B8) run again, so nothing is dropped. The sweep axis is the one along which
the bodies' translations spread most (computed on the host; any axis gives the same pairs).

Conservative boxes
------------------
The boxes are computed in float32 from the transforms less a common origin (the midpoint of the
translations' range, subtracted in float64), so that far-off scenes (1e6 from the origin) keep their
precision. Along world axis ``k`` of body ``i``, with ``m`` the linear part and ``t`` the
translation less the origin, every bound is moved outward by

    pad[i, k] = 2**-19 * (|t[k]| + sum_j |m[k, j]| * (max(|lo_j|, |hi_j|) + radius))
                + 2**-40 * max(|origin|)

The first term is about twice the worst rounding error of the float32 evaluation (input rounding,
the products and sums of a row, and WGSL's ``sqrt``, which may be off by several ulps), all
bounded by the row's sum of magnitudes; the second covers the float64 reference's own rounding at
the origin's magnitude. So every pair the float64 reference finds is found. A pair the reference
does not find may be reported when its boxes are apart by at most ``2 * (pad[a] + pad[b])`` along
every axis (the padding, and the rounding it covers): about 8e-6 of the bodies' coordinates
measured from the origin.
"""

from __future__ import annotations

from ...gpu.table import pass_table
from .b1_boxes import Columns, GridSetup, WorldBoxes
from .broad_common import COORDINATE_LIMIT, PAD_SCALE, SORT_BLOCK, BroadPass
from .broad_gpu_host import in_range, reference_pairs
from .broad_gpu import BroadPhaseStats, GpuBroadPhase
from .b4_sort import LocalSort, MergeStep, sort_steps
from .b6_sweep import Gather, Sweep, WideSweep

PASSES: tuple[type[BroadPass], ...] = (WorldBoxes, GridSetup, Columns, LocalSort, MergeStep,
                                       Gather, Sweep, WideSweep)
"""The broad phase's passes, in the order they run."""


def broad_pass_table() -> str:
    """The broad phase's pass table (reStructuredText), generated from :data:`PASSES`."""
    return pass_table(p.INFO for p in PASSES)


__all__ = ["COORDINATE_LIMIT", "PAD_SCALE", "PASSES", "SORT_BLOCK", "BroadPhaseStats",
           "GpuBroadPhase", "broad_pass_table", "in_range", "reference_pairs", "sort_steps"]

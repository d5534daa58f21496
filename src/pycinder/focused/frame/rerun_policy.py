"""What runs again, and why: the one place it is decided.

A focused query never drops a sample silently. Four things make work run again, from the
cheapest to the dearest:

1. **Lists overflowed, inside the frame (GPU).** A pixel listed more crossings within its tile's
   box than its list holds, so some samples were undecided. When the last query needed retries
   (frames of an animation are alike), the frame ends with retry rounds: pass F7 chooses the
   undecided tiles whose pair no tile found, from every round, and lays them out anew in the
   retry rounds' rows, and passes F1-F6 run again for them with lists
   :data:`~pycinder.focused.frame.atlas_buffers.RETRY_LISTS` times longer, in the same submission.
   The strategy chooses this with :func:`retry_on_gpu`, which sizes a retry round within the
   memory budget, and :func:`retry_rounds`, which makes as many as the last frame's tiles to run
   again needed. Tiles that do not fit them stay undecided, for case 4.
2. **A buffer was too small (host, same frame).** A pass filled a buffer whose size the host
   chose (clipped triangles, listed edges, records, and cull items, which a retry round may need
   more of than the frame's rounds): the frame is run again, whole, with the buffer grown
   (:func:`grown_caps`). Records are not worth a rerun past the device's largest
   buffer: the extra records are dropped and counted (pairs come from the per-pair flags, which
   are complete).
3. **A round too large (host, same tiles).** One round needs more clipped triangles, listed
   edges or cull items than the device's largest buffer holds: :func:`grown_caps` raises
   :class:`RoundTooLarge`; a frame with retry rounds runs again without them (their tiles come
   from every round), and otherwise the same tiles are planned in smaller rounds, down to one
   atlas band each, then narrower bands (:func:`smaller_rounds`).
4. **Tiles left undecided (host, those tiles).** After the frame, tiles still undecided whose
   answer could change (their pair not found elsewhere, or every tile's records wanted) run
   again (:func:`undecided_tiles`): first with lists four times longer, then with their boxes
   cut in two along the view, up to :data:`RETRIES` times; what is still undecided then is
   reported (``stats.possibly_lost``) and warned about. A tile that pass F6 left at its loop
   budget gets both at once (longer lists do not help it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...gpu.layout import (C_MAX_EDGE_ITEMS, C_MAX_EDGES, C_MAX_FACE_ITEMS, C_MAX_TRIS, C_RECORDS,
                           UNDECIDED_BUDGET_BIT)
from ...request import RecordMode
from ..plan.plan_numpy import HEIGHT_CLASSES, MAX_TILE, TilePlan, class_of, repack, split_depth
from .atlas_buffers import RETRY_LISTS, Caps

RETRIES = 5
"""Times undecided tiles are run again: first with longer lists, then with thinner boxes."""
LARGER_LISTS = 1
"""Retries that make the lists longer (8 -> 32 entries) before boxes are cut."""


class RoundTooLarge(Exception):
    """A round clipped more triangles (or listed more edges) than one buffer of this device
    holds: the caller plans the tiles in smaller rounds and runs them again."""

    def __init__(self, needed: int, limit: int, what: str = "clipped triangles") -> None:
        super().__init__(f"{needed} {what} in one round, {limit} fit")
        self.needed, self.limit, self.what = needed, limit, what


MAX_RETRY_ROUNDS = 8
"""Most retry rounds a frame ends with (see :func:`retry_rounds`)."""


def retry_on_gpu(recently_retried: bool, records: RecordMode, plan: TilePlan,
                 retry_budget: int) -> int:
    """Case 1: the atlas rows of each of ``plan``'s frame's retry rounds (0: the frame has
    none).

    Only when the last query ran tiles again (a retry round that finds nothing to retry still
    costs its passes' fixed cost, about as much as a frame of two small bodies on a CPU
    adapter), and when not every tile is tested (retry rounds leave out the tiles of pairs
    already found, whose records would then be missing). A retry round's rows hold lists
    :data:`~pycinder.focused.frame.atlas_buffers.RETRY_LISTS` times longer within ``retry_budget``
    atlas pixels, at most as many as the plan's largest round (the frame's pixel buffer and render
    target), a multiple of the tallest height class where at least one, else a power of two
    (so that no shelf of the layout, each at a multiple of its class's height, lies across two
    retry rounds), and at least the height class of the plan's tallest tile (none, where those
    do not fit)."""
    if not recently_retried or records.every_tile or not len(plan):
        return 0
    rows = min(retry_budget // plan.atlas_width, max(plan.round_rows))
    if rows >= HEIGHT_CLASSES[-1]:
        rows -= rows % HEIGHT_CLASSES[-1]
    elif rows > 0:
        rows = 1 << (rows.bit_length() - 1)  # a class height: shelves of any lower one align
    shelf = HEIGHT_CLASSES[int(class_of(plan.window[:, 3].max()))]
    return rows if rows >= shelf else 0


def retry_rounds(rows_needed: int, rows: int) -> int:
    """The retry rounds of a frame whose retry rounds have ``rows`` rows each, when the last
    frame's tiles to run again needed ``rows_needed`` rows of the retry rounds' layout (frames
    of an animation, or batches of a robot check, are alike): enough for them, at least one and
    at most :data:`MAX_RETRY_ROUNDS`. Tiles that do not fit run again on the host (case 4)."""
    return min(max(-(-rows_needed // max(rows, 1)), 1), MAX_RETRY_ROUNDS)


def grown_caps(counters: np.ndarray, caps: Caps, limits: Caps, records_read: bool,
               items: int) -> Caps | None:
    """Case 2: the buffers to grow before the frame runs again (None: it need not).

    Parameters
    ----------
    counters : (COUNTERS,) int
        The frame's counters (the largest counts of any round or retry round).
    caps, limits : Caps
        What the buffers hold now, and the most they may ever hold.
    records_read : bool
        The frame's records are read back (otherwise their count does not matter).
    items : int
        The cull items the frame's rounds could keep (a retry round may have culled more: its
        tiles come from every round).

    Raises
    ------
    RoundTooLarge
        Case 3: a round needs more than ``limits`` allow.
    """
    grown = Caps(caps.tris, caps.records, caps.edges, caps.items)
    changed = False
    culled = max(int(counters[C_MAX_FACE_ITEMS]), int(counters[C_MAX_EDGE_ITEMS]))
    if culled > items:
        if culled > limits.items:
            raise RoundTooLarge(culled, limits.items, "cull items")
        grown.items = culled
        changed = True
    for name, counter, what in (("tris", C_MAX_TRIS, "clipped triangles"),
                                ("edges", C_MAX_EDGES, "edges to sample")):
        needed, limit = int(counters[counter]), getattr(limits, name)
        if needed > getattr(caps, name):
            if needed > limit:
                raise RoundTooLarge(needed, limit, what)
            setattr(grown, name, min(int(needed * 1.5) + 1024, limit))
            changed = True
    if records_read and counters[C_RECORDS] > caps.records and caps.records < limits.records:
        grown.records = min(int(counters[C_RECORDS] * 1.5) + 1024, limits.records)
        changed = True
    return grown if changed else None


def smaller_rounds(plan: TilePlan, exc: RoundTooLarge, budget: int, width: int
                   ) -> tuple[TilePlan, int, int] | None:
    """Case 3: ``plan``'s tiles in rounds small enough for what ``exc`` needed.

    Fewer atlas pixels per round, down to one band each; then narrower bands (fewer tiles in
    each). Returns the new plan, and the budget and width to start from should it still be too
    large; None when rounds of one band of the narrowest width already were.
    """
    largest = max(plan.round_rows) * width
    budget = int(min(budget, largest) * 0.9 * exc.limit / exc.needed)
    smaller = repack(plan, budget, width)
    if max(smaller.round_rows) * width >= largest:
        if width <= MAX_TILE[0]:
            return None
        width = max(MAX_TILE[0], width // 2)
        smaller = repack(plan, budget, width)
    return smaller, budget, width


@dataclass
class Undecided:
    """Case 4: the tiles to run again, and how."""

    plan: TilePlan
    """Those tiles, re-planned (cut in depth where asked)."""
    tiles: np.ndarray
    """(U,) their indices in the plan that left them undecided (their records there are
    dropped: the retry covers their whole boxes again)."""
    capacity: int
    """List entries per pixel of the retry."""
    lists_overflowed: bool
    """Some of them overflowed their lists (not only pass F6's loop budget)."""


def undecided_tiles(plan: TilePlan, tile_counts: np.ndarray, found: np.ndarray,
                    every_tile: bool, capacity: int, base_capacity: int,
                    budget_of: Callable[[int], int]) -> tuple[np.ndarray, Undecided | None]:
    """Case 4: the tiles of ``plan`` to run again.

    Parameters
    ----------
    plan : TilePlan
    tile_counts : (T, 2) int
        Per tile: samples found, samples undecided (with
        :data:`~pycinder.gpu.layout.UNDECIDED_BUDGET_BIT` where pass F6 stopped at its budget).
    found : (K,) bool
        Pairs found so far.
    every_tile : bool
        Every tile's records are wanted (an undecided tile of a found pair still runs again).
    capacity, base_capacity : int
        List entries per pixel of the last run, and of a first run.
    budget_of : callable
        Atlas pixels per round (the memory budget) for lists of a given capacity.

    Returns
    -------
    again : (T,) bool
        The tiles left undecided whose answer could change.
    retry : Undecided or None
        How to run them again (None when there are none).
    """
    undecided = tile_counts[:, 1] > 0
    out_of_steps = (tile_counts[:, 1] & UNDECIDED_BUDGET_BIT) != 0   # pass F6's loop budget
    again = undecided if every_tile else undecided & ~found[plan.pair]
    if not again.any():
        return again, None
    which = np.flatnonzero(again)
    overflowed = bool((again & ~out_of_steps).any())
    if capacity == base_capacity:
        capacity *= RETRY_LISTS
        retry = split_depth(plan, which, budget_of(capacity),
                            cut=bool(out_of_steps[which].any()))
    else:
        retry = split_depth(plan, which, budget_of(capacity))
    return again, Undecided(retry, which, capacity, overflowed)


__all__ = ["LARGER_LISTS", "MAX_RETRY_ROUNDS", "RETRIES", "RoundTooLarge", "Undecided",
           "grown_caps", "retry_on_gpu", "retry_rounds", "smaller_rounds", "undecided_tiles"]

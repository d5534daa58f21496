"""The tile planner on the GPU (``planner="gpu"``): the same plan as
:func:`pycinder.focused.plan.plan_numpy.plan_tiles`, with the work per candidate pair and per tile
done in compute passes.

    bodies' poses and boxes, relative to anchors      (host, O(N)) -> upload
    pairs and tolerances                              -> upload
    P0 bodies: each body's frame, half axes, bounds   (compute, plan/p0_bodies.py)
    P1 windows: each pair's view, window, slab        (compute, plan/p1_windows.py)
    P2 atlas: probes, pieces, bands, cuts, rounds     (compute, plan/p2_atlas.py)
    P3 tile words: each tile's matrices as the frame reads them   (compute, plan/p3_tile_words.py)
    -> one submission, one map (a second of each when P2 needs more room than it had): the
       windows, the plan's summary and its tiles
    -> TilePlan: each tile's view gathered from its pair's window (host, NumPy), to decode
       records; the frame copies P3's tile words into its own buffer on the GPU

The geometry of every pair (three frames, the separating-axis test, the view, the window, the
slab and the count side) and the atlas's layout (which windows are probed, their pieces, each
tile's band, column and round) are the GPU's; the host uploads the pairs and gathers the tiles'
views. A plan equals the NumPy planner's up to single precision's rounding relative to each pair's
own extent (the bound is in :mod:`pycinder.focused.plan.p1_windows`), and its layout is the NumPy
planner's for the same window sizes, exactly. Where the two planners round a close decision
differently (a frame's area, the order of equal extents, a window of almost a whole number of
pixels), each plan holds a valid window of the pair, and the answers follow the tolerance
contract either way.

The NumPy planner plans a query that stops at its first pair (``in_collision``: its lead pairs are
chosen from the world boxes and planned into rounds of their own, and its tiles carry the flag that
stops the GPU), one of more than :data:`~pycinder.focused.plan.p2_atlas.MAX_PAIRS` candidate pairs,
and one of more tiles than the planner's buffers hold on the device.
"""

from __future__ import annotations

import time

import numpy as np
import wgpu

from ...gpu.buffers import DEFAULT_TIMEOUT, Readback
from ...gpu import native
from ...gpu.device import Gpu
from ...gpu.layout import TILE
from ...util.text import plural
from .p2_atlas import BAND_SLACK, MAX_PAIRS, MAX_TILES, NO_FIT, SUMMARY, AtlasPlan, AtlasPlanner
from .p2_atlas import TILE as ATLAS_TILE
from .plan_numpy import LazyViewPlan, TilePlan, check_pixels, empty_plan, plan_tiles
from .p0_bodies import GpuBodies
from .p3_tile_words import TileWords
from .p1_windows import WINDOW, GpuWindows


PASSES = (GpuBodies, GpuWindows, AtlasPlanner, TileWords)
"""The planner's passes, in the order they run (the docs' pass table)."""


class GpuPlanner:
    """Plans tiles with passes P0-P3 on the GPU; their pipelines and buffers are made once and
    reused (the buffers grown when a plan needs more).

    Parameters
    ----------
    gpu : Gpu
    timeout : float
        Seconds a readback may wait for the GPU.
    """

    def __init__(self, gpu: Gpu, timeout: float = DEFAULT_TIMEOUT) -> None:
        self.gpu = gpu
        self.timeout = float(timeout)
        self.windows = GpuWindows(gpu, timeout)
        self.atlas = AtlasPlanner(gpu, timeout)
        self.words = TileWords(gpu, timeout)
        self.readback = Readback(gpu.device, "tile plan")
        self.waited_ms = 0.0
        """Milliseconds the last :meth:`plan` waited for the GPU (the passes and the map)."""
        self._recent = 0  # tiles of the last plan (the next one's room)

    def plan(self, pairs: np.ndarray, pair_tolerances: np.ndarray, local_lo: np.ndarray,
             local_hi: np.ndarray, world_lo: np.ndarray, world_hi: np.ndarray,
             transforms: np.ndarray, *, budget_pixels: int, probe: bool = True,
             open_bodies: np.ndarray | None = None, max_pixels: float = float("inf"),
             faces: np.ndarray | None = None) -> tuple[TilePlan, wgpu.GPUBuffer | None]:
        """Tiles for candidate pairs, as :func:`pycinder.focused.plan.plan_numpy.plan_tiles` makes
        them (whose parameters these are; there are no lead pairs here).

        Parameters
        ----------
        pairs : (K, 2) int
        pair_tolerances : (K,) float
        local_lo, local_hi, world_lo, world_hi : (N, 3) float
        transforms : (N, 4, 4) float
        budget_pixels : int
        probe : bool
        open_bodies : (N,) bool, optional
        max_pixels : float
        faces : (N,) int, optional

        Returns
        -------
        plan : TilePlan
        words : wgpu.GPUBuffer or None
            The plan's tiles as the frame's passes read them (:data:`~pycinder.gpu.layout.TILE`,
            pass P3), valid until the next call; None for a plan made on the host (more than
            :data:`~pycinder.focused.plan.p2_atlas.MAX_PAIRS` pairs, or more tiles than the
            planner's buffers hold on this device).

        Raises
        ------
        GpuMemoryError
            The windows hold more than ``max_pixels`` pixels.
        GpuTimeoutError
            The GPU did not finish in time.
        """
        k = len(pairs)
        self.waited_ms = 0.0

        def on_host() -> tuple[TilePlan, None]:
            return plan_tiles(pairs, pair_tolerances, local_lo, local_hi, world_lo, world_hi,
                              transforms, budget_pixels=budget_pixels, probe=probe,
                              open_bodies=open_bodies, max_pixels=max_pixels, faces=faces), None

        if k == 0:
            return empty_plan(), None
        if k > MAX_PAIRS:
            return on_host()
        p1, p2, p3 = self.windows, self.atlas, self.words
        p1.upload_bodies(local_lo, local_hi, world_lo, world_hi, transforms, open_bodies,
                         faces=faces)
        p1.upload_pairs(pairs, pair_tolerances)
        # Room for most plans (fewer tiles than twice their pairs, or about the last plan's);
        # a larger one runs again with room for what it needs (P2 says how many).
        most = min(p2.tiles.limit // ATLAS_TILE.size, p3.tiles.limit // TILE.size) - BAND_SLACK
        p2.capacity = min(max(2 * k, self._recent + self._recent // 4) + 16, MAX_TILES, most)
        for _ in range(2):
            raw, data = self._run(k, budget_pixels, probe, faces is not None)
            head = data[:SUMMARY.size].view(SUMMARY.dtype)[0]
            pixels = int(head["pixels_lo"]) + (int(head["pixels_hi"]) << 32)
            if pixels > max_pixels:
                check_pixels(p1.to_plan(raw, pairs, pair_tolerances), pairs, pair_tolerances,
                             max_pixels)
            if not head["fits"]:
                needed = int(head["needed"])
                if needed == NO_FIT or needed > most:  # more tiles than the GPU's buffers hold
                    return on_host()
                p2.capacity = needed
                continue
            atlas = p2.parse(data)
            self._recent = len(atlas)
            return self._tiles(raw, atlas, pairs, pair_tolerances), p3.tiles.buffer
        raise RuntimeError("pass P2's plan did not fit buffers grown to its need")

    def _run(self, k: int, budget_pixels: int, probe: bool, faces: bool
             ) -> tuple[np.ndarray, np.ndarray]:
        """Encode P0, P1, P2 and P3 over ``k`` uploaded pairs, submit once, map once: the windows
        (K,) and the bytes of P2's plan (see :meth:`AtlasPlanner.parse`); P3's tile words stay on
        the GPU."""
        p1, p2 = self.windows, self.atlas
        encoder = native.encoder(self.gpu.device, "tile planner")
        p1.encode(encoder, k)
        p2.encode(encoder, p1.atlas, k, budget_pixels=budget_pixels, probe=probe, faces=faces)
        self.words.encode(encoder, windows=p1.buffer, pairs=p1.pairs, atlas_tiles=p2.tiles,
                          summary=p2.summary, capacity=p2.capacity, bodies=p1.poses)
        head = k * WINDOW.size
        nbytes = head + p2.nbytes
        staging = self.readback.ensure(nbytes)
        encoder.copy_buffer_to_buffer(p1.buffer.buffer, 0, staging, 0, head)
        p2.copy_into(encoder, staging, head)
        self.gpu.device.queue.submit([encoder.finish()])
        t0 = time.perf_counter()
        data = self.readback.read(nbytes, np.uint8, timeout=self.timeout,
                                  waiting_for=f"the tile plan of {plural(k, 'candidate pair')}")
        self.waited_ms += (time.perf_counter() - t0) * 1e3
        return data[:head].view(WINDOW.dtype), data[head:]

    def _tiles(self, raw: np.ndarray, atlas: AtlasPlan, pairs: np.ndarray,
               pair_tolerances: np.ndarray) -> TilePlan:
        """The :class:`TilePlan` of P2's tiles, each with its pair's window from P1 (``raw``,
        one per pair). The frame needs only the tiles' pairs, places and flags (its tile words
        are P3's); their views are gathered when first read (:class:`GpuTilePlan`)."""
        if len(atlas) == 0:
            return empty_plan(atlas.separated)
        k = atlas.pair
        flags = raw["flags"].take(k).astype(np.int64) | atlas.flags
        return GpuTilePlan(k, np.take(pairs, k, axis=0).astype(np.int64), atlas.window, flags,
                           atlas.round, atlas.round_rows, atlas.atlas_width, atlas.separated,
                           _Views(raw, atlas, pair_tolerances, self.windows.anchor))


class _Views:
    """What the views of a :class:`GpuTilePlan`'s tiles are gathered from: P1's windows
    ``raw`` (one per pair), P2's tiles, the pairs' tolerances and the bodies' anchors."""

    def __init__(self, raw: np.ndarray, atlas: AtlasPlan, pair_tolerances: np.ndarray,
                 anchor: np.ndarray) -> None:
        self.raw, self.atlas, self.anchor = raw, atlas, anchor
        self.pair_tolerances = np.asarray(pair_tolerances, np.float64)

    def gather(self, which: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``axes`` (T, 3, 3), ``origin`` (T, 3), ``pixel`` (T,) and ``slab`` (T, 2), float64:
        each tile's pair's window, its origin moved to its part of the window as
        :func:`pycinder.focused.plan.plan_numpy._place` moves it; of tiles ``which`` (n,) only,
        where given."""
        atlas = self.atlas
        k = atlas.pair if which is None else atlas.pair[which]
        r = self.raw.take(k)
        axes = r["axes"][:, :, :3].astype(np.float64)
        pixel = self.pair_tolerances.take(k)
        origin = self.anchor.take(r["anchor"], axis=0) + r["origin"]
        moved, u0, v0, shift = atlas.moved, atlas.u0, atlas.v0, atlas.shift
        if which is not None:
            moved, u0, v0, shift = moved[which], u0[which], v0[which], shift[which]
        u = np.where(moved, u0, 0) + shift
        v = np.where(moved, v0, 0)
        origin += (u * pixel)[:, None] * axes[:, 0] + (v * pixel)[:, None] * axes[:, 1]
        return axes, origin, pixel, r["slab"].astype(np.float64)


class GpuTilePlan(LazyViewPlan):
    """A :class:`TilePlan` made by the GPU planner, whose tiles' views (``axes``, ``origin``,
    ``pixel``, ``slab``) are gathered on the host only when first read: to decode records, to
    cut tiles again, or to compare plans. A query that reads none of them (pairs only, or
    records left undecoded) skips that work."""

    def __init__(self, pair: np.ndarray, bodies: np.ndarray, window: np.ndarray,
                 flags: np.ndarray, round: np.ndarray, round_rows: list[int], atlas_width: int,
                 separated: int, views: _Views) -> None:
        super().__init__(pair=pair, bodies=bodies, window=window, flags=flags, round=round,
                         round_rows=round_rows, atlas_width=atlas_width, separated=separated)
        self._views = views

    def _gather(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self._views.gather()

    def views(self, which: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """See :meth:`TilePlan.views`: gathered for tiles ``which`` alone, unless all were."""
        if self._gathered is not None:
            return super().views(which)
        which = np.asarray(which)
        if which.dtype == bool:
            which = np.flatnonzero(which)
        return self._views.gather(which.astype(np.int64))


__all__ = ["PASSES", "GpuPlanner", "GpuTilePlan"]

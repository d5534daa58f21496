"""Pass P2 of the GPU tile planner, atlas: the integer part of
:func:`pycinder.focused.plan.plan_numpy.plan_tiles` (with ``lead=None``) on the GPU, tile for tile
(``plan_atlas.wgsl``).

Given each candidate pair's window (:data:`WINDOW`: whether the pair has one, its size in pixels
and whether the pair is dense), the pass makes the tiles of the plan that
:func:`~pycinder.focused.plan.plan_numpy._phases_of`,
:func:`~pycinder.focused.plan.plan_numpy.fitted_width`,
:func:`~pycinder.focused.plan.plan_numpy._layout`,
:func:`~pycinder.focused.plan.plan_numpy._place` and
:func:`~pycinder.focused.plan.plan_numpy.concat_plans` make, in the same order: for each tile its
pair, its part of the window (``u0``, ``v0``, ``moved``, ``shift``), its extra flags, its place in
the atlas and its round, and each round's rows and the atlas width (:data:`TILE`, :data:`SUMMARY`).
Every figure is an integer, and equal to the NumPy planner's.

How it follows the NumPy planner
--------------------------------
Section by section, the tiles of a phase in ``_phases_of``'s order are: S, small windows whole;
O, the pieces of windows left unprobed (every window when probes are off or no window is large);
L, the probes of large windows (these three make phase 0); P, the pieces of large windows
(phase 1). ``_layout`` sorts a phase's tiles by height class (stably), so a tile's index in
that order and its start column in its class's run of bands are the tiles and widths of its
class before it: in earlier sections, in earlier windows of its section, and in its own window.
A window's pieces are a grid whose full rows are all of the tallest class and whose last row is
of one class, so each window adds to at most two classes, in closed form. The pass therefore
scans, over the pairs, 40 lanes (4 sections x 5 classes x tiles and widths), and each tile's
class index and start column follow from its pair's prefix in O(1). From the start column come
its band (``start // width``), its column and whether the band's end cuts it. A tile crosses at
most one band end (no tile is wider than the atlas), and each band end is crossed by at most one
tile. ``_layout`` lists the parts by band, each band's first parts in class order and then the
second part of the tile cut at the band's start; so the first part of a tile goes at its class
index plus the cuts of the bands two or more before its own, and a second part after the tiles
that start in its band and the second parts before it. These counts come from one more scan,
over the bands, of the tiles that start in each band and of its cut. ``_layout``'s rounds take a
class's bands into a round as many at a time as fit, which is closed form per class (the first
run fills the round the class starts in, the others hold ``max(rows_budget // rows, 1)`` bands),
so a band's round and row follow from its class's first band's; the last band of each round
gives the round's rows. Rounds of phase 1 are numbered after phase 0's (``concat_plans``).

Dispatches, in one compute pass (:meth:`AtlasPlanner.encode`):

1. ``count``, one workgroup of :data:`GROUP` threads, each over a block of consecutive pairs:
   the kept windows, their pixels (64 bits), whether any window is large (and any of a dense
   pair), a bound on the tiles; then per pair the 40 lanes of the pairs before it (a blocked
   scan: sum per thread, one workgroup scan, then each thread's pairs again); then thread 0
   computes the plan's constants (:data:`STATE`: the atlas width, class order, bands, the runs
   of bands into rounds), the summary's totals and the indirect arguments of 2 and 4;
2. ``place``, a thread per tile (indirect): the tile's band, counted in its band's word with
   the band's cut (found by a binary search of the pairs' prefixes);
3. ``bands``, one workgroup, blocked over the bands: the tiles and cuts up to each band, its
   round and row, each round's rows, the records of the plan;
4. ``write``, a thread per tile (indirect): the tile's record, and its second part's.

Parallel work: stages 2 and 4 are spread over the GPU. Stages 1 and 3 run on one workgroup;
they would spread over many with the usual three-step scan (a sum per block of pairs or bands,
a scan of the blocks' sums, then each block's scan from its offset) and a reduction of the
totals (atomics) before it: the per-pair and per-band work is already independent of the
order the blocks are done in.

llvmpipe (lavapipe's CPU driver) ends a thread's loops after 65,535 steps in all, silently. The
pair and band stages loop three times over a thread's block (pairs / 256 each), the workgroup
scans are written out step by step, and a tile's search takes ``log2(pairs)`` steps, so plans of
up to :data:`MAX_PAIRS` pairs and :data:`MAX_TILES` tiles (bands: at most as many, plus 10) stay
under that.

Capacity
--------
The number of tiles is found on the GPU. The tile records (:data:`TILE`) hold ``capacity``
tiles, the band scratch and the round rows ``capacity + BAND_SLACK`` bands (a phase has at most
a band per tile plus one per class, so a plan whose tiles fit has bands that fit too). When the
plan does not fit, nothing is written but the summary, whose ``needed`` says how many records it
needs (exact once its bands fit, else the bound ``pieces + bands``); :meth:`AtlasPlanner.parse`
raises the capacity to that, the next :meth:`AtlasPlanner.encode` grows the buffers, and the
caller encodes the pass again (grow and retry; the second try always fits).
:meth:`AtlasPlanner.run` sizes the buffers from its windows first (a host bound of
``2 (pieces + windows) + 10``, or the most a buffer binding holds), so it runs once. The
readback copies the whole capacity (the count is not known when the copy is encoded). Plans of
more than :data:`MAX_TILES` tiles are refused (``needed`` = 2**32 - 1;
:class:`~pycinder.errors.GpuMemoryError`): every count of the pass then fits 32 bits (widths
below ``MAX_TILES * 512``), and windows of 2**32 - 1 pixels (pass P1's "too wide to count") land
there. (:class:`~pycinder.focused.plan.plan_gpu.GpuPlanner` plans such a query on the host instead.)

Total pixels are summed in 64 bits (two words, ``pixels_lo``, ``pixels_hi``): the comparison with
:data:`~pycinder.focused.plan.plan_numpy.PROBE_PLAN` is exact for any plan, as the NumPy planner's
(an exact int64 sum) is.

Kept windows must be at least a pixel wide and tall (pass P1's are at least ``2 * MARGIN_PX``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import wgpu

from ...errors import GpuMemoryError
from ...gpu.bindings import Resource, Stage, dispatch
from ...gpu.buffers import DEFAULT_TIMEOUT, GrowableBuffer, Readback
from ...gpu import native
from ...gpu.device import Gpu, get_gpu
from ...gpu.structs import Struct
from ...gpu.table import PassInfo
from .plan_numpy import (ATLAS_WIDTH, HEIGHT_CLASS_CONSTS, HEIGHT_CLASSES, MAX_TILE,
    MIN_ATLAS_WIDTH, PROBE, PROBE_PLAN)

GROUP = 256
"""Threads of the one-workgroup stages (``count``, ``bands``); their scans are written out for
this size (8 steps)."""
MAX_TILES = 2**22
"""Most tiles (before band cuts) of a plan the pass makes."""
MAX_PAIRS = 2**20
"""Most candidate pairs of a plan: their prefixes (:data:`PREFIX`, 96 bytes a pair) stay under
WebGPU's default 128 MiB a storage binding, and the one-workgroup stages' threads (stage count
loops three times over ``MAX_PAIRS / GROUP`` pairs, stage bands over ``MAX_TILES / GROUP``
bands) under llvmpipe's 65,535 loop steps (see the module's notes)."""
BAND_SLACK = 16
"""Bands held beyond the tile capacity (a phase has at most a band per tile and one per class)."""

WINDOW = Struct("AtlasWindow", [
    ("kept", "u32", "1: the pair has a window; 0: its bounding volumes are apart"),
    ("w", "u32", "window width in pixels (at least 1 when kept)"),
    ("h", "u32", "window height in pixels (at least 1 when kept)"),
    ("dense", "u32", "1: the pair's bodies have PROBE_FACES faces or more together"),
], doc="One candidate pair's window, as pass P2 reads it.")

PARAMS = Struct("AtlasParams", [
    ("pairs", "u32", "candidate pairs K (windows read)"),
    ("probe", "u32", "1: large windows get probes (plan_tiles' probe)"),
    ("faces", "u32", "1: dense bits given (plan_tiles' faces); 0: every pair is dense"),
    ("capacity", "u32", "tile records the tile buffer holds"),
    ("band_capacity", "u32", "bands the band buffers and round rows hold"),
    ("budget_lo", "u32", "budget_pixels, low 32 bits"),
    ("budget_hi", "u32", "budget_pixels, high 32 bits"),
    ("pad", "u32", ""),
], uniform=True, doc="Pass P2's parameters.")

PREFIX = Struct("AtlasPairPrefix", [
    ("tiles", "vec4u", "tiles of sections S, O, L, P in the pairs before this one"),
    ("count0", "array<u32, 5>", "per class, tiles of this pair's phase-0 section before it"),
    ("width0", "array<u32, 5>", "their widths"),
    ("count1", "array<u32, 5>", "per class, tiles of section P before it"),
    ("width1", "array<u32, 5>", "their widths"),
], doc="Per candidate pair, what the pairs before it hold (pass P2's scan).")

STATE = Struct("AtlasState", [
    ("sections", "vec4u", "tiles of sections S, O, L (phase 0) and P (phase 1)"),
    ("tiles", "u32", "tiles of the plan before band cuts (0 when it does not fit)"),
    ("tiles0", "u32", "tiles of phase 0"),
    ("bands", "u32", "bands of the plan (0 when it does not fit)"),
    ("bands0", "u32", "bands of phase 0"),
    ("rounds", "u32", "rounds of the plan"),
    ("rounds0", "u32", "rounds of phase 0"),
    ("width", "u32", "atlas width"),
    ("shift", "u32", "log2 of the atlas width"),
    ("probes", "u32", "1: two phases"),
    ("fits", "u32", "1: the buffers hold the plan"),
    ("rows_budget", "u32", "rows per round: max(budget_pixels // width, 1), capped at 2**30"),
    ("class_first", "array<u32, 10>", "per phase and class: its first tile in class order"),
    ("band_first", "array<u32, 10>", "its first band among the plan's"),
    ("class_bands", "array<u32, 10>", "its bands"),
    ("round_start", "array<u32, 10>", "the round of its first band"),
    ("row_start", "array<u32, 10>", "the row of its first band"),
    ("first_run", "array<u32, 10>", "its bands that join the round it starts in (0: starts one)"),
    ("per_round", "array<u32, 10>", "its bands per round after those"),
    ("before_count", "array<u32, 20>", "per section and class: tiles of earlier sections"),
    ("before_width", "array<u32, 20>", "their widths"),
], doc="The plan's constants, written by stage count of pass P2 for its later stages.")

SUMMARY = Struct("AtlasSummary", [
    ("tiles", "u32", "tile records of the plan (band cuts' second parts included)"),
    ("needed", "u32", ("tile records the plan needs (a bound until its bands fit; 2**32 - 1: "
                       "more than MAX_TILES)")),
    ("fits", "u32", "1: the records and round rows hold the plan"),
    ("windows", "u32", "kept windows"),
    ("separated", "u32", "candidate pairs without a window"),
    ("pixels_lo", "u32", "pixels of the kept windows (sum of w h), low 32 bits"),
    ("pixels_hi", "u32", "high 32 bits"),
    ("atlas_width", "u32", "atlas width (fitted_width; ATLAS_WIDTH for an empty plan)"),
    ("rounds", "u32", "rounds of the plan"),
    ("phases", "u32", "phases of the plan (0, 1 or 2)"),
    ("phase_tiles", "u32", "tile records of phase 0 (phase 1's follow)"),
    ("phase_rounds", "u32", "rounds of phase 0"),
    ("pieces", "u32", "tiles before band cuts"),
    ("bands", "u32", "bands of the plan"),
    ("cuts", "u32", "tiles cut at a band's end"),
    ("rows_budget", "u32", "rows per round"),
], doc="Pass P2's summary; each round's rows follow it in the same buffer.")

TILE = Struct("AtlasTile", [
    ("window", "vec4u", "atlas column, row (in its round), width, height"),
    ("pair", "u32", "candidate pair of its window"),
    ("u0", "u32", "the part's offset in its window along screen x, pixels"),
    ("v0", "u32", "along screen y"),
    ("shift", "u32", "column of a band cut's second part in its tile (0 otherwise)"),
    ("moved", "u32", "1: its origin is moved by u0, v0 pixels (as _place moves it)"),
    ("flags", "u32", "FLAG_* bits added to the window's (FLAG_SKIP_IF_HIT in phase 1)"),
    ("round", "u32", "the round it is processed in"),
    ("phase", "u32", "0, or 1 for the pieces of probed windows"),
], doc="One tile of the plan (a part of a window, or a band cut's second part), in order.")

CONSTS: dict[str, int | float] = {
    "GROUP": GROUP, "MAX_TILES": MAX_TILES, "MAX_TILE_W": MAX_TILE[0],
    "MAX_TILE_H": MAX_TILE[1], "PROBE_W": PROBE[0], "PROBE_H": PROBE[1],
    "PROBE_PLAN": PROBE_PLAN, "ATLAS_WIDTH": ATLAS_WIDTH, "MIN_ATLAS_WIDTH": MIN_ATLAS_WIDTH,
    **HEIGHT_CLASS_CONSTS,
}

assert len(HEIGHT_CLASSES) == 5 and list(HEIGHT_CLASSES) == sorted(HEIGHT_CLASSES), \
    "plan_atlas.wgsl's lanes hold five height classes"
assert HEIGHT_CLASSES[-1] == MAX_TILE[1] and HEIGHT_CLASSES[-2] < MAX_TILE[1], \
    "a piece of a full row is of the tallest class, and only it"
assert MAX_TILE[0] <= ATLAS_WIDTH, "a tile crosses at most one band end"
assert PROBE[1] <= HEIGHT_CLASSES[2], "probes are of the three lowest classes"

_U = wgpu.BufferUsage
NO_FIT = 0xFFFFFFFF
"""The summary's ``needed`` of a plan of more than :data:`MAX_TILES` tiles."""


def atlas_windows(kept: np.ndarray, w: np.ndarray, h: np.ndarray,
                  dense: np.ndarray | None = None) -> np.ndarray:
    """Pass P2's input from host arrays.

    Parameters
    ----------
    kept : (K,) bool
        Whether each candidate pair has a window.
    w, h : (K,) int
        Window sizes in pixels (ignored where not kept).
    dense : (K,) bool, optional
        Whether the pair's bodies have :data:`~pycinder.focused.plan.plan_numpy.PROBE_FACES` faces
        or more together (default: none is; pass ``faces=False`` to the planner for "every pair").

    Returns
    -------
    (K,) structured array of :data:`WINDOW`
    """
    out = WINDOW.zeros(len(kept))
    out["kept"] = np.asarray(kept, bool)
    out["w"] = np.where(out["kept"] != 0, w, 0)
    out["h"] = np.where(out["kept"] != 0, h, 0)
    if dense is not None:
        out["dense"] = np.asarray(dense, bool)
    return out


@dataclass
class AtlasPlan:
    """The integer part of a :class:`~pycinder.focused.plan.plan_numpy.TilePlan`, read back from
    pass P2.

    pair : (T,) int64
        Each tile's candidate pair (``TilePlan.pair``).
    u0, v0 : (T,) int64
        The part of its window the tile is, from the window's corner, in pixels.
    moved : (T,) bool
        Whether its origin is moved by ``u0``, ``v0`` (as ``_place`` decides it).
    shift : (T,) int64
        A band cut's second part: its column in the tile cut (0 otherwise).
    flags : (T,) int64
        Flags added to its window's (``FLAG_SKIP_IF_HIT`` in phase 1).
    window : (T, 4) int64
        Atlas column and row (in its round), width and height (``TilePlan.window``).
    round : (T,) int64
        ``TilePlan.round``.
    phase : (T,) int64
        0, or 1 for the pieces of probed windows.
    round_rows : list[int]
        ``TilePlan.round_rows``.
    atlas_width : int
    separated : int
        Candidate pairs without a window.
    windows : int
        Kept windows.
    pixels : int
        Pixels of the kept windows.
    """

    pair: np.ndarray
    u0: np.ndarray
    v0: np.ndarray
    moved: np.ndarray
    shift: np.ndarray
    flags: np.ndarray
    window: np.ndarray
    round: np.ndarray
    phase: np.ndarray
    round_rows: list[int] = field(default_factory=list)
    atlas_width: int = ATLAS_WIDTH
    separated: int = 0
    windows: int = 0
    pixels: int = 0

    def __len__(self) -> int:
        return len(self.pair)


class AtlasPlanner:
    """Pass P2: the tiles of a plan from its candidate pairs' windows, on the GPU.

    Parameters
    ----------
    gpu : Gpu, optional
        Default: :func:`~pycinder.gpu.device.get_gpu`.
    timeout : float
        Seconds a readback may wait for the GPU.
    capacity : int
        Tile records the buffers hold at first (grown when a plan needs more).

    Attributes
    ----------
    tiles : GrowableBuffer
        The plan's tiles (:data:`TILE`), in order, once the pass has run and the plan fit.
    summary : GrowableBuffer
        :data:`SUMMARY`, then each round's rows (u32).
    """

    SHADER: ClassVar[str] = "plan_atlas"
    """Its shader, ``shaders/plan_atlas.wgsl``."""
    INFO: ClassVar[PassInfo] = PassInfo(
        "P2", "atlas", "each kept window's tiles, their places in the atlas's bands and their "
        "rounds, in the NumPy planner's order", when="when tiles are planned on the GPU")

    def __init__(self, gpu: Gpu | None = None, timeout: float = DEFAULT_TIMEOUT,
                 capacity: int = 4096) -> None:
        self.gpu = gpu or get_gpu()
        self.timeout = timeout
        self.capacity = max(int(capacity), 1)
        device = self.gpu.device
        structs = (WINDOW, PARAMS, PREFIX, STATE, SUMMARY, TILE)

        def stage(entry: str) -> Stage:
            return Stage(self.gpu, self.SHADER, entry, label=f"{self.INFO.title}: {entry}",
                         structs=structs, consts=CONSTS)

        self.stages = {e: stage(e) for e in ("count", "place", "bands", "write")}

        def grow(label: str, usage: int = _U.STORAGE) -> GrowableBuffer:
            return GrowableBuffer(device, f"{self.INFO.name} {label}", usage)

        self.windows = grow("windows", _U.STORAGE | _U.COPY_DST)
        self.prefix = grow("pair prefixes")
        self.band_counts = grow("band counts")
        self.band_info = grow("bands")
        self.summary = grow("summary", _U.STORAGE | _U.COPY_SRC)
        self.tiles = grow("tiles", _U.STORAGE | _U.COPY_SRC)
        self.state = device.create_buffer(label=f"{self.INFO.name} state", size=STATE.size,
                                          usage=_U.STORAGE)
        self.args = device.create_buffer(label=f"{self.INFO.name} indirect arguments", size=16,
                                         usage=_U.STORAGE | _U.INDIRECT)
        self.params = device.create_buffer(label=f"{self.INFO.name} parameters",
                                           size=PARAMS.size, usage=_U.UNIFORM | _U.COPY_DST)
        self.readback = Readback(device, f"{self.INFO.name} plan")

    @property
    def band_capacity(self) -> int:
        """Bands (and rounds) the buffers hold."""
        return self.capacity + BAND_SLACK

    def _ensure(self, pairs: int) -> None:
        self.prefix.ensure(max(pairs, 1) * PREFIX.size)
        self.band_counts.ensure(4 * self.band_capacity)
        self.band_info.ensure(16 * self.band_capacity)
        self.summary.ensure(SUMMARY.size + 4 * self.band_capacity)
        self.tiles.ensure(TILE.size * self.capacity)

    def encode(self, encoder: wgpu.GPUCommandEncoder, windows: Resource, pairs: int, *,
               budget_pixels: int, probe: bool = True, faces: bool = True) -> None:
        """Encode the pass (one compute pass of four dispatches) into ``encoder``.

        The parameters are written to the queue at once: encode the pass once per submission.

        Parameters
        ----------
        encoder : GPUCommandEncoder
        windows : buffer, GrowableBuffer or (buffer, offset, size)
            ``pairs`` records of :data:`WINDOW` (written earlier in the same encoder, or
            uploaded).
        pairs : int
            Candidate pairs K.
        budget_pixels : int
            Most atlas pixels of a round (``plan_tiles``' ``budget_pixels``).
        probe : bool
            ``plan_tiles``' ``probe``.
        faces : bool
            Whether the windows' ``dense`` bits count (``plan_tiles`` given ``faces``); False:
            every pair is dense (``faces=None``).
        """
        if not 0 <= pairs <= MAX_PAIRS:
            raise ValueError(f"{self.INFO.title} plans at most {MAX_PAIRS} candidate pairs, "
                             f"not {pairs}")
        self._ensure(pairs)
        budget = min(max(int(budget_pixels), 0), 2**64 - 1)
        params = PARAMS.zeros()
        params["pairs"] = pairs
        params["probe"] = bool(probe)
        params["faces"] = bool(faces)
        params["capacity"] = self.capacity
        params["band_capacity"] = self.band_capacity
        params["budget_lo"] = budget & 0xFFFFFFFF
        params["budget_hi"] = budget >> 32
        self.gpu.device.queue.write_buffer(self.params, 0, params)
        s = self.stages
        common = {"params": self.params, "prefix": self.prefix, "state": self.state}
        cpass = encoder.begin_compute_pass(label=self.INFO.title)
        dispatch(cpass, s["count"], s["count"].group(
            windows=windows, **common, args=self.args, band_counts=self.band_counts,
            summary=self.summary), 1)
        dispatch(cpass, s["place"], s["place"].group(
            windows=windows, **common, band_counts=self.band_counts), indirect=(self.args, 0))
        dispatch(cpass, s["bands"], s["bands"].group(
            params=self.params, state=self.state, band_counts=self.band_counts,
            band_info=self.band_info, summary=self.summary), 1)
        dispatch(cpass, s["write"], s["write"].group(
            windows=windows, **common, band_info=self.band_info, tiles=self.tiles),
            indirect=(self.args, 0))
        cpass.end()

    def copy_out(self, encoder: wgpu.GPUCommandEncoder) -> int:
        """Encode the copy of the summary, the round rows and the tile records into the
        readback buffer (after :meth:`encode`); returns the bytes to give :meth:`finish`."""
        nbytes = self.nbytes
        return self.copy_into(encoder, self.readback.ensure(nbytes), 0)

    @property
    def nbytes(self) -> int:
        """Bytes :meth:`copy_into` copies: the summary and round rows, then the tile records."""
        return SUMMARY.size + 4 * self.band_capacity + TILE.size * self.capacity

    def copy_into(self, encoder: wgpu.GPUCommandEncoder, staging: wgpu.GPUBuffer,
                  offset: int) -> int:
        """Encode the copy of the summary, the round rows and the tile records into
        ``staging`` at ``offset`` (after :meth:`encode`; what :meth:`parse` reads); returns
        the bytes copied (:attr:`nbytes`)."""
        head = SUMMARY.size + 4 * self.band_capacity
        records = TILE.size * self.capacity
        encoder.copy_buffer_to_buffer(self.summary.buffer, 0, staging, offset, head)
        encoder.copy_buffer_to_buffer(self.tiles.buffer, 0, staging, offset + head, records)
        return head + records

    def finish(self, nbytes: int) -> AtlasPlan | None:
        """Wait for the submitted pass (at most ``timeout`` seconds) and read its plan (see
        :meth:`parse`).

        Raises
        ------
        GpuTimeoutError
            The GPU did not finish in time.
        """
        data = self.readback.read(nbytes, np.uint8, timeout=self.timeout,
                                  waiting_for=f"the {self.INFO.title} plan")
        return self.parse(data)

    def parse(self, data: np.ndarray) -> AtlasPlan | None:
        """The plan in bytes copied by :meth:`copy_into`.

        Parameters
        ----------
        data : (nbytes,) uint8

        Returns
        -------
        AtlasPlan or None
            None when the plan did not fit: the buffers have grown to what it needs, and the
            pass must be encoded again.

        Raises
        ------
        GpuMemoryError
            The plan has more than :data:`MAX_TILES` tiles.
        """
        head = data[:SUMMARY.size].view(SUMMARY.dtype)[0]
        if not head["fits"]:
            needed = int(head["needed"])
            if needed == NO_FIT:
                raise GpuMemoryError(
                    f"the plan has more than {MAX_TILES} tiles ({int(head['windows'])} windows "
                    f"of {int(head['pixels_lo']) + (int(head['pixels_hi']) << 32)} pixels)")
            self.capacity = max(self.capacity, needed)
            return None
        n, rounds = int(head["tiles"]), int(head["rounds"])
        start = SUMMARY.size + 4 * self.band_capacity
        rows = data[SUMMARY.size:SUMMARY.size + 4 * rounds].view(np.uint32)
        rec = data[start:start + TILE.size * n].view(TILE.dtype)
        i64 = np.int64
        return AtlasPlan(
            pair=rec["pair"].astype(i64), u0=rec["u0"].astype(i64), v0=rec["v0"].astype(i64),
            moved=rec["moved"] != 0, shift=rec["shift"].astype(i64),
            flags=rec["flags"].astype(i64), window=rec["window"].astype(i64),
            round=rec["round"].astype(i64), phase=rec["phase"].astype(i64),
            round_rows=[int(r) for r in rows], atlas_width=int(head["atlas_width"]),
            separated=int(head["separated"]), windows=int(head["windows"]),
            pixels=int(head["pixels_lo"]) + (int(head["pixels_hi"]) << 32))

    def run(self, windows: np.ndarray, *, budget_pixels: int, probe: bool = True,
            faces: bool = True) -> AtlasPlan:
        """Upload windows, plan their tiles and read the plan back.

        Parameters
        ----------
        windows : (K,) structured array of :data:`WINDOW`
            See :func:`atlas_windows`.
        budget_pixels, probe, faces
            As :meth:`encode`'s.

        Returns
        -------
        AtlasPlan
        """
        windows = np.ascontiguousarray(windows, WINDOW.dtype)
        k = len(windows)
        kept = windows["kept"] != 0
        w = windows["w"][kept].astype(np.int64)
        h = windows["h"][kept].astype(np.int64)
        pieces = int(((-(-w // MAX_TILE[0])) * (-(-h // MAX_TILE[1]))).sum())
        if pieces + len(w) <= MAX_TILES:
            most = self.tiles.limit // TILE.size - BAND_SLACK
            self.capacity = max(self.capacity, min(2 * (pieces + len(w)) + 10, most))
        self.windows.ensure(max(windows.nbytes, WINDOW.size))
        self.windows.write(windows)
        for _ in range(3):
            encoder = native.encoder(self.gpu.device, self.INFO.title)
            self.encode(encoder, self.windows, k, budget_pixels=budget_pixels, probe=probe,
                        faces=faces)
            nbytes = self.copy_out(encoder)
            self.gpu.device.queue.submit([encoder.finish()])
            plan = self.finish(nbytes)
            if plan is not None:
                return plan
        raise RuntimeError(f"{self.INFO.title}: the plan did not fit buffers grown to its need")


__all__ = ["BAND_SLACK", "GROUP", "MAX_PAIRS", "MAX_TILES", "PARAMS", "PREFIX", "STATE",
           "SUMMARY", "TILE", "WINDOW", "AtlasPlan", "AtlasPlanner", "NO_FIT", "atlas_windows"]

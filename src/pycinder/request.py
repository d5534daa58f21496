"""What a query asks for: every option, checked once, frozen.

:class:`CollisionRequest` is shared by :class:`~pycinder.Detector`,
:func:`~pycinder.find_collisions`, :class:`~pycinder.CollisionManager` and ``pycinder check``.

The tolerance contract (strategy ``"focused"``, the default)
------------------------------------------------------------
With ``tolerance = t`` in world units, for every pair of closed bodies:

1. A pair whose exact distance is at least ``t`` is never reported.
2. A pair whose penetration is at least ``2 t`` is always reported: the pair still overlaps when
   either body is moved by ``2 t`` in any direction. Exactly what is guaranteed: the pair is
   reported when the overlap contains a ball of radius ``0.71 t``, or when an edge of one body
   passes at least ``1.6 t`` inside the other. Solids at the scale of the tolerance meet this
   whenever they penetrate by ``2 t``; a wall thinner than about ``1.4 t`` can pass through a
   body unseen, as with any method that samples space at a spacing.
3. Both hold whatever the scene's extent, its units and its body count: each candidate pair is
   tested in its own tiles, whose pixels are ``t`` wide, so other bodies never change a pair's
   answer. Pairs in between (closer than ``t``, or overlapping by less than ``2 t``) may go
   either way.

Why: each tile's pixels are ``t`` wide, and every pixel centre's ray is cast through both bodies
in the tile. Where such a ray leaves the overlap it crosses one body's surface inside the other:
that surface point is tested exactly, so a ball of radius ``0.71 t`` in the overlap (which always
holds a pixel centre's ray) is always found, and a hit is a real overlap (promise 1 with room to
spare). Edges are also sampled at most a pixel apart along each axis and tested at their pixel's
centre, at most ``0.71 t`` from the edge (still promise 1): an edge point ``1.6 t`` deep is
always within reach of a sample.

Without a tolerance, each pair gets ``DEFAULT_RELATIVE_TOLERANCE`` (1%) of the smaller body's
size (the length of its bounding box's diagonal in world units,
:func:`~pycinder.tolerance.body_sizes`): the promises
then hold per pair at that scale, again independent of the rest of the scene
(:func:`~pycinder.tolerance.default_pair_tolerances`; the whole policy is
:mod:`pycinder.tolerance`).

Open bodies. A body that is not a closed solid (it has holes, or faces wound inconsistently: any
edge walked more often one way than the other) has no inside, so ray parity is never used for it.
It is tested as a surface:

4. A pair is reported where the open body's surface crosses the other body's surface (an edge of
   one passes through a face of the other: tested exactly, edge by face, by pass F6), or where a
   part of the open body lies inside the other body when that one is a closed solid (promise 2's
   clauses, with the open body's edges and surface points). Surfaces that cross through each
   other are reported; an open body lying 2 ``t`` inside a closed one is reported.
5. A pair whose surfaces are at least ``t`` apart is never reported, as promise 1 says: nothing
   is ever found inside an open body (a ball resting in a cup, clear of its walls, is apart).

Precision. Pixels are resolved in single precision on the GPU: a pair's tolerance must be at
least 2**-20 of its larger body's size and 2**-48 of its distance from the world origin (see
:func:`pycinder.tolerance.resolvable_tolerance`). A default tolerance below that is raised to it
with a :class:`~pycinder.errors.PrecisionWarning`; a tolerance given below it raises. Each body's
vertices are re-centred in double precision before they are rounded, so a mesh stored far from
its own origin keeps its detail. Bodies up to 1e30 units across are supported.

The whole-scene strategy (``"scene"``) is the paper's: one image of ``resolution`` pixels across
the whole scene, with the paper's self-interference and readback options. Its pixel is the
scene's extent divided by the resolution, so it makes no promise in world units.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, fields
from typing import Any, Literal

import numpy as np

STRATEGIES = ("focused", "scene")
SELF_INTERFERENCE_MODES = ("prevent", "filter", "offset")
READBACK_MODES = ("compact", "full", "mipmap", "adaptive")
ENCODINGS = ("edge", "normal")
RECORD_MODES = ("found", "all", "none")
BROAD_PHASES = ("auto", "gpu", "numpy")
PLANNERS = ("auto", "numpy", "gpu")

GPU_BROAD_PHASE_BODIES = 2000
"""Bodies from which ``broad_phase="auto"`` finds the candidate pairs on the GPU: below that the
GPU saves nothing and costs a second round trip (the measurements are in the benchmarks'
README, "Measurements behind the constants")."""

GPU_PLANNER_PAIRS = {"gpu": 250, "cpu": 1000}
"""Candidate pairs from which ``planner="auto"`` plans the tiles on the GPU, on a GPU and on a CPU
adapter (lavapipe, llvmpipe): below that its second submission and map cost more than planning on
the host saves. Measured with ``python -m benchmarks.hostcpu --planner-sweep`` on
ManyBodies scenes (``benchmarks/results/hostcpu.md``, "Which planner"): on an NVIDIA H200 the GPU
planner's frame is as fast from 236 pairs and 1.6-1.7 times as fast from 4,559; on lavapipe as fast
from 1,009 pairs and slower at 236."""

FOUND_RECORDS_PER_PAIR = 16
"""Records kept per pair with ``records="found"`` (the first samples found)."""

DEFAULT_TIMEOUT = 60.0
"""Seconds a query may wait for the GPU (see :class:`CollisionRequest`)."""

DEFAULT_MAX_PIXELS = 2**30
"""Most pixels one focused query's tiles may hold (see :class:`CollisionRequest`)."""

DEFAULT_MEMORY_BUDGET = 256 * 2**20
"""Bytes the focused strategy's atlas may use per round (more pixels are processed in rounds)."""

MAX_BODIES = {"focused": 2**24 - 1, "scene": 65535}
"""Bodies one query can hold: the scene strategy writes 16-bit ids as the paper does; the focused
strategy is limited by tile and record layouts."""


@dataclass(frozen=True)
class RecordMode:
    """What one value of the focused strategy's ``records`` option means (see
    :func:`record_mode`).

    Attributes
    ----------
    name : {"found", "all", "none"}
    read : bool
        Records are kept and read back (otherwise only the per-tile counts are).
    every_tile : bool
        Every tile is tested: tiles of pairs already found are not skipped (no early-out), and
        undecided tiles of a pair found elsewhere are run again for their records.
    probe : bool
        Windows larger than a probe tile are probed at their centre first.
    per_pair : int or None
        Records kept per pair (None: every one).
    """

    name: str
    read: bool
    every_tile: bool
    probe: bool
    per_pair: int | None

    @property
    def complete(self) -> bool:
        """Every record of every pair is kept (what contacts are reduced from)."""
        return self.read and self.per_pair is None


_RECORD_MODES = {
    "found": RecordMode("found", read=True, every_tile=False, probe=True,
                        per_pair=FOUND_RECORDS_PER_PAIR),
    "all": RecordMode("all", read=True, every_tile=True, probe=False, per_pair=None),
    "none": RecordMode("none", read=False, every_tile=False, probe=True, per_pair=0),
}


def record_mode(records: str) -> RecordMode:
    """The meaning of a ``records`` value ("found", "all" or "none"); raises ValueError for any
    other."""
    _one_of("records", records, RECORD_MODES)
    return _RECORD_MODES[records]


_SCENE_ONLY = ("resolution", "self_interference", "readback", "mipmap_levels", "edge_offset")


@dataclass(frozen=True)
class CollisionRequest:
    """Every option of a query, checked when the request is made.

    Parameters
    ----------
    strategy : {"focused", "scene"}
        ``"focused"`` (default): a broad phase, then one tile per candidate pair sized by the
        tolerance. ``"scene"``: the paper's passes over one image of the whole scene.
    tolerance : float, optional
        World-unit tolerance of the focused strategy (see the module's contract). Default: 1% of
        the smaller body's size, per pair.
    resolution : int, optional
        Scene strategy: width and height of the image in pixels (default 1024).
    self_interference : {"prevent", "filter", "offset"}
        Scene strategy: how z-fighting of a body's edges with its own faces is handled (paper
        4.3.1). The focused strategy never tests a body against itself.
    readback : {"compact", "full", "mipmap", "adaptive"}
        Scene strategy: what is read back (paper 4.3.2). The focused strategy reads the per-tile
        counts and the compact records.
    mipmap_levels : int
        Scene strategy, ``readback="mipmap"``: how many 2x2 reductions.
    encode : {"edge", "normal"}
        What each record carries besides its point: the penetrating edge's index, or also its
        world-space normal (paper 5.3).
    edge_offset : float, optional
        Scene strategy, ``self_interference="offset"``: how far edges move outwards, in world
        units (default: half a pixel of the view at the scene's centre).
    strict : bool
        Raise instead of warning for open, inside-out and zero-area meshes and for views that
        cut a body.
    profile : bool
        Time each GPU pass with timestamp queries where the adapter supports them.
    memory_budget : int
        Focused strategy: bytes of pixel data per round of the atlas.
    max_pixels : int
        Focused strategy: most pixels one query's tiles may hold (default 2**30). A query over it
        raises :class:`~pycinder.errors.GpuMemoryError` before anything is allocated, naming the
        pairs and a tolerance that would fit. Pixels grow with (overlap size / tolerance)**2.
    timeout : float
        Seconds a query may wait for the GPU before it raises
        :class:`~pycinder.errors.GpuTimeoutError` (default 60).
    broad_phase : {"auto", "gpu", "numpy"}
        Focused strategy: where the candidate pairs (bodies whose world boxes overlap) are
        found. ``"gpu"``: world boxes, a sort and a sweep in compute passes
        (:class:`pycinder.focused.broad.GpuBroadPhase`), one more submission and map per
        query; it may add pairs whose boxes are apart by a few millionths of their coordinates,
        which the tile planner then separates. ``"numpy"``: a vectorised sweep on the host.
        ``"auto"`` (default): the GPU from :data:`GPU_BROAD_PHASE_BODIES` bodies. The pairs
        reported are the same.
    planner : {"auto", "numpy", "gpu"}
        Focused strategy: where the tiles are planned. ``"numpy"``: on the host, in float64.
        ``"gpu"``: compute passes plan every pair's view and window and pack the atlas
        (:class:`pycinder.focused.plan.plan_gpu.GpuPlanner`), one more submission and map per query;
        a plan equals the host's up to single precision's rounding, relative to each pair's own
        extent (see :mod:`pycinder.focused.plan.plan_gpu`). ``"auto"`` (default): the GPU from
        :data:`GPU_PLANNER_PAIRS` candidate pairs (fewer on a GPU than on a CPU adapter), where
        its frame was measured as fast or faster, else the host. A query that stops at its first
        pair plans on the host. ``result.stats.planner`` says which planned.
    records : {"found", "all", "none"}, optional
        Focused strategy: ``"found"`` (default) stops testing a pair as soon as one of its tiles
        found it colliding (large windows are probed at their centre first) and returns the
        first records found (up to :data:`FOUND_RECORDS_PER_PAIR` per pair); ``"all"`` tests
        every tile and returns every sample inside the other body (what contacts are reduced
        from); ``"none"`` returns pairs only. The pairs are the same in every mode (see
        :class:`RecordMode`). The scene strategy always returns its records. Default:
        ``"all"`` with ``contacts=True``, else ``"found"``.
    contacts : bool
        Focused strategy: every query keeps what its contacts are reduced from (every record,
        ``records="all"``), so that :meth:`~pycinder.CollisionResult.contacts` answers from the
        result's own records, with no GPU. A physics step asks for pairs and contacts together:
        ``Detector(contacts=True)``, or ``contacts=True`` per call. ``contacts=True`` with
        ``records`` other than ``"all"`` is an error, as is ``contacts=True`` with the scene
        strategy (its one image has no tiles to measure contacts in).
    clearance : float, optional
        Focused strategy: report every pair whose surfaces are closer than this many world units,
        overlapping pairs included, with its distance; never a pair more than ``clearance * 9/8``
        apart (see :mod:`pycinder.focused.modes.clearance`). The tolerance of the interference test
        inside it is ``clearance / 4`` unless a finer one is given.
    min_depth : float, optional
        Focused strategy: hard clashes. Report every pair that penetrates deeper than this many
        world units (the shortest translation that separates it is longer), with its depth; never a
        pair of convex bodies at most ``min_depth / 2`` deep, touching and apart pairs included
        (see :mod:`pycinder.focused.modes.hardclash`). It is measured exactly, face pair by face
        pair, with no pixels: ``tolerance`` and ``records`` do not apply (it keeps no records). Not
        with ``clearance``.
    """

    strategy: Literal["focused", "scene"] = "focused"
    tolerance: float | None = None
    resolution: int | None = None
    self_interference: str = "prevent"
    readback: str = "compact"
    mipmap_levels: int = 2
    encode: str = "edge"
    edge_offset: float | None = None
    strict: bool = False
    profile: bool = False
    memory_budget: int = DEFAULT_MEMORY_BUDGET
    records: str | None = None
    timeout: float = DEFAULT_TIMEOUT
    max_pixels: int = DEFAULT_MAX_PIXELS
    broad_phase: str = "auto"
    planner: str = "auto"
    contacts: bool = False
    clearance: float | None = None
    min_depth: float | None = None

    def __post_init__(self) -> None:
        _one_of("strategy", self.strategy, STRATEGIES)
        _one_of("encode", self.encode, ENCODINGS)
        _one_of("broad_phase", self.broad_phase, BROAD_PHASES)
        _one_of("planner", self.planner, PLANNERS)
        object.__setattr__(self, "records",
                           _records_for_contacts(self.strategy, self.records, self.contacts))
        for name in ("strict", "profile"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if self.tolerance is not None:
            object.__setattr__(self, "tolerance",
                               _positive_real("tolerance", self.tolerance, "world units"))
        object.__setattr__(self, "timeout", _positive_real("timeout", self.timeout, "seconds"))
        if not _positive_int(self.max_pixels):
            raise ValueError(f"max_pixels must be a positive whole number, got {self.max_pixels!r}")
        if not _positive_int(self.memory_budget) or self.memory_budget < 2**20:
            raise ValueError(f"memory_budget must be a whole number of bytes, at least 1 MiB, "
                             f"got {self.memory_budget!r}")
        _check_mode(self)
        if self.strategy == "focused":
            given = [n for n in _SCENE_ONLY if getattr(self, n) != _DEFAULTS[n]]
            if given:
                raise ValueError(
                    f"{', '.join(given)} only apply to strategy='scene' (the paper's whole-scene "
                    "image); the focused strategy sizes its pixels by the tolerance. Pass "
                    "strategy='scene' to use them.")
            return
        if self.tolerance is not None:
            raise ValueError("tolerance applies to strategy='focused'; the scene strategy's "
                             "accuracy is set by its resolution")
        if self.broad_phase != "auto":
            raise ValueError("broad_phase applies to strategy='focused'; the scene strategy "
                             "draws every body in one image, with no broad phase")
        if self.planner not in ("auto", "numpy"):
            raise ValueError("planner applies to strategy='focused'; the scene strategy draws "
                             "every body in one image, with no tiles to plan")
        if self.resolution is None:
            object.__setattr__(self, "resolution", 1024)
        if not _positive_int(self.resolution):
            raise ValueError(f"resolution must be a positive whole number of pixels, got "
                             f"{self.resolution!r}")
        object.__setattr__(self, "resolution", int(self.resolution))
        _one_of("self_interference", self.self_interference, SELF_INTERFERENCE_MODES)
        _one_of("readback", self.readback, READBACK_MODES)
        if not _positive_int(self.mipmap_levels) or not 1 <= self.mipmap_levels <= 14:
            raise ValueError(f"mipmap_levels must be a whole number from 1 to 14, got "
                             f"{self.mipmap_levels!r}")
        if self.edge_offset is not None and (
                not isinstance(self.edge_offset, (int, float)) or isinstance(self.edge_offset, bool)
                or not math.isfinite(self.edge_offset)):
            raise ValueError(f"edge_offset must be a finite number, got {self.edge_offset!r}")

    def gpu_broad_phase(self, bodies: int) -> bool:
        """Whether a focused query of ``bodies`` bodies finds its candidate pairs on the GPU."""
        return self.broad_phase == "gpu" or (self.broad_phase == "auto"
                                             and bodies >= GPU_BROAD_PHASE_BODIES)

    def gpu_planner(self, pairs: int, cpu_adapter: bool) -> bool:
        """Whether a focused query of ``pairs`` candidate pairs plans its tiles on the GPU (on a
        CPU adapter where ``cpu_adapter``; see :data:`GPU_PLANNER_PAIRS`)."""
        if self.planner != "auto":
            return self.planner == "gpu"
        return pairs >= GPU_PLANNER_PAIRS["cpu" if cpu_adapter else "gpu"]

    @property
    def max_bodies(self) -> int:
        return MAX_BODIES[self.strategy]

    @property
    def record_mode(self) -> RecordMode:
        """What :attr:`records` means (see :func:`record_mode`)."""
        return record_mode(self.records)

    def replace(self, **changes: Any) -> CollisionRequest:
        """A copy with some options changed (checked again). Changing ``contacts`` alone lets
        ``records`` follow it (``"all"`` with contacts, ``"found"`` without)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        if changes.get("strategy", self.strategy) == "focused":
            for name in _SCENE_ONLY:
                values[name] = _DEFAULTS[name]
        if "contacts" in changes and "records" not in changes \
                and self.records == ("all" if self.contacts else "found"):
            values["records"] = None  # the default that follows contacts
        values.update(changes)
        return CollisionRequest(**values)

    def call_records(self, records: str | None = None, contacts: bool | None = None
                     ) -> str | None:
        """The records one query keeps, from the options of its call
        (:meth:`~pycinder.Detector.submit`, :meth:`~pycinder.Detector.find_collisions`,
        :func:`~pycinder.batch.find_collisions_batch`), checked as the request's own are.

        Parameters
        ----------
        records : {"found", "all", "none"}, optional
            This call's records; default: the request's.
        contacts : bool, optional
            True: this call keeps what its contacts need (every record). False: it needs none
            (the request's records, or ``"found"`` where the request asked for contacts).
            Default: the request's.

        Returns
        -------
        str or None
            A records mode of the focused strategy; None for the scene strategy (it keeps its
            own records).

        Raises
        ------
        ValueError
            For a value not allowed, ``contacts=True`` with ``records`` other than ``"all"`` or
            with a query mode (``clearance``, ``min_depth``), and records or contacts per call
            with the scene strategy.
        """
        if contacts is not None and not isinstance(contacts, bool):
            raise ValueError(f"contacts must be True or False, got {contacts!r}")
        if records is not None:
            record_mode(records)  # a ValueError naming the modes for any other value
        if self.strategy != "focused":
            if records is not None:
                raise ValueError("records per call applies to strategy='focused'")
            _records_for_contacts(self.strategy, None, bool(contacts))  # raises for True
            return None
        if contacts is None:
            return records or self.records
        if contacts:
            for name, figure in _MODE_FIGURES.items():
                if getattr(self, name) is not None:
                    raise ValueError(f"contacts=True is not available with {name}: a {name} "
                                     f"query's figure is {figure}")
            return _records_for_contacts(self.strategy, records, True)
        return records or ("found" if self.contacts else self.records)


def _records_for_contacts(strategy: str, records: str | None, contacts: Any) -> str:
    """The records a query keeps given ``records`` (None: the default) and ``contacts``; raises
    ValueError for a bad value or a combination that cannot give contacts."""
    if not isinstance(contacts, bool):
        raise ValueError(f"contacts must be True or False, got {contacts!r}")
    if records is not None:
        _one_of("records", records, RECORD_MODES)
    if not contacts:
        return "found" if records is None else records
    if strategy != "focused":
        raise ValueError("contacts are measured in the focused strategy's tiles; "
                         "strategy='scene' has none (its one image has no tiles per pair). "
                         "Leave strategy out for contacts.")
    if records not in (None, "all"):
        raise ValueError(f"contacts=True keeps every record of each pair (records='all'), "
                         f"but records={records!r} was given: leave records out, or pass "
                         f"records='all'")
    return "all"


def _positive_real(name: str, value: Any, unit: str) -> float:
    """``value`` as a float; a ValueError naming the option unless it is a finite positive
    number (not a bool)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive number of {unit}, got {value!r}")
    return float(value)


_MODE_FIGURES = {"clearance": "each pair's distance (result.distances)",
                 "min_depth": "each pair's depth (result.depths)"}


def _check_mode(request: CollisionRequest) -> None:
    """Check the query mode options (``clearance``, ``min_depth``): positive, one at most, on
    the focused strategy, without contacts."""
    given = [name for name in _MODE_FIGURES if getattr(request, name) is not None]
    if len(given) > 1:
        raise ValueError("min_depth and clearance ask different questions (hard clashes, or "
                         "pairs within a distance): give one of them")
    for name in given:
        object.__setattr__(request, name,
                           _positive_real(name, getattr(request, name), "world units"))
        if request.strategy != "focused":
            raise ValueError(f"{name} applies to strategy='focused': its figures are measured "
                             "per candidate pair")
        if request.contacts:
            raise ValueError(f"contacts=True and {name} are not available together: a {name} "
                             f"query's figure is {_MODE_FIGURES[name]}")


def _positive_int(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value > 0


def _one_of(name: str, value: Any, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, allowed))}; got {value!r}")


_DEFAULTS = {"resolution": None, "self_interference": "prevent", "readback": "compact",
             "mipmap_levels": 2, "edge_offset": None}

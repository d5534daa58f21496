"""What a query returns: the colliding pairs, the per-sample records, their contacts, and what it
cost."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from .records import RECORD_DTYPE, pair_keys
from .util.text import plural

from .contacts import Contacts, TileViews, reduce_contacts

if TYPE_CHECKING:
    from .scene import Scene
    from .view import View


@dataclass
class FocusedStats:
    """What the focused strategy did: its tiles and passes."""

    tolerance: tuple[float, float] = (0.0, 0.0)
    """Smallest and largest tolerance over the candidate pairs (they differ when it is relative)."""
    candidates: int = 0
    """Pairs whose world boxes overlap (the broad phase's answer)."""
    broad_phase: str = ""
    """Where the candidates were found: "numpy" or "gpu" (see the request's ``broad_phase``)."""
    planner: str = ""
    """Where the tiles were planned: "numpy" or "gpu" (see the request's ``planner``)."""
    separated: int = 0
    """Candidates dropped because their oriented boxes are apart along some axis."""
    tiles: int = 0
    pixels: int = 0
    """Pixels of all tiles."""
    atlas_pixels: int = 0
    rounds: int = 0
    triangles: int = 0
    """Clipped triangles rasterised."""
    samples: int = 0
    """Edge samples tested."""
    undecided: int = 0
    """Samples whose pixel held more crossings than its list (retried with thinner boxes)."""
    retries: int = 0
    submitted_ms: float = 0.0
    """Host milliseconds from the query's start to its frame's submission (validation
    excluded): the work the host does before the GPU can start on the frame."""
    waited_ms: float = 0.0
    """Milliseconds the host waited for the GPU before the frame's submission: the GPU broad
    phase's and the GPU planner's passes and maps. When a frame was submitted they are part of
    ``submitted_ms``, and ``submitted_ms - waited_ms`` is the host's own work before the frame
    (on a real GPU the waits are the passes' short run and a round trip each)."""
    dropped_records: int = 0
    """Records found but not kept because they outnumber what one buffer of the device holds
    (``records="all"`` at a fine tolerance); pairs are unaffected."""
    incomplete_records: int = 0
    """Reported pairs some of whose records may be missing (``records="all"``: a tile of theirs
    still undecided after retries); their contacts come from the records found."""


@dataclass
class SceneStats:
    """What the scene strategy (the paper's whole-scene image) did."""

    resolution: tuple[int, int] = (0, 0)
    readback: str = ""
    self_interference: str = ""
    views: int = 0
    self_interference_pixels: int = 0
    """Pixels blanked by the filter because a body's edge was counted inside itself."""
    unidentified_pixels: int = 0
    """Pixels with a non-zero count that no single body claimed (blanked)."""
    mip_level: int = 0


_DETAIL = {"focused": FocusedStats, "scene": SceneStats}
_DETAIL_FIELDS = {name: {f.name for f in fields(cls)} for name, cls in _DETAIL.items()}


@dataclass
class Stats:
    """What a query did and what it cost.

    The fields below are common to both strategies; ``detail`` holds the strategy's own
    (:class:`FocusedStats` or :class:`SceneStats`), and its fields read and write as attributes
    of the stats themselves (``stats.tiles``, ``stats.resolution``). Reading a field of the
    other strategy raises an AttributeError that says so. ``wall_ms`` has the wall time of each
    stage and ``gpu_ms`` the GPU time of each pass when the request asked for profiling.
    """

    strategy: str = "focused"
    adapter: str = ""
    bodies: int = 0
    records: int = 0
    bytes_read: int = 0
    uploaded_vertex_bytes: int = 0
    reruns: int = 0
    """Frames run again because a buffer had to grow."""
    possibly_lost: int = 0
    """Pairs that may have been dropped (undecided after retries, or a lossy readback): 0 means
    nothing was lost."""
    wall_ms: dict[str, float] = field(default_factory=dict)
    gpu_ms: dict[str, float] = field(default_factory=dict)
    detail: FocusedStats | SceneStats = field(init=False)

    def __post_init__(self) -> None:
        if self.strategy not in _DETAIL:
            raise ValueError(f"strategy must be one of {tuple(_DETAIL)}, got {self.strategy!r}")
        object.__setattr__(self, "detail", _DETAIL[self.strategy]())

    def __getattr__(self, name: str) -> Any:
        # Only called for names that are not fields of Stats itself.
        detail = self.__dict__.get("detail")
        if detail is not None and name in _DETAIL_FIELDS[self.strategy]:
            return getattr(detail, name)
        for other, names in _DETAIL_FIELDS.items():
            if name in names:
                raise AttributeError(f"Stats.{name} is a statistic of the {other} strategy; this "
                                     f"query ran the {self.__dict__.get('strategy')} strategy")
        raise AttributeError(f"Stats has no attribute {name!r}")

    def __setattr__(self, name: str, value: Any) -> None:
        detail = self.__dict__.get("detail")
        if detail is not None and name in _DETAIL_FIELDS[self.strategy]:
            setattr(detail, name, value)
        elif name in _OWN_FIELDS:
            object.__setattr__(self, name, value)
        else:
            self.__getattr__(name)  # raises, naming the strategy the field belongs to

    def add_ms(self, stage: str, ms: float) -> None:
        self.wall_ms[stage] = self.wall_ms.get(stage, 0.0) + ms

    def __repr__(self) -> str:
        def items(obj: Any, names: Sequence[str]) -> list[str]:
            out = []
            for n in names:
                v = getattr(obj, n)
                if isinstance(v, tuple) and all(isinstance(x, float) for x in v):
                    v = "(" + ", ".join(f"{x:.4g}" for x in v) + ")"
                elif isinstance(v, int) and not isinstance(v, bool):
                    v = f"{v:,}"
                out.append(f"{n}={v}")
            return out

        common = ("bodies", "records", "bytes_read", "uploaded_vertex_bytes", "reruns",
                  "possibly_lost")
        lines = [f"Stats({self.strategy} strategy on {self.adapter or 'no adapter'}"]
        lines += _pack(items(self, common), "  ")
        detail = [f.name for f in fields(self.detail)
                  if f.name != "waited_ms" or self.detail.waited_ms]  # a wait only when waited
        lines += _pack(items(self.detail, detail), f"  {self.strategy}: ")
        for label, ms in (("wall ms", self.wall_ms), ("gpu ms", self.gpu_ms)):
            if ms:
                lines += _pack([f"{k} {v:.3g}" for k, v in ms.items()], f"  {label}: ")
        return "\n".join(lines) + ")"


def _pack(entries: list[str], first: str, width: int = 100) -> list[str]:
    """``entries`` joined by commas into lines of at most ``width`` characters (an entry is never
    split), the first line starting with ``first`` and the others indented."""
    lines, line = [], first
    for k, entry in enumerate(entries):
        text = entry + ("," if k < len(entries) - 1 else "")
        if line.strip() and len(line) + 1 + len(text) > width:
            lines.append(line)
            line = "    "
        line += ("" if line.endswith((" ", ": ")) or line == first else " ") + text
    lines.append(line)
    return lines


_OWN_FIELDS = {f.name for f in fields(Stats)}


class CollisionResult:
    """The answer to one query: plain arrays and dataclasses, with no detector, GPU handle or
    caller's body in it.

    Attributes
    ----------
    pairs : (K, 2) int64
        Unique colliding pairs ``(i, j)`` with ``i < j``, sorted.
    records : structured array of :data:`~pycinder.RECORD_DTYPE`
        One row per sample found inside another body (see :mod:`pycinder.records`): samples,
        not contacts; :meth:`contacts` reduces them to one contact per region. A focused query
        decodes its records (world points, edges and faces) when they are first read, not
        before it returns: a caller that reads only the pairs never pays for them.
    stats : Stats
    views : list of View
        Scene strategy: the view of each ``records["view"]`` index.
    tiles : TileViews or None
        Focused strategy: the tile of each ``records["view"]`` index (NumPy arrays).
    scene : Scene or None
        The validated bodies the query ran on (their shapes are copies in single precision, not
        the caller's arrays).
    records_kept : {"found", "all", "none"} or None
        The records the focused query kept (its ``records``, ``"all"`` when it was asked for
        contacts); None for the scene strategy. :meth:`contacts` needs ``"all"``.
    distances : (K,) float64 or None
        A clearance query (``clearance=c``): each pair's distance between surfaces, 0 where the
        bodies overlap (see :mod:`pycinder.focused.modes.clearance`); None for other queries.
    distance_errors : (K,) float64 or None
        The bound on each of :attr:`distances`' error.
    depths : (K,) float64 or None
        A hard-clash query (``min_depth=d``): each pair's penetration depth, an upper bound of the
        shortest translation that separates it (see :mod:`pycinder.focused.modes.hardclash`); None
        for other queries.
    depth_errors : (K,) float64 or None
        The bound on each of :attr:`depths`' error, for convex bodies (a non-convex pair's
        depth is at most its figure plus the rounding part of this bound).
    measured_contacts : Contacts or None
        Contacts of pairs whose every record was dropped (more records than one buffer of the
        device holds): one per pair, measured whole by pass H1 (its depth, along the direction that
        separates it; see :mod:`pycinder.focused.modes.hardclash`); :meth:`contacts` includes them.

    Notes
    -----
    Contacts are asked for with the query (``contacts=True``), as a physics step asks for pairs
    and contacts together: the query then keeps every record, and :meth:`contacts` reduces them
    here, with no GPU. A result pickles as it is (to return it from a process pool, or to store
    it): its records are decoded first; its contacts, computed or not, come with it.

    Parameters
    ----------
    records : structured array, or (count, decode)
        The records, or how many there are and a function of no arguments that decodes them
        (called on first read, and its answer kept).
    """

    def __init__(self, pairs: np.ndarray,
                 records: np.ndarray | tuple[int, Callable[[], np.ndarray]], stats: Stats,
                 views: list[View] | None = None, tiles: TileViews | None = None,
                 scene: Scene | None = None, records_kept: str | None = None) -> None:
        self.pairs = pairs
        self.stats = stats
        self.views = [] if views is None else views
        self.tiles = tiles
        self.scene = scene
        self.records_kept = records_kept
        self.distances: np.ndarray | None = None
        self.distance_errors: np.ndarray | None = None
        self.depths: np.ndarray | None = None
        self.depth_errors: np.ndarray | None = None
        self.measured_contacts: Contacts | None = None
        self._contacts: Contacts | None = None
        self._decode: Callable[[], np.ndarray] | None = None
        self._records: np.ndarray | None = None
        if isinstance(records, tuple):
            self._count, self._decode = records
        else:
            self._count, self._records = len(records), records

    def __getstate__(self) -> dict[str, Any]:
        """What a pickled result holds: its attributes, with its records decoded (the decoder,
        a function, stays behind)."""
        state = self.__dict__.copy()
        state["_records"], state["_decode"] = self.records, None
        return state

    @property
    def records(self) -> np.ndarray:
        records = self._records
        if records is None:
            # Decoding is a pure function of what the query read: two threads reading at once
            # both decode, and either answer is the same.
            records = self._records = self._decode()
        return records

    @classmethod
    def empty(cls, stats: Stats) -> CollisionResult:
        return cls(np.zeros((0, 2), dtype=np.int64), np.zeros(0, RECORD_DTYPE), stats)

    @property
    def is_collision(self) -> bool:
        return len(self.pairs) > 0

    def __bool__(self) -> bool:
        return self.is_collision

    def __len__(self) -> int:
        return len(self.pairs)

    @property
    def names(self) -> list[str | None] | None:
        """The body names the query was given (None where it was given none)."""
        if self.scene is not None and any(n is not None for n in self.scene.names):
            return list(self.scene.names)
        return None

    def __repr__(self) -> str:
        shown = [self._pair_label(i, j) for i, j in self.pairs[:4].tolist()]
        if len(self.pairs) > 4:
            shown.append(f"... {len(self.pairs) - 4} more")
        st = self.stats
        if st.strategy == "focused":
            lo, hi = st.tolerance
            setting = f"tolerance {lo:.4g}" if lo == hi else f"tolerance {lo:.4g} to {hi:.4g}"
            if self.depths is not None:
                setting = "depths measured face pair by face pair"
            if not st.candidates:
                setting = "no candidate pairs"
        else:
            setting = f"resolution {st.resolution[0]}"
        pairs = plural(len(self.pairs), "pair")
        return (f"CollisionResult({pairs}" + (f": {', '.join(shown)}" if shown else "") +
                f"; {plural(self._count, 'record')}; {st.strategy} strategy, {setting}; "
                f"{plural(st.bodies, 'body')}; on {st.adapter or 'no adapter'})")

    def _pair_label(self, i: int, j: int) -> str:
        names = self.names
        if names is None:
            return f"({i}, {j})"
        return f"({names[i] if names[i] is not None else i}, " \
               f"{names[j] if names[j] is not None else j})"

    def points(self) -> np.ndarray:
        """World-space points of the records, (len(records), 3) float64."""
        return self.records["point"].copy()

    def edge_vertices(self) -> np.ndarray:
        """Each record's penetrating edge as (len(records), 2) int64 vertex indices into the
        penetrating body's own vertex array; -1 for records that are not edge samples."""
        if self.scene is None:
            raise ValueError("this result has no scene to look edges up in")
        rec = self.records
        out = np.full((len(rec), 2), -1, dtype=np.int64)
        edge = rec["edge"] >= 0
        shape = self.scene.body_shape[rec["penetrating"]]
        for k in np.unique(shape[edge]):
            sel = edge & (shape == k)
            out[sel] = self.scene.shapes[k].topology.edges[rec["edge"][sel]]
        return out

    def across(self, groups: np.ndarray) -> CollisionResult:
        """This result restricted to pairs of bodies in different groups ((N,) int)."""
        keep = groups[self.pairs[:, 0]] != groups[self.pairs[:, 1]]
        rec = self.records
        rec = rec[groups[rec["penetrating"]] != groups[rec["penetrated"]]]
        self.stats.records = len(rec)
        return CollisionResult(self.pairs[keep], rec, self.stats, self.views, self.tiles,
                               self.scene, self.records_kept)

    def contacts(self) -> Contacts:
        """One contact per contact region of every colliding pair, with its point, normal and
        penetration depth (see :mod:`pycinder.contacts`), reduced from this result's records:
        no GPU runs.

        Contacts are reduced from every record of a pair: ask for them with the query
        (``contacts=True``, or ``records="all"``). The answer is computed on first call, kept,
        and pickled with the result.

        Returns
        -------
        Contacts
            Arrays of C contacts (``pair`` (C, 2), ``point`` (C, 3), ``normal`` (C, 3),
            ``depth`` (C,), ...); iterating gives one :class:`~pycinder.ContactData` per
            contact, named by the query's names (body indices where it had none).

        Raises
        ------
        ValueError
            For a result that kept fewer than every record (``records="found"``, the default,
            or ``"none"``): the message says to query with ``contacts=True``; for a result of
            the scene strategy, whose image has no tiles to measure contacts in; for a
            clearance query's result (its figures are :attr:`distances`) or a hard-clash
            query's (its figures are :attr:`depths`).

        Examples
        --------
        >>> import trimesh, pycinder
        >>> box = trimesh.creation.box((1, 1, 1))
        >>> ball = trimesh.creation.icosphere(radius=0.4).apply_translation((0.6, 0, 0))
        >>> result = pycinder.find_collisions([box, ball], tolerance=0.005, contacts=True)
        >>> [(c.pair, round(c.depth, 1)) for c in result.contacts()]
        [((0, 1), 0.3)]
        """
        if self._contacts is not None:
            return self._contacts
        if self.stats.strategy != "focused":
            raise ValueError("contacts are measured in the focused strategy's tiles; this result "
                             "comes from strategy='scene'. Run the query with the default "
                             "strategy and contacts=True for contacts.")
        for figures, mode, what in ((self.distances, "clearance", "distance"),
                                    (self.depths, "min_depth", "depth")):
            if figures is not None:
                raise ValueError(f"a {mode} query's figure is each pair's {what} "
                                 f"(result.{what}s); it has no contacts (contacts=True and "
                                 f"{mode} are not available together)")
        if self.records_kept != "all":
            kept = f"records={self.records_kept!r}" if self.records_kept else \
                "no word of which records it kept"
            raise ValueError(
                f"this result has no contacts: its query kept {kept}, and contacts are reduced "
                f"from every record of each pair. Ask for them with the query: "
                f"find_collisions(..., contacts=True) (on a Detector too, or "
                f"Detector(contacts=True) for every query; find_collisions_batch(..., "
                f"contacts=True) for a batch)")
        contacts = reduce_contacts(self.records, self.scene, self.tiles)
        if self.measured_contacts is not None:
            contacts = contacts.joined(self.measured_contacts)
        contacts = contacts.restricted_to(self.pairs)
        contacts.names = self.names
        self._contacts = contacts
        return contacts

    def pair_samples(self) -> np.ndarray:
        """How many of the records each colliding pair has: the interfering samples read back
        for it.

        Returns
        -------
        (K,) int64
            One count per row of :attr:`pairs`, 0 for a pair with no record (a query that kept
            none, or a pair found by a measuring query's own pass).
        """
        rec = self.records
        keys, counts = np.unique(pair_keys(rec["penetrating"], rec["penetrated"]),
                                 return_counts=True)
        if not len(keys):
            return np.zeros(len(self.pairs), dtype=np.int64)
        wanted = pair_keys(self.pairs[:, 0], self.pairs[:, 1])
        at = np.searchsorted(keys, wanted).clip(max=len(keys) - 1)
        return np.where(keys[at] == wanted, counts[at], 0).astype(np.int64)

    def report(self, names: Sequence[str] | None = None, *, mode: str = "default",
               tolerance_range: Sequence[float] | None = None,
               warnings: Sequence[dict[str, Any]] = ()) -> dict[str, Any]:
        """This result as the object ``pycinder check --json`` prints (``json.dumps`` of it).

        Parameters
        ----------
        names : sequence of str, optional
            One name per body (default: the names the query was given, or the bodies'
            indices as text where it was given none).
        mode : {"default", "min_depth", "clearance"}
            The query's mode; any other than ``"default"`` is the report's ``mode``.
        tolerance_range : (2,) sequence of float, optional
            Focused strategy: the report's ``tolerance``, [smallest, largest] in world units
            (see :func:`pycinder.files.tolerance_range`); None makes it null (a hard-clash
            query measures with no pixels). Ignored for the scene strategy.
        warnings : sequence of dict
            The report's ``warnings``, one ``{"category": ..., "message": ...}`` each.

        Returns
        -------
        dict
            In this order: ``collision`` (bool); ``pairs``, one ``{"a": NAME, "b": NAME,
            "samples": N}`` per row of :attr:`pairs` (:meth:`pair_samples`), with ``depth`` and
            ``depth_error`` (:attr:`depths`) or ``distance`` and ``distance_error``
            (:attr:`distances`) where the query measured them; ``bodies`` (the names);
            ``strategy``; ``tolerance`` and ``candidates`` (focused) or ``resolution`` (scene:
            the image's width in pixels); ``mode`` (unless ``"default"``); ``adapter``;
            ``warnings``; ``errors`` (``[]``: the query ran).
        """
        if names is None:
            given = self.names or [None] * self.stats.bodies
            names = [str(i) if n is None else str(n) for i, n in enumerate(given)]
        names = list(names)
        st = self.stats
        samples = self.pair_samples().tolist()
        report: dict[str, Any] = {
            "collision": bool(len(self.pairs)),
            "pairs": [{"a": names[i], "b": names[j], "samples": n}
                      for (i, j), n in zip(self.pairs.tolist(), samples)],
            "bodies": names,
            "strategy": st.strategy,
        }
        for figures, bounds, name in ((self.depths, self.depth_errors, "depth"),
                                      (self.distances, self.distance_errors, "distance")):
            if figures is not None:
                for pair, d, e in zip(report["pairs"], figures.tolist(), bounds.tolist()):
                    pair[name], pair[f"{name}_error"] = d, e
        if st.strategy == "focused":
            report["tolerance"] = (None if tolerance_range is None
                                   else [float(t) for t in tolerance_range])
            report["candidates"] = st.candidates
        else:
            report["resolution"] = st.resolution[0]
        if mode != "default":
            report["mode"] = mode
        report.update(adapter=st.adapter, warnings=list(warnings), errors=[])
        return report

    def pair_names(self, names: Sequence[Any] | None = None) -> set[tuple[Any, Any]]:
        """The pairs as a set of sorted name tuples, as trimesh's ``return_names`` gives them.

        Parameters
        ----------
        names : sequence, optional
            One name per body; default: the names the query was given (``names=``). A body
            without a name is named by its index.
        """
        if names is None:
            names = self.names
        if names is None:
            names = range(int(self.pairs.max(initial=-1)) + 1)
        label = [n if n is not None else i for i, n in enumerate(names)]
        return {_sorted_pair(label[i], label[j]) for i, j in self.pairs.tolist()}


def _sorted_pair(a: Any, b: Any) -> tuple[Any, Any]:
    """``(a, b)`` sorted as trimesh sorts names, by their text where they do not compare."""
    try:
        return (a, b) if not b < a else (b, a)
    except TypeError:
        return (a, b) if str(a) <= str(b) else (b, a)

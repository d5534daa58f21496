"""What a query returns: the colliding pairs, the per-sample records, and what it cost."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .records import RECORD_DTYPE

if TYPE_CHECKING:
    from .scene import Scene
    from .tiles import TilePlan
    from .view import View


@dataclass
class Stats:
    """What a query did and what it cost.

    Counts are for the whole query; ``wall_ms`` has the wall time of each stage and ``gpu_ms`` the
    GPU time of each pass when the request asked for profiling.
    """

    strategy: str = "focused"
    adapter: str = ""
    bodies: int = 0
    # focused strategy
    tolerance: tuple[float, float] = (0.0, 0.0)
    """Smallest and largest tolerance over the candidate pairs (they differ when it is relative)."""
    candidates: int = 0
    """Pairs whose world boxes overlap (the broad phase's answer)."""
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
    possibly_lost: int = 0
    """Pairs that may have been dropped (undecided after retries, or a lossy readback): 0 means
    nothing was lost."""
    dropped_records: int = 0
    """Records found but not kept because they outnumber what one buffer of the device holds
    (``records="all"`` at a fine tolerance); pairs are unaffected."""
    incomplete_records: int = 0
    """Reported pairs some of whose records may be missing (``records="all"``: a tile of theirs
    still undecided after retries); their contacts come from the records found."""
    # scene strategy
    resolution: tuple[int, int] = (0, 0)
    readback: str = ""
    self_interference: str = ""
    views: int = 0
    self_interference_pixels: int = 0
    """Pixels blanked by the filter because a body's edge was counted inside itself."""
    unidentified_pixels: int = 0
    """Pixels with a non-zero count that no single body claimed (blanked)."""
    mip_level: int = 0
    # both
    records: int = 0
    bytes_read: int = 0
    uploaded_vertex_bytes: int = 0
    reruns: int = 0
    """Frames run again because a buffer had to grow."""
    submitted_ms: float = 0.0
    """Focused strategy: host milliseconds from the query's start to its first submission
    (validation excluded): the work the host does before the GPU can start."""
    wall_ms: dict[str, float] = field(default_factory=dict)
    gpu_ms: dict[str, float] = field(default_factory=dict)

    def add_ms(self, stage: str, ms: float) -> None:
        self.wall_ms[stage] = self.wall_ms.get(stage, 0.0) + ms


@dataclass
class CollisionResult:
    """The answer to one query.

    Attributes
    ----------
    pairs : (K, 2) int64
        Unique colliding pairs ``(i, j)`` with ``i < j``, sorted.
    records : structured array of :data:`~pycinder.RECORD_DTYPE`
        One row per edge sample found inside another body.
    stats : Stats
    views : list of View
        Scene strategy: the view of each ``records["view"]`` index.
    tiles : TilePlan or None
        Focused strategy: the tile of each ``records["view"]`` index.
    """

    pairs: np.ndarray
    records: np.ndarray
    stats: Stats
    views: list[View] = field(default_factory=list)
    tiles: TilePlan | None = field(default=None, repr=False)
    scene: Scene | None = field(default=None, repr=False)

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
                               self.scene)

    def pair_names(self, names: Sequence[Any]) -> set[tuple[Any, Any]]:
        """The pairs as a set of sorted name tuples, as trimesh's ``return_names`` gives them."""
        return {tuple(sorted((names[i], names[j]))) for i, j in self.pairs.tolist()}

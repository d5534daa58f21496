"""Contacts: the records of each colliding pair reduced to one contact per contact region.

A record is a point of one body's surface (or near one of its edges) found inside the other body.
For a pair ``(a, b)``:

* **regions**: the pair's records joined when they lie in neighbouring cells of a grid four
  tolerances wide (connected components); a fragment of a few records that lies within a larger
  region's box (where a surface seen at a grazing angle is sampled thinly) joins that region;
* **normal**: per region, the outward normals of ``a``'s surface inside ``b`` minus those of
  ``b``'s surface inside ``a``, summed over the area each surface record stands for (a pixel
  over the cosine of the face's angle to the tile's view) and normalised: it points from ``a``
  into ``b``, as
  python-fcl's contact normal points from its first object to its second. Where the sum
  cancels out (one body wholly inside the other), the direction from ``a``'s centre to ``b``'s;
* **depth**: how far the region's points reach along the normal: ``a``'s deepest point into
  ``b`` minus ``b``'s deepest point into ``a`` (the width of the overlap along the normal, as
  sampled: within about a tolerance);
* **point**: the record nearest the region's centre: a point of one surface inside the other
  body, so on the intersection of the two;
* **faces**: the face of each body at its deepest surface record (-1 when a body has no surface
  record in the region).

Everything is vectorised over all records of a query.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from .records import pair_keys
from .scene.bodies import world_edge_normals, world_face_normals
from .util.text import plural

if TYPE_CHECKING:
    from .scene import Scene

CELL_TOLERANCES = 4.0
"""Grid cell of the region search, in tolerances: records closer than this join a region."""
FRAGMENT_SAMPLES = 8
"""A region of at most this many records inside a larger region's box joins it (see
:func:`_absorb_fragments`)."""


class ContactData:
    """One contact region of a colliding pair, shaped like trimesh's ``ContactData``.

    Attributes
    ----------
    names : set
        The two object names.
    pair : (name, name)
        The names in order: ``normal`` points from the first object into the second.
    point : (3,) float
        A point on the intersection of the two objects.
    normal : (3,) float
        Unit contact normal.
    depth : float
        Penetration depth along the normal.
    """

    def __init__(self, pair: tuple[Any, Any], point: np.ndarray, normal: np.ndarray,
                 depth: float, faces: tuple[int, int]) -> None:
        self.pair = pair
        self.names = set(pair)
        self._inds = {pair[0]: int(faces[0]), pair[1]: int(faces[1])}
        self.point = point
        self.normal = normal
        self.depth = float(depth)

    def index(self, name: Any) -> int:
        """The face of object ``name`` at the contact (-1 where unknown)."""
        return self._inds[name]

    def __repr__(self) -> str:
        return (f"ContactData(pair={self.pair}, point={np.round(self.point, 6).tolist()}, "
                f"normal={np.round(self.normal, 6).tolist()}, depth={self.depth:.6g})")


@dataclass
class Contacts:
    """Contacts of a query, one row per contact region.

    Iterating (or indexing) gives one :class:`ContactData` per contact, with the bodies named by
    ``names`` (by their indices where there are none).

    Attributes
    ----------
    pair : (C, 2) int64
        The two bodies ``(a, b)``, ``a < b``.
    point : (C, 3) float64
        A point of the intersection (of a contact measured whole, ``samples`` 0: the middle of
        the two bodies' box overlap).
    normal : (C, 3) float64
        Unit normal pointing from ``a`` into ``b``.
    depth : (C,) float64
        Penetration depth along the normal (of a contact measured whole: the pair's directional
        depth, an upper bound; see :mod:`pycinder.focused.modes.hardclash`).
    face : (C, 2) int64
        Face of ``a`` and of ``b`` at the contact (-1 where not known).
    deepest : (C, 2, 3) float64
        The record of ``a`` reaching furthest into ``b``, and of ``b`` into ``a`` (NaN where a
        body has no record in the region).
    samples : (C,) int64
        Records in the region.
    names : list or None
        The query's body names.
    """

    pair: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    depth: np.ndarray
    face: np.ndarray
    deepest: np.ndarray
    samples: np.ndarray
    names: list[Any] | None = None

    def __len__(self) -> int:
        return len(self.pair)

    def _name(self, i: int) -> Any:
        if self.names is None or self.names[i] is None:
            return i
        return self.names[i]

    def __getitem__(self, k: int) -> ContactData:
        a, b = self.pair[k].tolist()
        return ContactData((self._name(a), self._name(b)), self.point[k], self.normal[k],
                           float(self.depth[k]), tuple(self.face[k].tolist()))

    def __iter__(self) -> Iterator[ContactData]:
        return (self[k] for k in range(len(self)))

    def __repr__(self) -> str:
        pairs = len(np.unique(pair_keys(self.pair[:, 0], self.pair[:, 1]))) if len(self) else 0
        deepest = f", deepest {self.depth.max():.4g}" if len(self) else ""
        return f"Contacts({plural(len(self), 'contact')} over {plural(pairs, 'pair')}{deepest})"

    @classmethod
    def empty(cls) -> Contacts:
        return cls(np.zeros((0, 2), np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0),
                   np.zeros((0, 2), np.int64), np.zeros((0, 2, 3)), np.zeros(0, np.int64))

    @classmethod
    def measured(cls, pair: np.ndarray, point: np.ndarray, normal: np.ndarray,
                 depth: np.ndarray) -> Contacts:
        """One contact per pair measured whole rather than reduced from records (no faces, no
        deepest records, no samples).

        Parameters
        ----------
        pair : (C, 2) int
        point, normal : (C, 3) float
        depth : (C,) float
        """
        c = len(pair)
        return cls(np.asarray(pair, np.int64).reshape(c, 2), np.asarray(point, np.float64),
                   np.asarray(normal, np.float64), np.asarray(depth, np.float64),
                   np.full((c, 2), -1, np.int64), np.full((c, 2, 3), np.nan),
                   np.zeros(c, np.int64))

    def select(self, keep: np.ndarray) -> Contacts:
        """The contacts ``keep`` (a (C,) mask or indices)."""
        return Contacts(self.pair[keep], self.point[keep], self.normal[keep], self.depth[keep],
                        self.face[keep], self.deepest[keep], self.samples[keep], self.names)

    def joined(self, other: Contacts) -> Contacts:
        """These contacts and ``other``'s, ordered by pair (stably: each part's own order kept
        within a pair)."""
        if not len(other):
            return self
        fields = ("pair", "point", "normal", "depth", "face", "deepest", "samples")
        both = Contacts(*(np.concatenate([getattr(self, f), getattr(other, f)]) for f in fields),
                        names=self.names)
        return both.select(np.argsort(pair_keys(both.pair[:, 0], both.pair[:, 1]),
                                      kind="stable"))

    def restricted_to(self, pairs: np.ndarray) -> Contacts:
        """The contacts of ``pairs`` ((K, 2) int, ``i < j``) only."""
        if not len(self):
            return self
        keep = np.isin(pair_keys(self.pair[:, 0], self.pair[:, 1]),
                       pair_keys(pairs[:, 0], pairs[:, 1]))
        if keep.all():
            return self
        return self.select(keep)


def _components(key: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Connected components of occupied grid cells.

    Parameters
    ----------
    key : (M,) int64
        Sorted unique packed cell keys.
    cells : (M, 4) int64
        The cells (group, x, y, z) the keys pack, with x, y, z >= 1.

    Returns
    -------
    (M,) int64
        A component label per cell.
    """
    m = len(key)
    label = np.arange(m)
    pack = _packer(cells)
    offsets = np.array([(dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)
                        if (dx, dy, dz) > (0, 0, 0)])
    links = []
    for o in offsets:
        n = pack(np.c_[cells[:, :1], cells[:, 1:] + o])
        j = np.searchsorted(key, n)
        j = np.minimum(j, m - 1)
        found = key[j] == n
        links.append(np.stack([np.flatnonzero(found), j[found]], axis=1))
    edges = np.concatenate(links) if links else np.zeros((0, 2), np.int64)
    while len(edges):
        low = np.minimum(label[edges[:, 0]], label[edges[:, 1]])
        before = label.copy()
        np.minimum.at(label, edges[:, 0], low)
        np.minimum.at(label, edges[:, 1], low)
        label = label[label]  # pointer jumping
        if np.array_equal(label, before):
            break
    return label


def _packer(cells: np.ndarray):
    """A function packing (group, x, y, z) rows into int64 keys; x, y, z in [0, 2**14)."""
    def pack(c: np.ndarray) -> np.ndarray:
        return ((c[:, 0] * 2**14 + c[:, 1]) * 2**14 + c[:, 2]) * 2**14 + c[:, 3]
    return pack


def _absorb_fragments(region: np.ndarray, point: np.ndarray, pair: np.ndarray,
                      cell: np.ndarray) -> np.ndarray:
    """Regions renumbered after joining fragments to the region they belong to.

    Where a surface is seen at a grazing angle its samples thin out, and a few of them can lie
    more than a grid cell from the rest. A region of at most :data:`FRAGMENT_SAMPLES` records
    whose centre lies in the box of a larger region of the same pair (grown by a grid cell)
    joins the largest such region; regions of more records are never joined.

    Parameters
    ----------
    region : (n,) int64
        Region of each record, numbered from 0.
    point : (n, 3) float64
    pair : (n,) int64
        Pair of each record.
    cell : (n,) float64
        Grid cell size at each record.

    Returns
    -------
    (n,) int64
        Region of each record, numbered from 0.
    """
    n = int(region.max()) + 1
    count = np.bincount(region, minlength=n)
    small = np.flatnonzero(count <= FRAGMENT_SAMPLES)
    big = np.flatnonzero(count > FRAGMENT_SAMPLES)
    if not len(small) or not len(big):
        return region
    pair_of = np.zeros(n, np.int64)
    pair_of[region] = pair
    pad = np.zeros(n)
    np.maximum.at(pad, region, cell)
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    np.minimum.at(lo, region, point)
    np.maximum.at(hi, region, point)
    centre = 0.5 * (lo[small] + hi[small])
    inside = (pair_of[small][:, None] == pair_of[big][None, :]) & \
        (centre[:, None, :] >= lo[big][None] - pad[big][None, :, None]).all(axis=2) & \
        (centre[:, None, :] <= hi[big][None] + pad[big][None, :, None]).all(axis=2)
    score = np.where(inside, count[big][None, :], -1)
    best = np.argmax(score, axis=1)
    joins = score[np.arange(len(small)), best] >= 0
    target = np.arange(n)
    target[small[joins]] = big[best[joins]]
    return np.unique(target[region], return_inverse=True)[1]


def _width(region: np.ndarray, n: int, along: np.ndarray, from_a: np.ndarray) -> np.ndarray:
    """Per region, the overlap's width along a direction: how far ``a``'s records reach along
    it minus how far back ``b``'s reach; for a region with records of one body only (one body
    inside the other), the extent of those records."""
    hi_a = np.full(n, -np.inf)
    lo_a = np.full(n, np.inf)
    hi_b = np.full(n, -np.inf)
    lo_b = np.full(n, np.inf)
    np.maximum.at(hi_a, region[from_a], along[from_a])
    np.minimum.at(lo_a, region[from_a], along[from_a])
    np.maximum.at(hi_b, region[~from_a], along[~from_a])
    np.minimum.at(lo_b, region[~from_a], along[~from_a])
    only_a, only_b = ~np.isfinite(lo_b), ~np.isfinite(hi_a)
    return np.where(only_a, hi_a - lo_a, np.where(only_b, hi_b - lo_b, hi_a - lo_b))


class TileViews(Protocol):
    """What contacts read of a focused query's tiles (a
    :class:`~pycinder.focused.plan.plan_numpy.TilePlan`): each tile's pixel size and view axes."""

    pixel: np.ndarray
    """(T,) float: world size of a pixel."""
    axes: np.ndarray
    """(T, 3, 3) float: the tile's screen axes u, v and its view direction, as rows."""

    def __len__(self) -> int: ...


def reduce_contacts(records: np.ndarray, scene: Scene | None,
                    tiles: TileViews | None) -> Contacts:
    """One contact per contact region of every colliding pair, from a focused query's records
    as they are, with no GPU.

    The records should come from a focused query asked for contacts (``contacts=True``, which
    keeps every record: :meth:`CollisionResult.contacts <pycinder.CollisionResult.contacts>`
    checks this and calls this function); with fewer records the contacts are those of the
    records found.

    Parameters
    ----------
    records : (R,) RECORD_DTYPE
        The query's records (``result.records``).
    scene : Scene or None
        The query's scene (``result.scene``): the bodies' poses, for the normals.
    tiles : TileViews or None
        The query's tiles (``result.tiles``).

    Returns
    -------
    Contacts
        C contacts over every pair that has records.
    """
    rec = records
    if len(rec) == 0 or scene is None or tiles is None:
        return Contacts.empty()
    a = np.minimum(rec["penetrating"], rec["penetrated"]).astype(np.int64)
    b = np.maximum(rec["penetrating"], rec["penetrated"]).astype(np.int64)
    from_a = rec["penetrating"] == a
    tol = tiles.pixel[rec["view"]] if len(tiles) else np.ones(len(rec))
    point = rec["point"].astype(np.float64)
    # Outward normal of the penetrating body at each record, in world space.
    normal = np.zeros((len(rec), 3))
    surface = rec["face"] >= 0
    normal[surface] = world_face_normals(scene, rec["penetrating"][surface], rec["face"][surface])
    edge = ~surface
    normal[edge] = world_edge_normals(scene, rec["penetrating"][edge], rec["edge"][edge])
    signed = np.where(from_a[:, None], normal, -normal)
    # A surface record stands for one pixel of the tile's screen: its area on the surface is a
    # pixel over the cosine of the face's angle to the view. Edge records carry no area.
    view = tiles.axes[rec["view"], 2]
    cosine = np.abs(np.einsum("ij,ij->i", normal, view))
    weight = np.where(surface, 1.0 / np.maximum(cosine, 0.05), 0.0)
    if not surface.any():
        weight[:] = 1.0
    # Regions: connected cells of a grid a few tolerances wide, per pair.
    pair_key, group = np.unique(pair_keys(a, b), return_inverse=True)
    cell_size = CELL_TOLERANCES * tol
    cell = np.floor(point / cell_size[:, None]).astype(np.int64)
    first = np.full((len(pair_key), 3), np.iinfo(np.int64).max)
    np.minimum.at(first, group, cell)
    cell = cell - first[group] + 1
    if cell.max() >= 2**14 - 1:  # a region too large for the packing: coarsen the grid
        scale = int(np.ceil(cell.max() / (2**14 - 2)))
        cell = (cell - 1) // scale + 1
    cells = np.c_[group, cell]
    pack = _packer(cells)
    keys = pack(cells)
    ukey, cell_of = np.unique(keys, return_inverse=True)
    ucells = cells[np.unique(cell_of, return_index=True)[1]]
    region_of_cell = _components(ukey, ucells)
    region = np.unique(region_of_cell[cell_of], return_inverse=True)[1]
    region = _absorb_fragments(region, point, group, cell_size)
    n = int(region.max()) + 1
    count = np.bincount(region, minlength=n)
    area = np.bincount(region, weight, n)
    summed = np.stack([np.bincount(region, signed[:, k] * weight, n) for k in range(3)], axis=1)
    length = np.linalg.norm(summed, axis=1)
    region_pair = np.stack([pair_key >> 32, pair_key & 0xFFFFFFFF], axis=1)[
        group[np.unique(region, return_index=True)[1]]]
    first_record = np.unique(region, return_index=True)[1]
    centroid = np.stack([np.bincount(region, point[:, k], n) for k in range(3)], axis=1) \
        / count[:, None]
    # Candidate normals; the one along which the sampled overlap is thinnest wins, as the
    # penetration depth is the overlap's smallest width over all directions.
    centre = np.einsum("nij,nj->ni", scene.transforms[:, :3, :3],
                       0.5 * (scene.local_lo + scene.local_hi)) + scene.transforms[:, :3, 3]
    apart = centre[region_pair[:, 1]] - centre[region_pair[:, 0]]
    d = point - centroid[region]
    cov = np.zeros((n, 3, 3))
    np.add.at(cov, region, d[:, :, None] * d[:, None, :])
    spread = np.linalg.eigh(cov)[1][:, :, 0]            # least-spread direction of the records
    candidates = np.stack([
        summed / np.maximum(length, 1e-300)[:, None],     # area-weighted surface normals
        spread,
        tiles.axes[rec["view"][first_record], 1],          # the tile's thin axis
        apart,                                            # from a's centre to b's
    ], axis=1)
    norms = np.linalg.norm(candidates, axis=2)
    candidates /= np.maximum(norms, 1e-300)[..., None]
    # Point each from a into b: by the surface normals where they clearly say which way (in a
    # concave contact the centres can say the opposite), else by the centres.
    by_normals = np.einsum("nkj,nj->nk", candidates, summed / np.maximum(area, 1e-300)[:, None])
    by_centres = np.einsum("nkj,nj->nk", candidates, apart)
    sign = np.where(np.abs(by_normals) > 0.3, by_normals, by_centres)
    candidates[sign < 0] *= -1
    valid = norms > 1e-12
    valid[:, 0] &= length >= 0.2 * area
    widths = np.stack([_width(region, n, np.einsum("ij,ij->i", point, candidates[region, k]), from_a)
                       for k in range(4)], axis=1)
    widths[~valid] = np.inf
    best = np.argmin(widths, axis=1)
    unit = candidates[np.arange(n), best]
    depth = np.maximum(widths[np.arange(n), best], 0.0)
    along = np.einsum("ij,ij->i", point, unit[region])
    # Point: the record nearest the region's centroid.
    dist = np.linalg.norm(point - centroid[region], axis=1)
    order = np.lexsort((dist, region))
    nearest = order[np.unique(region[order], return_index=True)[1]]
    # Faces and points: each body's deepest record in the region (faces from surface records).
    face = np.full((n, 2), -1, np.int64)
    deepest = np.full((n, 2, 3), np.nan)
    for side, mine, sign in ((0, from_a, -1.0), (1, ~from_a, 1.0)):
        for sel in (mine, mine & surface):
            idx = np.flatnonzero(sel)
            if not len(idx):
                continue
            o = idx[np.lexsort((sign * along[idx], region[idx]))]
            best = o[np.unique(region[o], return_index=True)[1]]
            if sel is mine:
                deepest[region[best], side] = point[best]
            else:
                face[region[best], side] = rec["face"][best]
    return Contacts(region_pair, point[nearest], unit, depth, face, deepest, count)

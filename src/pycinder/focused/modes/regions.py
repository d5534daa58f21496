"""Regions where a pair's bodies meet, measured at the region's own scale.

A figure measured in single precision is rounded in proportion to how far the vertices it is
computed from lie from the frame's origin. Measured over two whole bodies, that is the bodies'
extent (an 84 m slab) and, for models in map coordinates, their distance from the origin. Here a
pair is measured instead in regions: boxes of at most :func:`tile_side` per side covering the box
where the pair's world boxes meet (grown by a margin), each with its own frame at its centre, and
each body's faces cut to the region in float64 on the host before they are rounded to single
precision. Rounding then scales with the region, whatever the bodies' length or their distance
from the origin.

What a body is within a region:

* an open body (no inside): its faces cut to the region (:func:`clip_triangles`);
* a closed body: the solid within the region, faces cut to it and closed by the region's own
  walls where the body's inside reaches them (:func:`solid_within`, manifold3d's exact boolean
  intersection with the box), so that a ray through the region meets the solid's extremes there.

A translation that separates two bodies separates their parts within any region, so a region's
figure never exceeds what the whole pair would give (see :mod:`~pycinder.focused.modes.hardclash`
for what that means for the depth contract).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import wgpu

from ...gpu.buffers import GrowableBuffer
from ...gpu.layout import CLUSTER_FACES
from ...util.optional import require
from .pairwork import FRAME, ITEM

if TYPE_CHECKING:
    from ...scene import Scene

MAX_REGIONS = 20_000
"""Most regions one pair is measured in: a pair that would need more is refused, naming the
coarser figure that would do."""

ROUNDING = 2.0**-16
"""Bound of a figure's rounding per unit of the reach of its frame's vertices (single
precision: a few units of 2^-24 per operation, with the conditioning of the shaders' tests)."""


def tile_side(value: float, grow: float, fraction: float = 1 / 32) -> float:
    """The largest side of a region whose figures are rounded by at most ``fraction`` of
    ``value``, with regions grown by ``grow`` on every side.

    A region of side ``s`` grown by ``g`` reaches ``sqrt(3) / 2 * (s + 2 g)`` from its centre, so
    its rounding bound is :data:`ROUNDING` times that.
    """
    return max(fraction * value / (ROUNDING * 0.5 * np.sqrt(3.0)) - 2.0 * grow, grow)


def tiles(lo: np.ndarray, hi: np.ndarray, side: float) -> tuple[np.ndarray, np.ndarray,
                                                                  np.ndarray]:
    """Cover each box with a grid of boxes of equal size, at most ``side`` per side.

    Parameters
    ----------
    lo, hi : (K, 3) float64
        The boxes (``hi >= lo``).
    side : float

    Returns
    -------
    owner : (T,) int64
        The box each tile covers part of.
    tile_lo, tile_hi : (T, 3) float64
    """
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    size = hi - lo
    n = np.maximum(np.ceil(size / side), 1).astype(np.int64)  # (K, 3) tiles per axis
    total = n.prod(axis=1)
    owner = np.repeat(np.arange(len(lo)), total)
    within = np.arange(len(owner)) - np.repeat(np.cumsum(total) - total, total)
    nk = n[owner]
    ix = within % nk[:, 0]
    iy = (within // nk[:, 0]) % nk[:, 1]
    iz = within // (nk[:, 0] * nk[:, 1])
    index = np.stack([ix, iy, iz], axis=1)
    step = size[owner] / nk
    tile_lo = lo[owner] + index * step
    tile_hi = np.where(index + 1 == nk, hi[owner], lo[owner] + (index + 1) * step)
    return owner, tile_lo, tile_hi


def clip_triangles(tris: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Triangles cut to a box (Sutherland-Hodgman against its six planes, in float64), each
    part fanned into triangles.

    Parameters
    ----------
    tris : (T, 3, 3) float64
    lo, hi : (3,) float64

    Returns
    -------
    (M, 3, 3) float64
        The parts within the box (a triangle within it is kept as it is).
    """
    tris = np.asarray(tris, np.float64)
    if len(tris) == 0:
        return tris.reshape(0, 3, 3)
    t_lo, t_hi = tris.min(axis=1), tris.max(axis=1)
    near = np.all((t_hi >= lo) & (t_lo <= hi), axis=1)
    tris = tris[near]
    inside = np.all((tris.min(axis=1) >= lo) & (tris.max(axis=1) <= hi), axis=1)
    keep, cut = tris[inside], tris[~inside]
    if len(cut) == 0:
        return keep
    most = 9  # a triangle cut by six planes has at most nine corners
    poly = np.zeros((len(cut), most, 3))
    poly[:, :3] = cut
    count = np.full(len(cut), 3)
    for axis in range(3):
        for bound, sign in ((lo[axis], 1.0), (hi[axis], -1.0)):
            dist = sign * (poly[:, :, axis] - bound)  # >= 0 inside
            new = np.zeros_like(poly)
            new_count = np.zeros_like(count)
            k = np.arange(most)
            valid = k[None, :] < count[:, None]
            nxt = (k[None, :] + 1) % np.maximum(count[:, None], 1)
            p, q = poly, np.take_along_axis(poly, nxt[:, :, None], axis=1)
            dp, dq = dist, np.take_along_axis(dist, nxt, axis=1)
            for j in range(most):
                v = valid[:, j]
                # Keep p when inside; add the crossing when the edge p q crosses the plane.
                keep_p = v & (dp[:, j] >= 0)
                rows = np.flatnonzero(keep_p)
                new[rows, new_count[rows]] = p[rows, j]
                new_count[rows] += 1
                crosses = v & ((dp[:, j] >= 0) != (dq[:, j] >= 0))
                rows = np.flatnonzero(crosses)
                t = dp[rows, j] / (dp[rows, j] - dq[rows, j])
                x = p[rows, j] + t[:, None] * (q[rows, j] - p[rows, j])
                x[:, axis] = bound  # exactly on the plane
                new[rows, new_count[rows]] = x
                new_count[rows] += 1
            poly, count = new, new_count
    fans = []
    for j in range(1, most - 1):
        rows = np.flatnonzero(count > j + 1)
        fans.append(np.stack([poly[rows, 0], poly[rows, j], poly[rows, j + 1]], axis=1))
    parts = np.concatenate([keep, *fans])
    edge1, edge2 = parts[:, 1] - parts[:, 0], parts[:, 2] - parts[:, 0]
    area = np.linalg.norm(np.cross(edge1, edge2), axis=1)
    return parts[area > 0]


def _manifold3d() -> Any:
    return require("manifold3d", "min_depth finer than single precision allows over whole "
                   "bodies (solids cut to the regions where they meet)", "test")


class SolidCutter:
    """A closed body in float64, cut to boxes (manifold3d's exact intersection).

    Parameters
    ----------
    vertices : (V, 3) float64
        The body's vertices in the frame the boxes are given in (near its boxes, so that
        manifold3d's tolerance, relative to the body's extent, is what bounds the cut).
    faces : (F, 3) int
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        m3d = _manifold3d()
        self._m3d = m3d
        mesh = m3d.Mesh64(vert_properties=np.ascontiguousarray(vertices, np.float64),
                          tri_verts=np.ascontiguousarray(faces, np.uint32))
        mesh.merge()
        self.solid = m3d.Manifold(mesh)
        self.ok = self.solid.status() == m3d.Error.NoError and not self.solid.is_empty()

    def within(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """The solid within the box ``lo``, ``hi`` (3,) as triangles (M, 3, 3) float64."""
        box = self._m3d.Manifold.cube(tuple(np.asarray(hi, np.float64) - lo)).translate(
            tuple(np.asarray(lo, np.float64)))
        part = (self.solid ^ box).to_mesh64()
        v = np.asarray(part.vert_properties, np.float64)[:, :3]
        f = np.asarray(part.tri_verts, np.int64).reshape(-1, 3)
        return v[f]


def world_triangles(scene: Scene, body: int, origin: np.ndarray) -> np.ndarray:
    """A body's faces as world triangles relative to ``origin`` (3,), in float64.

    Returns
    -------
    (F, 3, 3) float64
    """
    shape = scene.shapes[int(scene.body_shape[body])]
    t = np.asarray(scene.transforms[body], np.float64)
    v = np.asarray(shape.vertices, np.float64) @ t[:3, :3].T + (t[:3, 3] - origin)
    return v[np.asarray(shape.topology.faces, np.int64)]


def body_vertices(scene: Scene, body: int, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A body's world vertices relative to ``origin`` (3,) in float64, and its faces as tested.

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    """
    shape = scene.shapes[int(scene.body_shape[body])]
    t = np.asarray(scene.transforms[body], np.float64)
    v = np.asarray(shape.vertices, np.float64) @ t[:3, :3].T + (t[:3, 3] - origin)
    return v, np.asarray(shape.topology.faces, np.int64)


def linear_map(scene: Scene, body: int) -> np.ndarray:
    """A body's 3x3 linear map (its transform's), or the identity where that is singular."""
    m = np.asarray(scene.transforms[body], np.float64)[:3, :3]
    scale = np.abs(m).max()
    if scale == 0 or abs(np.linalg.det(m)) <= 1e-9 * scale**3:
        return np.eye(3)
    return m


def meeting_regions(scene: Scene, pairs: np.ndarray, grow: float, side: float, solids: bool,
                    orient: bool, option: str = "min_depth", value: float = 0.0
                    ) -> tuple[RegionGeometry, np.ndarray]:
    """Every candidate pair's regions: tiles of at most ``side`` covering the box where the
    pair's world boxes meet grown by ``grow``, each tile grown by ``grow``, with both bodies'
    parts within it (solids closed by the tile's walls when ``solids``, else surfaces).

    Parameters
    ----------
    scene : Scene
    pairs : (K, 2) int
    grow, side : float
    solids : bool
        Cut closed bodies as solids (pass H1) rather than as surfaces (pass C1).
    orient : bool
        Keep each body's own axes in the frames (pass H1's lines).

    Returns
    -------
    geometry : RegionGeometry
    owner : (R,) int64
        The pair of each region.

    Raises
    ------
    ValueError
        A closed body manifold3d cannot take as a solid, or a pair that meets over more than
        :data:`MAX_REGIONS` regions, naming the pair (``option`` and ``value``: the query's
        figure, for the message).
    """
    lo, hi = scene.world_boxes()
    open_body = scene.open
    geometry = RegionGeometry()
    owner: list[int] = []
    for k, (a, b) in enumerate(np.asarray(pairs, np.int64)):
        meet_lo = np.maximum(lo[a], lo[b]) - grow
        meet_hi = np.minimum(hi[a], hi[b]) + grow
        origin = 0.5 * (meet_lo + meet_hi)
        counts = np.maximum(np.ceil((meet_hi - meet_lo) / side), 1)
        if counts.prod() > MAX_REGIONS:
            # Regions scale with the figure along each axis the pair meets over more than one.
            axes = max(int((counts > 1).sum()), 1)
            coarser = value * (counts.prod() / MAX_REGIONS) ** (1.0 / axes)
            raise ValueError(
                f"{option} {value:g} is too small for {scene.label(int(a))} and "
                f"{scene.label(int(b))}: they meet over a box of "
                f"{' x '.join(f'{x:.3g}' for x in meet_hi - meet_lo)}, which would be measured "
                f"in {int(counts.prod())} regions (at most {MAX_REGIONS}, each small enough for "
                f"single precision); use a {option} of at least {coarser:.3g}, or query those "
                f"bodies at their own scale")
        _, t_lo, t_hi = tiles((meet_lo - origin)[None], (meet_hi - origin)[None], side)
        parts = []
        for body in (a, b):
            if solids and not open_body[body]:
                cutter = SolidCutter(*body_vertices(scene, body, origin))
                if not cutter.ok:
                    raise ValueError(
                        f"{scene.label(int(body))} is closed but not a two-manifold solid "
                        f"manifold3d can cut, so its pair with "
                        f"{scene.label(int(b if body == a else a))} cannot be measured in the "
                        f"regions where they meet; use a coarser min_depth for it")
                parts.append(cutter.within)
            else:
                tris = world_triangles(scene, body, origin)
                parts.append(lambda l, h, tris=tris: clip_triangles(tris, l, h))
        map_a = linear_map(scene, a) if orient else np.eye(3)
        map_b = linear_map(scene, b) if orient else np.eye(3)
        for l, h in zip(t_lo - grow, t_hi + grow):
            part_a = parts[0](l, h)
            if len(part_a) == 0:
                continue
            part_b = parts[1](l, h)
            if len(part_b) == 0:
                continue
            geometry.add(part_a, part_b, 0.5 * (l + h), map_a, map_b)
            owner.append(k)
    return geometry, np.array(owner, np.int64)


class RegionGeometry:
    """Pieces of two bodies per region, packed for passes H1 and C1: vertices in the region's own
    frame, rounded to single precision only after the cut.

    Each region ``r`` gets a :data:`~pycinder.focused.modes.pairwork.FRAME` whose rows are body
    a's linear map (``m0``) and body b's (``m1``) with no translation, and its pieces' vertices
    are stored as ``inverse(map) @ (world - centre)``, so the shaders' lines along each body's
    axes are the bodies' own, and ``to_pair`` gives ``world - centre``. Without ``orient`` both
    maps are the identity (pass C1 needs no lines).
    """

    def __init__(self) -> None:
        self.positions: list[np.ndarray] = []
        self.faces_a: list[tuple[int, int]] = []
        self.faces_b: list[tuple[int, int]] = []
        self.frames: list[np.ndarray] = []
        self.reach: list[float] = []
        self._faces = 0

    def add(self, part_a: np.ndarray, part_b: np.ndarray, centre: np.ndarray,
            map_a: np.ndarray, map_b: np.ndarray) -> None:
        """Add a region: both bodies' parts (M, 3, 3) float64 relative to the pair's origin,
        the region's centre (3,) relative to it, and each body's 3x3 linear map."""
        frame = FRAME.zeros(1)
        spans = []
        for part, linear, field in ((part_a, map_a, "m0"), (part_b, map_b, "m1")):
            local = part.reshape(-1, 3) - centre
            inverse = np.linalg.inv(linear)
            self.positions.append((local @ inverse.T).astype(np.float32))
            m = np.zeros((3, 4))
            m[:, :3] = linear
            frame[field] = m
            spans.append((self._faces, len(part)))
            self._faces += len(part)
        self.faces_a.append(spans[0])
        self.faces_b.append(spans[1])
        self.frames.append(frame)
        pts = np.concatenate([part_a.reshape(-1, 3), part_b.reshape(-1, 3)]) - centre
        self.reach.append(float(np.sqrt((pts * pts).sum(axis=1).max())) if len(pts) else 0.0)

    def __len__(self) -> int:
        return len(self.frames)

    def packed(self, whole_faces: int | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The regions packed: positions (3 P,) float32, faces (3 F,) uint32 (three vertices of
        their own per face), items, frames (R,) and reach (R,) float64.

        Each region's items are chunks of at most :data:`~pycinder.gpu.layout.CLUSTER_FACES`
        faces of a and of b; with ``whole_faces``, a region whose b part has at most that many
        faces and at most 2^16 face pairs is one item (marked whole, so pass H1 may stop early).
        """
        positions = (np.concatenate(self.positions).reshape(-1) if self.positions
                     else np.zeros(0, np.float32))
        faces = np.arange(3 * self._faces, dtype=np.uint32)
        rows = []
        for r, ((sa, na), (sb, nb)) in enumerate(zip(self.faces_a, self.faces_b)):
            if na == 0 or nb == 0:
                continue
            if whole_faces is not None and nb <= whole_faces and na * nb <= 2**16:
                rows.append((r, sa, na, sb, nb, 1))
                continue
            for i in range(sa, sa + na, CLUSTER_FACES):
                for j in range(sb, sb + nb, CLUSTER_FACES):
                    rows.append((r, i, min(CLUSTER_FACES, sa + na - i), j,
                                 min(CLUSTER_FACES, sb + nb - j), 0))
        items = ITEM.zeros(len(rows))
        if rows:
            table = np.array(rows, np.int64)
            for k, name in enumerate(("pair", "a_start", "a_count", "b_start", "b_count",
                                      "whole")):
                items[name] = table[:, k]
        frames = np.concatenate(self.frames) if self.frames else FRAME.zeros(0)
        return positions, faces, items, frames, np.array(self.reach, np.float64)


class RegionBuffers:
    """The packed regions' vertices and faces on the GPU (made once per mode, grown as needed).

    Parameters
    ----------
    device : wgpu.GPUDevice
    label : str
    """

    def __init__(self, device: wgpu.GPUDevice, label: str) -> None:
        usage = wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_DST
        self.positions = GrowableBuffer(device, f"{label} positions", usage)
        self.faces = GrowableBuffer(device, f"{label} faces", usage)

    def write(self, positions: np.ndarray, faces: np.ndarray) -> None:
        """Upload :meth:`RegionGeometry.packed`'s positions (3 P,) float32 and faces (3 F,)
        uint32."""
        for buffer, data in ((self.positions, positions), (self.faces, faces)):
            buffer.ensure(max(data.nbytes, 16))
            if data.nbytes:
                buffer.write(data)


__all__ = ["ROUNDING", "RegionBuffers", "RegionGeometry", "SolidCutter", "body_vertices", "clip_triangles",
           "linear_map", "meeting_regions", "tile_side", "tiles", "world_triangles"]

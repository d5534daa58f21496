"""Regions where a pair's bodies meet, measured at the region's own scale.

A figure measured in single precision is rounded in proportion to how far the vertices it is
computed from lie from the frame's origin. Measured over two whole bodies, that is the bodies'
extent (an 84 m slab) and, for models in map coordinates, their distance from the origin. Here a
pair is measured instead in regions: boxes of at most :func:`tile_side` per side covering the box
where the pair's world boxes meet (grown by a margin) wherever a face of one body is near the
other (:func:`meeting_tiles`), each with its own frame at its centre, and
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

import weakref
from typing import TYPE_CHECKING, Any

import numpy as np
import wgpu

from ...gpu.buffers import GrowableBuffer
from ...gpu.layout import CLUSTER_FACES
from ...util.optional import require
from .pair_work import FRAME, ITEM, TOUCH

if TYPE_CHECKING:
    from ...scene import Scene

MAX_REGIONS = 20_000
"""Most regions one pair is measured in: a pair that would need more is refused, naming the
coarser figure that would do."""

ROUNDING = 2.0**-16
"""Bound of a figure's rounding per unit of the reach of its frame's vertices (single
precision: a few units of 2^-24 per operation, with the conditioning of the shaders' tests)."""


STORED_ROUNDING = 2.0**-22
"""Bound of how far a body's stored vertices (single precision, about the centre of their box)
lie from where it was given, per unit of its bounding radius (in world units, its transform's
largest stretch included): 4 units of 2^-24. Region pieces are cut from the stored vertices, so
two bodies given touching may overlap by that much in a region, whatever its own scale."""


def stored_rounding(scene: Scene, body: int) -> float:
    """How far body ``body``'s stored vertices may lie from where they were given, in world
    units (:data:`STORED_ROUNDING`)."""
    shape = scene.shapes[int(scene.body_shape[body])]
    stretch = float(np.linalg.norm(np.asarray(scene.transforms[body], np.float64)[:3, :3], 2))
    return STORED_ROUNDING * shape.radius * stretch


def tile_side(value: float, grow: float, fraction: float = 1 / 32) -> float:
    """The largest side of a region whose figures are rounded by at most ``fraction`` of
    ``value``, with regions grown by ``grow`` on every side.

    A region of side ``s`` grown by ``g`` reaches ``sqrt(3) / 2 * (s + 2 g)`` from its centre, so
    its rounding bound is :data:`ROUNDING` times that.
    """
    return max(fraction * value / (ROUNDING * 0.5 * np.sqrt(3.0)) - 2.0 * grow, grow)


def triangles_meet_box(tris: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Which triangles meet boxes (the separating-axis test over the box's three axes, the
    triangle's normal and the nine crossings of their edges; touching counts as meeting, and a
    slack of 1e-9 of the sizes involved keeps the test on the side of meeting).

    Parameters
    ----------
    tris : (T, 3, 3) float64
    lo, hi : (3,) or (T, 3) float64
        One box, or one per triangle.

    Returns
    -------
    (T,) bool
    """
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    half = np.broadcast_to(half, (len(tris), 3))
    v = tris - np.broadcast_to(centre, (len(tris), 3))[:, None, :]
    scale = half.max(axis=1) + np.abs(v).max(axis=(1, 2)) if len(tris) else np.zeros(0)
    slack = 1e-9 * scale
    meet = np.all((v.min(axis=1) <= half + slack[:, None]) &
                  (v.max(axis=1) >= -half - slack[:, None]), axis=1)
    edges = np.roll(v, -1, axis=1) - v  # (T, 3, 3): edge i from corner i
    ex, ey, ez = edges[..., 0], edges[..., 1], edges[..., 2]  # (T, 3) each
    zero = np.zeros_like(ex)
    # The normal, then the unit axes x, y, z crossed with each edge (T, 10, 3).
    axes = np.concatenate([
        np.cross(edges[:, 0], edges[:, 1])[:, None],
        np.stack([zero, -ez, ey], axis=2),   # x cross each edge
        np.stack([ez, zero, -ex], axis=2),   # y cross each edge
        np.stack([-ey, ex, zero], axis=2),   # z cross each edge
    ], axis=1)
    p = np.einsum("tkc,tac->tak", v, axes)  # (T, 10, 3): each corner along each axis
    size = np.abs(axes)
    r = np.einsum("tac,tc->ta", size, half) + slack[:, None] * size.sum(axis=2)
    meet &= np.all((p.min(axis=2) <= r) & (p.max(axis=2) >= -r), axis=1)
    return meet


def meeting_tiles(lo: np.ndarray, hi: np.ndarray, side: float, grow: float,
                  tris: list[np.ndarray], solid: list[bool],
                  most: int = MAX_REGIONS) -> tuple[np.ndarray, np.ndarray]:
    """Tiles of at most ``side`` per side where two bodies may meet: the box ``lo``, ``hi``
    halved along its longest side until small enough, keeping a part only where, grown by
    ``grow``, it meets a face of one body and, of the other, a face or (a solid) possibly its
    inside. Level by level, each part tested against the faces that met its parent.

    Parameters
    ----------
    lo, hi : (3,) float64
    side, grow : float
    tris : [(Ta, 3, 3), (Tb, 3, 3)] float64
        The bodies' faces.
    solid : [bool, bool]
        Whether each body has an inside (a tile without its faces may lie within it).
    most : int
        Stop once more tiles than this are found, or more than four times as many parts are
        still to halve (the caller refuses the pair: more than ``most`` are returned).

    Returns
    -------
    tile_lo, tile_hi : (T, 3) float64
    """
    b_lo = np.asarray(lo, np.float64)[None]
    b_hi = np.asarray(hi, np.float64)[None]
    # Per body, (part, face) rows still to test.
    rows = [(np.zeros(len(t), np.int64), np.arange(len(t))) for t in tris]
    found_lo, found_hi = [], []
    found = 0
    while len(b_lo) and found <= most:
        if found + len(b_lo) > 4 * most:  # parts still to halve: at least this many tiles
            found += len(b_lo)
            found_lo.append(b_lo)
            found_hi.append(b_hi)
            break
        has = []
        for k in range(2):
            part, face = rows[k]
            meet = triangles_meet_box(tris[k][face], b_lo[part] - grow, b_hi[part] + grow)
            rows[k] = (part[meet], face[meet])
            has.append(np.bincount(rows[k][0], minlength=len(b_lo)) > 0)
        keep = (has[0] | has[1]) & (has[0] | solid[0]) & (has[1] | solid[1])
        size = b_hi - b_lo
        small = size.max(axis=1) <= side
        done = keep & small
        found_lo.append(b_lo[done])
        found_hi.append(b_hi[done])
        found += int(done.sum())
        split = np.flatnonzero(keep & ~small)
        # Part i of the split ones becomes parts 2 i and 2 i + 1 of the next level.
        index = np.full(len(b_lo), -1)
        index[split] = np.arange(len(split))
        axis = np.argmax(size[split], axis=1)
        mid = 0.5 * (b_lo[split, axis] + b_hi[split, axis])
        lower_hi, upper_lo = b_hi[split].copy(), b_lo[split].copy()
        lower_hi[np.arange(len(split)), axis] = mid
        upper_lo[np.arange(len(split)), axis] = mid
        b_lo = np.stack([b_lo[split], upper_lo], axis=1).reshape(-1, 3)
        b_hi = np.stack([lower_hi, b_hi[split]], axis=1).reshape(-1, 3)
        for k in range(2):
            part, face = rows[k]
            alive = index[part] >= 0
            part, face = 2 * index[part[alive]], face[alive]
            rows[k] = (np.concatenate([part, part + 1]), np.concatenate([face, face]))
    return np.concatenate(found_lo), np.concatenate(found_hi)


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
            k = np.arange(most)
            valid = k[None, :] < count[:, None]
            if np.all(dist[valid] >= 0):  # no corner beyond this plane: nothing to cut
                continue
            new = np.zeros_like(poly)
            new_count = np.zeros_like(count)
            nxt = (k[None, :] + 1) % np.maximum(count[:, None], 1)
            p, q = poly, np.take_along_axis(poly, nxt[:, :, None], axis=1)
            dp, dq = dist, np.take_along_axis(dist, nxt, axis=1)
            for j in range(int(count.max())):  # each plane adds at most one corner
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
    for j in range(1, int(count.max(initial=0)) - 1):
        rows = np.flatnonzero(count > j + 1)
        fans.append(np.stack([poly[rows, 0], poly[rows, j], poly[rows, j + 1]], axis=1))
    parts = np.concatenate([keep, *fans])
    edge1, edge2 = parts[:, 1] - parts[:, 0], parts[:, 2] - parts[:, 0]
    area = np.linalg.norm(np.cross(edge1, edge2), axis=1)
    return parts[area > 0]


def contains(tris: np.ndarray, point: np.ndarray) -> bool:
    """Whether a closed surface's triangles (T, 3, 3) float64 hold ``point`` (3,) inside: the
    parity of their crossings by a ray from it (in a direction no building axis is near, so that
    the ray misses edges and vertices but for sets of measure zero)."""
    direction = np.array([0.5773502691896258, 0.5163977794943222, 0.6324555320336759])
    v0, e1, e2 = tris[:, 0] - point, tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    h = np.cross(direction, e2)
    det = np.einsum("tc,tc->t", e1, h)
    ok = np.abs(det) > 1e-300
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = -v0
    u = np.einsum("tc,tc->t", s, h) * inv
    q = np.cross(s, e1)
    v = (q @ direction) * inv
    t = np.einsum("tc,tc->t", e2, q) * inv
    hits = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return bool(hits.sum() % 2)


def _manifold3d() -> Any:
    return require("manifold3d", "min_depth finer than single precision allows over whole "
                   "bodies (solids cut to the regions where they meet)", "bim")


def mesh_solid(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray) -> Any:
    """A closed mesh as a manifold3d solid about ``origin``, in float64, each part wound outward
    as pycinder winds a closed mesh wound inconsistently (:mod:`pycinder.scene.winding`, here
    with the vertices about ``origin`` in float64, so that a georeferenced part faces as it
    does); None where the mesh is open or manifold3d refuses it.

    Parameters
    ----------
    vertices : (V, 3) float64
        World vertices.
    faces : (F, 3) int
    origin : (3,) float64
        The solid's origin in the world (near where it is cut).

    Returns
    -------
    manifold3d.Manifold or None
    """
    from ...scene.topology import build_topology

    local = np.asarray(vertices, np.float64) - origin
    topo = build_topology(np.asarray(faces), len(local), "")
    if not topo.closed:
        return None
    topo.orient(local)
    cutter = SolidCutter(local, np.asarray(topo.faces, np.int64))
    return cutter.solid if cutter.ok else None


def manifold_pieces(faces: np.ndarray) -> list[np.ndarray]:
    """A solid's faces in pieces that are each a two-manifold: faces joined through edges that
    exactly two faces share. A closed mesh is one piece or more; a solid whose closed parts
    share an edge (three or more faces on it: steps of a stair modelled as boxes meeting along
    their edges) falls apart into those parts.

    Parameters
    ----------
    faces : (F, 3) int

    Returns
    -------
    list of (F_i,) int64
        The face indices of each piece.
    """
    faces = np.asarray(faces, np.int64)
    n = len(faces)
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, which, count = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    which = which.reshape(-1)
    owner = np.repeat(np.arange(n), 3)
    twice = count[which] == 2
    order = np.argsort(which[twice], kind="stable")
    joined = owner[twice][order].reshape(-1, 2)  # the two faces of each edge shared by two
    label = np.arange(n)
    while True:  # connected components: the least face index of each, by pointer jumping
        low = np.minimum(label[joined[:, 0]], label[joined[:, 1]])
        before = label.copy()
        np.minimum.at(label, joined[:, 0], low)
        np.minimum.at(label, joined[:, 1], low)
        label = label[label]
        if np.array_equal(label, before):
            break
    _, piece = np.unique(label, return_inverse=True)
    order = np.argsort(piece, kind="stable")
    return np.split(order, np.flatnonzero(np.diff(piece[order])) + 1)


class SolidCutter:
    """A closed body in float64, cut to boxes (manifold3d's exact intersection).

    A solid whose closed parts share an edge (a balanced mesh with edges of more than two faces,
    which manifold3d does not take whole) is the union of its parts
    (:func:`manifold_pieces`), less those wound inward (its cavities).

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
        vertices = np.ascontiguousarray(vertices, np.float64)
        faces = np.asarray(faces, np.int64)
        self.solid = self._manifold(vertices, faces)
        if self.solid.status() != m3d.Error.NoError and len(faces):
            parts = [faces[f] for f in manifold_pieces(faces)]
            pieces = [self._manifold(vertices, f) for f in parts]
            if all(p.status() == m3d.Error.NoError for p in pieces):
                add = [p for p in pieces if p.volume() > 0]
                cut = [self._manifold(vertices, f[:, ::-1])  # a cavity, wound outward
                       for f, p in zip(parts, pieces) if p.volume() < 0]
                solid = m3d.Manifold.batch_boolean(add, m3d.OpType.Add) if add else None
                if solid is not None and cut:
                    solid = solid - m3d.Manifold.batch_boolean(cut, m3d.OpType.Add)
                if solid is not None:
                    self.solid = solid
        # Wound inside out (manifold3d takes it, with a negative volume), its inside would be
        # cut as its outside: not a solid to cut.
        self.ok = (self.solid.status() == m3d.Error.NoError and not self.solid.is_empty()
                   and self.solid.volume() > 0)

    def _manifold(self, vertices: np.ndarray, faces: np.ndarray) -> Any:
        """manifold3d's solid of ``faces`` (F, 3) over ``vertices`` (V, 3), welded."""
        used, tri = np.unique(faces, return_inverse=True)
        mesh = self._m3d.Mesh64(vert_properties=np.ascontiguousarray(vertices[used]),
                                tri_verts=np.ascontiguousarray(tri.reshape(-1, 3), np.uint32))
        mesh.merge()
        return self._m3d.Manifold(mesh)

    def moved(self, offset: np.ndarray) -> SolidCutter:
        """The same solid translated by ``offset`` (3,) float64 (manifold3d's translation, in
        float64): one body's cutter serves the frames of all its pairs."""
        out = object.__new__(SolidCutter)
        out._m3d, out.ok = self._m3d, self.ok
        out.solid = self.solid.translate(tuple(float(x) for x in offset))
        return out

    def within(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """The solid within the box ``lo``, ``hi`` (3,) as triangles (M, 3, 3) float64."""
        box = self._m3d.Manifold.cube(tuple(np.asarray(hi, np.float64) - lo)).translate(
            tuple(np.asarray(lo, np.float64)))
        part = (self.solid ^ box).to_mesh64()
        v = np.asarray(part.vert_properties, np.float64)[:, :3]
        f = np.asarray(part.tri_verts, np.int64).reshape(-1, 3)
        return v[f]


_cutters: weakref.WeakKeyDictionary[Scene, dict[int, tuple[np.ndarray, SolidCutter]]] = \
    weakref.WeakKeyDictionary()


def placed_cutter(scene: Scene, body: int, origin: np.ndarray) -> SolidCutter:
    """A closed body's :class:`SolidCutter` in the frame about ``origin`` (3,): made once per
    scene and body, about the centre of the body's world box, and translated."""
    made = _cutters.setdefault(scene, {})
    if body not in made:
        lo, hi = scene.world_boxes()
        centre = 0.5 * (lo[body] + hi[body])
        made[body] = (centre, SolidCutter(*body_vertices(scene, body, centre)))
    centre, cutter = made[body]
    return cutter.moved(centre - np.asarray(origin, np.float64))


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
    """A body's world vertices relative to ``origin`` (3,) in float64, and its faces as tested,
    turned the other way round where the body's transform mirrors it (so that a closed body's
    faces still face out: manifold3d takes them as a solid).

    Returns
    -------
    vertices : (V, 3) float64
    faces : (F, 3) int64
    """
    shape = scene.shapes[int(scene.body_shape[body])]
    t = np.asarray(scene.transforms[body], np.float64)
    v = np.asarray(shape.vertices, np.float64) @ t[:3, :3].T + (t[:3, 3] - origin)
    faces = np.asarray(shape.topology.faces, np.int64)
    return v, (faces[:, ::-1] if np.linalg.det(t[:3, :3]) < 0 else faces)


def linear_map(scene: Scene, body: int) -> np.ndarray:
    """A body's 3x3 linear map (its transform's), or the identity where that is singular."""
    m = np.asarray(scene.transforms[body], np.float64)[:3, :3]
    scale = np.abs(m).max()
    if scale == 0 or abs(np.linalg.det(m)) <= 1e-9 * scale**3:
        return np.eye(3)
    return m


def meeting_regions(scene: Scene, pairs: np.ndarray, grow: float, side: float, solids: bool,
                    orient: bool, option: str = "min_depth", value: float = 0.0,
                    search: tuple[np.ndarray, np.ndarray] | None = None
                    ) -> tuple[RegionGeometry, np.ndarray]:
    """Every candidate pair's regions: tiles of at most ``side`` covering the box where the
    pair's world boxes meet grown by ``grow`` (or the box ``search`` gives), where a face of
    one body is near the other (:func:`meeting_tiles`), each tile grown by ``grow``, with both
    bodies' parts within it (solids closed by the tile's walls when ``solids``, else surfaces).

    Parameters
    ----------
    scene : Scene
    pairs : (K, 2) int
        The pairs (a pair may come more than once, with different ``search`` boxes).
    grow, side : float
    solids : bool
        Cut closed bodies as solids (pass H1) rather than as surfaces (pass C1).
    orient : bool
        Keep each body's own axes in the frames (pass H1's lines).
    option, value : str, float
        The query's option and figure, for the messages.
    search : (K, 3) float64, (K, 3) float64, optional
        World boxes to cover instead of where the pairs' world boxes meet.

    Returns
    -------
    geometry : RegionGeometry
    owner : (R,) int64
        The row of ``pairs`` of each region.

    Raises
    ------
    ValueError
        A closed body manifold3d cannot take as a solid, or a pair that meets over more than
        :data:`MAX_REGIONS` regions, naming the pair.
    """
    lo, hi = scene.world_boxes()
    open_body = scene.open
    geometry = RegionGeometry()
    owner: list[int] = []
    bodies: dict[tuple[int, int], tuple] = {}
    for k, (a, b) in enumerate(np.asarray(pairs, np.int64)):
        meet_lo = np.maximum(lo[a], lo[b]) - grow
        meet_hi = np.minimum(hi[a], hi[b]) + grow
        if (a, b) not in bodies:
            bodies = {(a, b): _pair_bodies(scene, int(a), int(b), meet_lo, meet_hi, solids,
                                           orient, open_body, option)}
        origin, tris, solid, parts, map_a, map_b, stored = bodies[(a, b)]
        if search is not None:
            meet_lo, meet_hi = search[0][k], search[1][k]
        if search is not None and np.all(meet_hi - meet_lo <= side):
            # One tile: a box where the pair overlaps (the caller's), which holds both.
            t_lo, t_hi = (meet_lo - origin)[None], (meet_hi - origin)[None]
        else:
            t_lo, t_hi = meeting_tiles(meet_lo - origin, meet_hi - origin, side, grow, tris,
                                       solid)
        if len(t_lo) > MAX_REGIONS:
            # Regions scale with the figure along each axis the pair meets over more than one.
            size = t_hi.max(axis=0) - t_lo.min(axis=0)
            axes = max(int((size > side).sum()), 1)
            coarser = value * (len(t_lo) / MAX_REGIONS) ** (1.0 / axes)
            raise ValueError(
                f"{option} {value:g} is too small for {scene.label(int(a))} and "
                f"{scene.label(int(b))}: they meet over a box of "
                f"{' x '.join(f'{x:.3g}' for x in meet_hi - meet_lo)} and would be measured in "
                f"more than {MAX_REGIONS} regions (each small enough for single precision, and "
                f"for a non-convex pair small enough to be local); use a {option} of at least "
                f"{coarser:.3g}, or query those bodies at their own scale")
        for tile_lo, tile_hi in zip(t_lo - grow, t_hi + grow):
            part_a = parts[0](tile_lo, tile_hi)
            if len(part_a) == 0:
                continue
            part_b = parts[1](tile_lo, tile_hi)
            if len(part_b) == 0:
                continue
            geometry.add(part_a, part_b, 0.5 * (tile_lo + tile_hi), map_a, map_b,
                         (solid[0], solid[1]), stored)
            geometry.boxes.append((tile_lo + origin, tile_hi + origin))
            owner.append(k)
    return geometry, np.array(owner, np.int64)


def _pair_bodies(scene: Scene, a: int, b: int, meet_lo: np.ndarray, meet_hi: np.ndarray,
                 solids: bool, orient: bool, open_body: np.ndarray, option: str) -> tuple:
    """What :func:`meeting_regions` needs of a pair's two bodies: the origin it cuts them
    around (where their boxes meet), their faces, whether each is cut as a solid, a function
    cutting each to a box, their linear maps, and how far their stored vertices may have moved
    them towards each other (:func:`stored_rounding`, both together)."""
    origin = 0.5 * (meet_lo + meet_hi)
    tris = [world_triangles(scene, body, origin) for body in (a, b)]
    solid = [solids and not open_body[body] for body in (a, b)]
    parts = []
    for k, body in enumerate((a, b)):
        if solid[k]:
            cutter = placed_cutter(scene, body, origin)
            if not cutter.ok:
                raise ValueError(
                    f"{scene.label(body)} is closed but not a two-manifold solid wound outward "
                    f"that manifold3d can "
                    f"cut, so its pair with {scene.label(b if body == a else a)} cannot be "
                    f"measured in the regions where they meet; use a coarser {option} for it")
            parts.append(cutter.within)
        else:
            parts.append(lambda lo, hi, t=tris[k]: clip_triangles(t, lo, hi))
    map_a = linear_map(scene, a) if orient else np.eye(3)
    map_b = linear_map(scene, b) if orient else np.eye(3)
    stored = stored_rounding(scene, a) + stored_rounding(scene, b)
    return origin, tris, solid, parts, map_a, map_b, stored


class RegionGeometry:
    """Pieces of two bodies per region, packed for passes H1 and C1: vertices in the region's own
    frame, rounded to single precision only after the cut.

    Each region ``r`` gets a :data:`~pycinder.focused.measure.pair_work.FRAME` whose rows are body
    a's linear map (``m0``) and body b's (``m1``) with no translation, and its pieces' vertices
    are stored as ``inverse(map) @ (world - centre)``, so the shaders' lines along each body's
    axes are the bodies' own, and ``to_pair`` gives ``world - centre``. Without ``orient`` both
    maps are the identity (pass C1 needs no lines).
    """

    def __init__(self) -> None:
        self.positions: list[np.ndarray] = []
        self.faces_a: list[tuple[int, int]] = []
        self.faces_b: list[tuple[int, int]] = []
        self.closed: list[tuple[bool, bool]] = []
        """Whether each region's part of body a, and of b, is a closed solid (cut by
        manifold3d and closed by the region's walls, wound outward), not a surface."""
        self.frames: list[np.ndarray] = []
        self.reach: list[float] = []
        self.boxes: list[tuple[np.ndarray, np.ndarray]] = []
        """Each region's world box (set by :func:`meeting_regions`)."""
        self._faces = 0

    def add(self, part_a: np.ndarray, part_b: np.ndarray, centre: np.ndarray,
            map_a: np.ndarray, map_b: np.ndarray,
            closed: tuple[bool, bool] = (False, False), stored: float = 0.0) -> None:
        """Add a region: both bodies' parts (M, 3, 3) float64 relative to the pair's origin,
        the region's centre (3,) relative to it, each body's 3x3 linear map, whether each
        part is a closed solid, and how far the bodies' stored vertices may have moved them
        towards each other (world units: faces overlapping by no more only touch, for pass H1's
        ``touch``, with the region's own rounding)."""
        self.closed.append(closed)
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
        pts = np.concatenate([part_a.reshape(-1, 3), part_b.reshape(-1, 3)]) - centre
        self.reach.append(float(np.sqrt((pts * pts).sum(axis=1).max())) if len(pts) else 0.0)
        if closed[0] and closed[1]:  # two solids: faces that only touch add nothing to H1
            frame["touch"] = TOUCH * self.reach[-1] + 2.0 * stored
        self.frames.append(frame)

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


__all__ = ["MAX_REGIONS", "ROUNDING", "RegionBuffers", "RegionGeometry", "STORED_ROUNDING",
           "SolidCutter", "body_vertices", "clip_triangles", "contains", "linear_map",
           "manifold_pieces", "meeting_regions", "mesh_solid", "meeting_tiles", "placed_cutter",
           "stored_rounding", "tile_side", "triangles_meet_box", "world_triangles"]

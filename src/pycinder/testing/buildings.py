"""A generated IFC building with exact truth: the model of the tests and of the ``building``
benchmark.

    cells (a bay each) -> boxes and cylinders placed on purpose -> IFC4 (or IFC2X3) files
                       -> exact distance and penetration depth of every pair closer than a margin

Each cell is one bay of a building, 6 m by 6 m and 3 m high: a slab on four columns, two beams
ending on the columns' faces under the slab, two walls butting the columns, a pipe run of three
segments butted end to end between the walls, a duct run of two segments ending on the beams'
faces and flush under the slab, and a pipe lying on the duct's underside along a line. Everything
in it touches: face on face, end on face, line on face and coplanar butt joints, as real models
do. Each cell adds one case of its own, in turn (:data:`CASES`): a pipe through a beam (deep),
a duct 20 mm into a beam (shallow), a duct 1 mm into the slab (grazing), a pipe sleeve inside a
wall (contained), a duct 10 mm from a column and a pipe 40 mm from a wall (near), a duct through
a wall (deep) and a pipe's end 20 mm into a wall (shallow). Some walls hold a door opening (an
IfcOpeningElement, applied by the tessellation), away from every other element.

Every body is an axis-aligned box or an axis-aligned cylinder, so each pair's exact distance and
penetration depth (the length of the shortest translation that separates the two, as FCL and
coal define it) follow in closed form (:func:`relation`): a box and a cylinder, or two parallel
cylinders, are products of an interval along the axis and a cross-section, whose Minkowski
difference is the product of the factors' differences. Cells are 2 m apart, so pairs of
different cells are never within :data:`MARGIN`. The tessellation turns each circle into a
polygon inscribed in it: a cylinder's figures are exact to :func:`chord_error` (under 1 mm for
the radii used, computed for :data:`CIRCLE_SEGMENTS` segments per circle).

:func:`write_ifc` writes it as IFC, at the origin or moved into map coordinates by its site's
placement (``offset``). :mod:`pycinder.testing.buildingscore` scores answers against the
truth. The tests use it, and the building benchmark (``benchmarks/building.py`` of a checkout,
not in the wheel) runs pycinder and IfcClash on it.
"""

from __future__ import annotations

import math
import os
import random
import uuid
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..util.optional import require

W, D, H = 6.0, 6.0, 3.0
"""A cell's width (x), depth (y) and storey height (z), in metres."""
SLAB = 0.2
"""Slab thickness: the slab is z in [H - SLAB, H]."""
PITCH = 8.0
"""Distance between the origins of neighbouring cells along x and y (cells are 6.6 m across at
most, so at least 1.4 m apart)."""
MARGIN = 0.2
"""Pairs closer than this are in the truth with their exact figures; every other pair is at
least this far apart."""
CASES = ("deep: pipe through beam", "shallow: duct into beam", "grazing: duct into slab",
         "contained: sleeve in wall", "near: duct by column", "near: pipe by wall",
         "deep: duct through wall", "shallow: pipe end into wall")
"""The clash case each cell adds, cell ``k`` taking ``CASES[k % 8]``."""
ELEMENTS_PER_CELL = 16
CIRCLE_SEGMENTS = 16
"""Fewest segments per circle assumed for :func:`chord_error` (IfcOpenShell uses at least this
many for the radii here)."""

GRAZE = 0.005
"""Deepest a "grazing" pair goes (metres)."""
SHALLOW = 0.05
"""Deepest a "shallow" pair goes; deeper ones are "deep"."""


@dataclass(frozen=True)
class Part:
    """One element: an axis-aligned box or cylinder.

    Attributes
    ----------
    ifc_class : str
        IFC4 class (``IfcWall``, ``IfcSlab``, ``IfcColumn``, ``IfcBeam``, ``IfcPipeSegment``,
        ``IfcDuctSegment``).
    name : str
    global_id : str
    lo, hi : (3,) float
        Box corners; for a cylinder, the corners of its bounding box.
    axis : int or None
        A cylinder's axis (0, 1 or 2); None for a box.
    radius : float
        A cylinder's radius (0 for a box).
    cell : int
        The cell the element belongs to.
    discipline : {"architecture", "structure", "mep"}
        Which file of a federated model holds it.
    """

    ifc_class: str
    name: str
    global_id: str
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    axis: int | None = None
    radius: float = 0.0
    cell: int = 0
    discipline: str = "architecture"

    @property
    def is_cylinder(self) -> bool:
        return self.axis is not None


@dataclass(frozen=True)
class Relation:
    """The exact relation of a pair of parts.

    Attributes
    ----------
    distance : float
        Euclidean distance between the solids (0 when they touch or overlap).
    depth : float
        Penetration depth: the length of the shortest translation that separates them (0 when
        they touch or are apart).
    contained : bool
        One lies wholly inside the other.
    error : float
        Bound on both figures' error once cylinders are tessellated (0 for two boxes).
    """

    distance: float
    depth: float
    contained: bool = False
    error: float = 0.0

    @property
    def kind(self) -> str:
        """``"touching"``, ``"near"``, ``"grazing"``, ``"shallow"``, ``"deep"`` or
        ``"contained"``."""
        if self.contained:
            return "contained"
        if self.depth > SHALLOW:
            return "deep"
        if self.depth > GRAZE:
            return "shallow"
        if self.depth > 0:
            return "grazing"
        return "touching" if self.distance == 0 else "near"


@dataclass
class Building:
    """A generated building: its parts and the exact relation of every pair within
    :data:`MARGIN`.

    Attributes
    ----------
    parts : list of Part
    truth : dict
        ``(global_id, global_id)`` (sorted) to :class:`Relation`, for every pair closer than
        :data:`MARGIN`; every other pair is at least that far apart.
    openings : list of (str, (3,) float, (3,) float)
        Door openings: the voided wall's GlobalId and the opening's box corners.
    """

    parts: list[Part]
    truth: dict[tuple[str, str], Relation]
    openings: list[tuple[str, tuple[float, ...], tuple[float, ...]]] = field(default_factory=list)

    def by_id(self) -> dict[str, Part]:
        return {p.global_id: p for p in self.parts}

    def pairs(self, kind: str) -> set[tuple[str, str]]:
        """The pairs (sorted GlobalIds) of one :attr:`Relation.kind`."""
        return {k for k, r in self.truth.items() if r.kind == kind}

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for r in self.truth.values():
            out[r.kind] = out.get(r.kind, 0) + 1
        return out


def chord_error(radius: float, segments: int = CIRCLE_SEGMENTS) -> float:
    """How far a polygon of ``segments`` sides inscribed in a circle of ``radius`` comes inside
    it, at most: ``radius (1 - cos(pi / segments))``."""
    return radius * (1.0 - math.cos(math.pi / segments))


# -- exact relations ------------------------------------------------------------------------


def _interval(a_lo: float, a_hi: float, b_lo: float, b_hi: float) -> tuple[float, float]:
    """Gap (>= 0) and depth (>= 0: the shortest shift that separates them) of two intervals."""
    gap = max(b_lo - a_hi, a_lo - b_hi, 0.0)
    depth = max(min(a_hi - b_lo, b_hi - a_lo), 0.0)
    return _snap(gap), _snap(depth)


EXACT = 1e-9
"""Figures below this (metres) are rounding of the placements' sums: they are 0."""


def _snap(x: float) -> float:
    return 0.0 if abs(x) < EXACT else float(x)


def _section(p: Part, axis: int) -> tuple[np.ndarray, np.ndarray]:
    other = [k for k in range(3) if k != axis]
    return np.asarray(p.lo)[other], np.asarray(p.hi)[other]


def _disk_rect(c: np.ndarray, r: float, lo: np.ndarray, hi: np.ndarray) -> tuple[float, float]:
    """Gap and depth of a disk (centre ``c``, radius ``r``) and a rectangle, in 2-D: the depth
    is the distance from ``c`` to the boundary of the rectangle grown by ``r`` (support
    functions: ``r`` plus the distance to the nearest side inside, ``r`` less the distance to
    the rectangle outside)."""
    outside = np.maximum(np.maximum(lo - c, c - hi), 0.0)
    d_out = float(np.linalg.norm(outside))
    if d_out > 0:
        return _snap(max(d_out - r, 0.0)), _snap(max(r - d_out, 0.0))
    return 0.0, r + float(np.min(np.minimum(c - lo, hi - c)))


def relation(a: Part, b: Part) -> Relation:
    """The exact :class:`Relation` of two parts.

    Raises
    ------
    ValueError
        For two cylinders whose axes are not parallel (the generator never places them near
        each other).
    """
    if not a.is_cylinder and not b.is_cylinder:
        gaps, depths = zip(*(_interval(a.lo[k], a.hi[k], b.lo[k], b.hi[k]) for k in range(3)))
        distance = _snap(float(np.linalg.norm(gaps)))
        depth = min(depths) if distance == 0 else 0.0
        inside = all(a.lo[k] >= b.lo[k] and a.hi[k] <= b.hi[k] for k in range(3)) or \
            all(b.lo[k] >= a.lo[k] and b.hi[k] <= a.hi[k] for k in range(3))
        return Relation(distance, depth, inside and depth > 0)
    if a.is_cylinder and b.is_cylinder and a.axis != b.axis:
        raise ValueError(f"{a.name} and {b.name}: cylinders across each other have no exact "
                         "relation here")
    cyl, other = (a, b) if a.is_cylinder else (b, a)
    k = cyl.axis
    assert k is not None
    gap_ax, depth_ax = _interval(cyl.lo[k], cyl.hi[k], other.lo[k], other.hi[k])
    c_lo, c_hi = _section(cyl, k)
    centre = (c_lo + c_hi) / 2
    o_lo, o_hi = _section(other, k)
    if other.is_cylinder:
        oc = (o_lo + o_hi) / 2
        dc = float(np.linalg.norm(centre - oc))
        gap_2d = _snap(max(dc - cyl.radius - other.radius, 0.0))
        depth_2d = _snap(max(cyl.radius + other.radius - dc, 0.0))
        inside_2d = dc + min(cyl.radius, other.radius) <= max(cyl.radius, other.radius)
        error = chord_error(cyl.radius) + chord_error(other.radius)
    else:
        gap_2d, depth_2d = _disk_rect(centre, cyl.radius, o_lo, o_hi)
        inside_2d = bool(np.all(c_lo >= o_lo) and np.all(c_hi <= o_hi))
        error = chord_error(cyl.radius)
    distance = _snap(math.hypot(gap_ax, gap_2d))
    depth = min(depth_ax, depth_2d) if distance == 0 else 0.0
    inside_ax = (cyl.lo[k] >= other.lo[k] and cyl.hi[k] <= other.hi[k])
    contained = inside_ax and inside_2d and depth > 0 and not other.is_cylinder
    return Relation(distance, depth, contained, error)


# -- layout ---------------------------------------------------------------------------------


def _cell_parts(k: int, origin: np.ndarray, new_id: Callable[[], str]
                ) -> tuple[list[Part], list[tuple[str, tuple[float, ...], tuple[float, ...]]]]:
    """The parts of cell ``k`` at ``origin``, and its door opening (every fourth cell)."""
    parts: list[Part] = []
    o = origin

    def box(cls: str, name: str, lo: Sequence[float], hi: Sequence[float], disc: str) -> Part:
        p = Part(cls, f"{name} {k}", new_id(), tuple(map(float, o + lo)),
                 tuple(map(float, o + hi)), cell=k, discipline=disc)
        parts.append(p)
        return p

    def cyl(cls: str, name: str, axis: int, start: Sequence[float], length: float, r: float,
            disc: str = "mep") -> Part:
        c = o + np.asarray(start, float)
        lo, hi = c - r, c + r
        lo[axis], hi[axis] = c[axis], c[axis] + length
        p = Part(cls, f"{name} {k}", new_id(), tuple(map(float, lo)), tuple(map(float, hi)),
                 axis=axis, radius=r, cell=k, discipline=disc)
        parts.append(p)
        return p

    top = H - SLAB  # underside of the slab
    box("IfcSlab", "Slab", (0, 0, top), (W, D, H), "architecture")
    for i, (x, y) in enumerate([(0, 0), (W - 0.3, 0), (0, D - 0.3), (W - 0.3, D - 0.3)]):
        box("IfcColumn", f"Column {i}", (x, y, 0), (x + 0.3, y + 0.3, top), "structure")
    beam_lo = top - 0.4
    box("IfcBeam", "Beam south", (0.3, 0, beam_lo), (W - 0.3, 0.3, top), "structure")
    box("IfcBeam", "Beam north", (0.3, D - 0.3, beam_lo), (W - 0.3, D, top), "structure")
    box("IfcWall", "Wall west", (0, 0.3, 0), (0.2, D - 0.3, top), "architecture")
    east = box("IfcWall", "Wall east", (W - 0.2, 0.3, 0), (W, D - 0.3, top), "architecture")
    run = (W - 0.4) / 3
    for i in range(3):
        cyl("IfcPipeSegment", f"Pipe {i}", 0, (0.2 + i * run, D / 2, 2.0), run, 0.05)
    for i, (y0, y1) in enumerate([(0.3, D / 2), (D / 2, D - 0.3)]):
        box("IfcDuctSegment", f"Duct {i}", (W / 2 - 0.2, y0, top - 0.3), (W / 2 + 0.2, y1, top),
            "mep")
    cyl("IfcPipeSegment", "Pipe under duct", 1, (W / 2, 0.8, top - 0.3 - 0.04), D - 1.6, 0.04)
    case = k % len(CASES)
    if case == 0:  # through the south beam's web, 0.25 m deep
        cyl("IfcPipeSegment", "Pipe through beam", 1, (W / 2 + 1, -0.3, beam_lo + 0.2), 1.3, 0.05)
    elif case == 1:  # 20 mm up into the south beam
        box("IfcDuctSegment", "Duct into beam", (1, 0.05, beam_lo - 0.3 + 0.02),
            (3, 0.25, beam_lo + 0.02), "mep")
    elif case == 2:  # 1 mm up into the slab
        box("IfcDuctSegment", "Duct into slab", (0.5, D / 2 + 0.8, top - 0.3 + 0.001),
            (2.5, D / 2 + 1.2, top + 0.001), "mep")
    elif case == 3:  # a sleeve inside the west wall
        cyl("IfcPipeSegment", "Sleeve in wall", 0, (0.05, D / 2 + 1, 1.0), 0.1, 0.03)
    elif case == 4:  # 10 mm from the south-west column
        box("IfcDuctSegment", "Duct by column", (0.31, 0, 1.0), (0.71, 0.3, 1.3), "mep")
    elif case == 5:  # 40 mm from the west wall
        cyl("IfcPipeSegment", "Pipe by wall", 1, (0.2 + 0.04 + 0.05, 1.0, 1.5), 1.0, 0.05)
    elif case == 6:  # through the east wall, 0.5 m deep
        box("IfcDuctSegment", "Duct through wall", (W - 1, D / 2 + 1.5, 1.5),
            (W + 0.3, D / 2 + 1.9, 1.8), "mep")
    else:  # a pipe's end 20 mm into the west wall
        cyl("IfcPipeSegment", "Pipe into wall", 0, (0.2 - 0.02, 2.0, 0.8), 1.3, 0.05)
    openings = []
    if k % 4 == 0:  # a door through the east wall, clear of every other element
        openings.append((east.global_id, tuple(map(float, o + (W - 0.3, 1.0, 0.0))),
                         tuple(map(float, o + (W + 0.1, 2.0, 2.1)))))
    return parts, openings


def generate(elements: int = 3000, seed: int = 0) -> Building:
    """A building of about ``elements`` elements (whole cells of :data:`ELEMENTS_PER_CELL`),
    with the exact relation of every pair within :data:`MARGIN`.

    Parameters
    ----------
    elements : int
        Elements wanted; the building holds ``ceil(elements / 16)`` cells.
    seed : int
        Seed of the GlobalIds.

    Returns
    -------
    Building
    """
    rng = random.Random(seed)

    def new_id() -> str:
        return _compress_guid(uuid.UUID(int=rng.getrandbits(128), version=4).hex)

    cells = max(1, math.ceil(elements / ELEMENTS_PER_CELL))
    side = math.ceil(math.sqrt(cells))
    parts: list[Part] = []
    openings: list[tuple[str, tuple[float, ...], tuple[float, ...]]] = []
    truth: dict[tuple[str, str], Relation] = {}
    for k in range(cells):
        origin = np.array([(k % side) * PITCH, (k // side) * PITCH, 0.0])
        cell, doors = _cell_parts(k, origin, new_id)
        parts += cell
        openings += doors
        for i, a in enumerate(cell):
            for b in cell[i + 1:]:
                box_gap = np.maximum(np.maximum(np.subtract(a.lo, b.hi), np.subtract(b.lo, a.hi)),
                                     0.0)
                if np.linalg.norm(box_gap) >= MARGIN:
                    continue
                rel = relation(a, b)
                if rel.distance < MARGIN:
                    truth[tuple(sorted((a.global_id, b.global_id)))] = rel  # type: ignore[index]
    return Building(parts, truth, openings)


_GUID_CHARS = "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_$"


def _compress_guid(hex_uuid: str) -> str:
    """IFC's 22-character GlobalId of a 32-digit hexadecimal UUID (as
    ``ifcopenshell.guid.compress``)."""
    n = int(hex_uuid, 16)
    out = []
    for _ in range(22):
        out.append(_GUID_CHARS[n % 64])
        n //= 64
    return "".join(reversed(out))


# -- IFC ------------------------------------------------------------------------------------


_IFC2X3_CLASSES = {"IfcPipeSegment": "IfcFlowSegment", "IfcDuctSegment": "IfcFlowSegment"}


def write_ifc(building: Building, path: str | os.PathLike[str], *, schema: str = "IFC4",
              disciplines: Sequence[str] | None = None,
              offset: Sequence[float] = (0.0, 0.0, 0.0)) -> Path:
    """Write the building (or the parts of some disciplines) as an IFC file.

    Boxes are rectangles extruded upwards, cylinders circles extruded along their axis, each
    with its own local placement, in metres, relative to the storey's, which is relative to the
    site's; walls with a door get an IfcOpeningElement that voids them. In IFC2X3, pipe and duct
    segments are IfcFlowSegment. The site is placed at ``offset``: a model in map coordinates,
    every element's coordinates in the file the same as at the origin, its world coordinates
    (what IfcOpenShell's geometry gives every reader) moved by ``offset``.

    Parameters
    ----------
    building : Building
    path : str or path-like
    schema : {"IFC4", "IFC2X3"}
    disciplines : sequence of str, optional
        Only the parts of these (``"architecture"``, ``"structure"``, ``"mep"``).
    offset : (3,) float
        The site's placement, in metres (default: the origin).

    Returns
    -------
    Path
        ``path``.
    """
    ifcopenshell = require("ifcopenshell", "writing the generated building as IFC", "bim")
    f = ifcopenshell.file(schema=schema)
    rng = random.Random(zlib.crc32(os.fsencode(os.fspath(path))))

    def gid() -> str:
        return _compress_guid(uuid.UUID(int=rng.getrandbits(128), version=4).hex)

    def point(*xyz: float) -> Any:
        return f.createIfcCartesianPoint([float(v) for v in xyz])

    def direction(*xyz: float) -> Any:
        return f.createIfcDirection([float(v) for v in xyz])

    owner = None
    if schema == "IFC2X3":
        person = f.createIfcPerson(None, "pycinder", None, None, None, None, None, None)
        org = f.createIfcOrganization(None, "pycinder", None, None, None)
        app = f.createIfcApplication(org, "0", "pycinder", "pycinder")
        owner = f.createIfcOwnerHistory(f.createIfcPersonAndOrganization(person, org, None),
                                        app, None, "ADDED", None, None, None, 0)
    metre = f.createIfcSIUnit(None, "LENGTHUNIT", None, "METRE")
    units = f.createIfcUnitAssignment([metre])
    origin = f.createIfcAxis2Placement3D(point(0, 0, 0), None, None)
    context = f.createIfcGeometricRepresentationContext(None, "Model", 3, 1e-5, origin, None)
    body_context = f.createIfcGeometricRepresentationSubContext(
        "Body", "Model", None, None, None, None, context, None, "MODEL_VIEW", None)
    project = f.createIfcProject(gid(), owner, "pycinder building", None, None, None, None,
                                 [context], units)
    site_place = f.createIfcLocalPlacement(None, f.createIfcAxis2Placement3D(
        point(*offset), None, None))
    site = f.createIfcSite(gid(), owner, "Site", None, None, site_place, None, None, "ELEMENT",
                           None, None, None, None, None)
    building_el = f.createIfcBuilding(gid(), owner, "Building", None, None,
                                      f.createIfcLocalPlacement(site_place, origin), None, None,
                                      "ELEMENT", None, None, None)
    storey_place = f.createIfcLocalPlacement(site_place, origin)
    storey = f.createIfcBuildingStorey(gid(), owner, "Level 0", None, None, storey_place, None,
                                       None, "ELEMENT", 0.0)
    f.createIfcRelAggregates(gid(), owner, None, None, project, [site])
    f.createIfcRelAggregates(gid(), owner, None, None, site, [building_el])
    f.createIfcRelAggregates(gid(), owner, None, None, building_el, [storey])
    z_up, x_dir = direction(0, 0, 1), direction(1, 0, 0)

    def box_shape(lo: Sequence[float], hi: Sequence[float]) -> tuple[Any, Any]:
        size = np.subtract(hi, lo)
        place = f.createIfcLocalPlacement(storey_place, f.createIfcAxis2Placement3D(
            point((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]), z_up, x_dir))
        profile = f.createIfcRectangleProfileDef(
            "AREA", None, f.createIfcAxis2Placement2D(f.createIfcCartesianPoint([0.0, 0.0]), None),
            float(size[0]), float(size[1]))
        solid = f.createIfcExtrudedAreaSolid(profile, f.createIfcAxis2Placement3D(
            point(0, 0, 0), None, None), z_up, float(size[2]))
        return place, solid

    def cyl_shape(p: Part) -> tuple[Any, Any]:
        k = p.axis
        assert k is not None
        c = (np.asarray(p.lo) + np.asarray(p.hi)) / 2
        c[k] = p.lo[k]
        axis = [0.0, 0.0, 0.0]
        axis[k] = 1.0
        ref = [0.0, 0.0, 1.0] if k != 2 else [1.0, 0.0, 0.0]
        place = f.createIfcLocalPlacement(storey_place, f.createIfcAxis2Placement3D(
            point(*c), direction(*axis), direction(*ref)))
        profile = f.createIfcCircleProfileDef(
            "AREA", None, f.createIfcAxis2Placement2D(f.createIfcCartesianPoint([0.0, 0.0]), None),
            float(p.radius))
        solid = f.createIfcExtrudedAreaSolid(profile, f.createIfcAxis2Placement3D(
            point(0, 0, 0), None, None), z_up, float(p.hi[k] - p.lo[k]))
        return place, solid

    def shape(solid: Any) -> Any:
        rep = f.createIfcShapeRepresentation(body_context, "Body", "SweptSolid", [solid])
        return f.createIfcProductDefinitionShape(None, None, [rep])

    wanted = set(disciplines) if disciplines is not None else None
    elements = {}
    contained = []
    for p in building.parts:
        if wanted is not None and p.discipline not in wanted:
            continue
        place, solid = cyl_shape(p) if p.is_cylinder else box_shape(p.lo, p.hi)
        cls = _IFC2X3_CLASSES.get(p.ifc_class, p.ifc_class) if schema == "IFC2X3" else p.ifc_class
        el = f.create_entity(cls, GlobalId=p.global_id, OwnerHistory=owner, Name=p.name,
                             ObjectPlacement=place, Representation=shape(solid))
        elements[p.global_id] = el
        contained.append(el)
    for wall_id, lo, hi in building.openings:
        if wall_id not in elements:
            continue
        place, solid = box_shape(lo, hi)
        opening = f.create_entity("IfcOpeningElement", GlobalId=gid(), OwnerHistory=owner,
                                  Name="Door opening", ObjectPlacement=place,
                                  Representation=shape(solid))
        f.createIfcRelVoidsElement(gid(), owner, None, None, elements[wall_id], opening)
    if contained:
        f.createIfcRelContainedInSpatialStructure(gid(), owner, None, None, contained, storey)
    path = Path(path)
    f.write(str(path))
    return path


DISCIPLINES = ("architecture", "structure", "mep")


def write_federated(building: Building, folder: str | os.PathLike[str], *,
                    schema: str = "IFC4", offset: Sequence[float] = (0.0, 0.0, 0.0)
                    ) -> list[Path]:
    """Write the building as three files, ``architecture.ifc`` (walls, slabs),
    ``structure.ifc`` (columns, beams) and ``mep.ifc`` (pipe and duct segments), in
    ``folder``, each with its site at ``offset`` (see :func:`write_ifc`); returns their
    paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return [write_ifc(building, folder / f"{d}.ifc", schema=schema, disciplines=[d],
                      offset=offset) for d in DISCIPLINES]

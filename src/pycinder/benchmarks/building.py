"""A generated IFC building with exact truth, and the ``building`` benchmark against IfcClash.

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

``python -m pycinder.benchmarks.building --elements 3000`` runs the benchmark and prints its
Markdown (``pycinder bench building`` runs 3,000 and 20,000 elements and writes its JSON).
"""

from __future__ import annotations

import argparse
import math
import os
import random
import sys
import tempfile
import time
import uuid
import warnings
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
              disciplines: Sequence[str] | None = None) -> Path:
    """Write the building (or the parts of some disciplines) as an IFC file.

    Boxes are rectangles extruded upwards, cylinders circles extruded along their axis, each
    with its own local placement, in metres; walls with a door get an IfcOpeningElement that
    voids them. In IFC2X3, pipe and duct segments are IfcFlowSegment.

    Parameters
    ----------
    building : Building
    path : str or path-like
    schema : {"IFC4", "IFC2X3"}
    disciplines : sequence of str, optional
        Only the parts of these (``"architecture"``, ``"structure"``, ``"mep"``).

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
    site_place = f.createIfcLocalPlacement(None, origin)
    site = f.createIfcSite(gid(), owner, "Site", None, None, site_place, None, None, "ELEMENT",
                           None, None, None, None, None)
    building_el = f.createIfcBuilding(gid(), owner, "Building", None, None,
                                      f.createIfcLocalPlacement(site_place, origin), None, None,
                                      "ELEMENT", None, None, None)
    storey = f.createIfcBuildingStorey(gid(), owner, "Level 0", None, None,
                                       f.createIfcLocalPlacement(site_place, origin), None, None,
                                       "ELEMENT", 0.0)
    f.createIfcRelAggregates(gid(), owner, None, None, project, [site])
    f.createIfcRelAggregates(gid(), owner, None, None, site, [building_el])
    f.createIfcRelAggregates(gid(), owner, None, None, building_el, [storey])
    z_up, x_dir = direction(0, 0, 1), direction(1, 0, 0)

    def box_shape(lo: Sequence[float], hi: Sequence[float]) -> tuple[Any, Any]:
        size = np.subtract(hi, lo)
        place = f.createIfcLocalPlacement(None, f.createIfcAxis2Placement3D(
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
        place = f.createIfcLocalPlacement(None, f.createIfcAxis2Placement3D(
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
                    schema: str = "IFC4") -> list[Path]:
    """Write the building as three files, ``architecture.ifc`` (walls, slabs),
    ``structure.ifc`` (columns, beams) and ``mep.ifc`` (pipe and duct segments), in
    ``folder``; returns their paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return [write_ifc(building, folder / f"{d}.ifc", schema=schema, disciplines=[d])
            for d in DISCIPLINES]


# -- the benchmark --------------------------------------------------------------------------

DEPTH = 0.01
"""``min_depth`` of the hard-clash runs, and IfcClash's intersection tolerance (metres)."""
CLEARANCE = 0.05
"""``clearance`` of the clearance runs (metres)."""


def score(building: Building, reported: set[tuple[str, str]], mode: str,
          depth: float = DEPTH, clearance: float = CLEARANCE) -> dict[str, Any]:
    """Score reported pairs (sorted GlobalIds) against the truth.

    Parameters
    ----------
    building : Building
    reported : set of (str, str)
    mode : {"default", "min_depth", "clearance", "intersection", "collision"}
        What the pairs answer: the hard-clash modes must find every pair deeper than ``depth``
        and never one at most ``depth / 2`` deep; clearance every pair closer than
        ``clearance`` and never one farther than ``clearance * 9 / 8``; the default and
        IfcClash's collision mode every overlap deeper than ``depth``.

    Returns
    -------
    dict
        ``must`` (pairs that must be found), ``found`` (of those), ``recall``, ``touching``
        (touching pairs reported), ``grazes`` (pairs at most ``depth / 2`` deep, touching
        excluded, reported), ``near`` (pairs apart but within the margin, reported),
        ``false`` (pairs that must not be reported, reported: for the hard-clash modes pairs
        apart, touching or at most ``depth / 2`` deep; for clearance, pairs farther than
        ``clearance * 9 / 8``; for the default pairs apart), ``reported``.
    """
    truth = building.truth
    if mode == "clearance":
        must = {k for k, r in truth.items() if r.distance < clearance - r.error}
        never = lambda r: r.distance > clearance * 9 / 8 + r.error  # noqa: E731
    else:
        must = {k for k, r in truth.items() if r.depth > depth + r.error}
        if mode in ("min_depth", "intersection"):
            never = lambda r: r.depth <= depth / 2 - r.error  # noqa: E731
        else:
            never = lambda r: r.distance > r.error  # noqa: E731
    false = 0
    touching = grazes = near = 0
    for k in reported:
        r = truth.get(k)
        if r is None:  # at least MARGIN apart
            false += 1
            continue
        kind = r.kind
        touching += kind == "touching"
        near += kind == "near"
        grazes += 0 < r.depth <= depth / 2
        false += bool(never(r))
    found = len(must & reported)
    return {"must": len(must), "found": found,
            "recall": found / len(must) if must else 1.0, "touching": touching,
            "grazes": grazes, "near": near, "false": false, "reported": len(reported)}


def _pycinder_runs(paths: Sequence[Path], building: Building,
                   say: Callable[[str], None]) -> list[dict[str, Any]]:
    from ..bim import ifc

    rows = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as cache:
        model = ifc.read_ifc(paths, cache=cache)
    tess = time.perf_counter() - t0
    modes: list[tuple[str, dict[str, float]]] = [
        ("default", {}), ("min_depth", {"min_depth": DEPTH}),
        ("clearance", {"clearance": CLEARANCE})]
    for mode, options in modes:
        say(f"building: pycinder {mode}, {len(model.bodies):,} elements")
        t0 = time.perf_counter()
        clashes = ifc.find_clashes(model, **options)  # type: ignore[arg-type]
        clash_s = time.perf_counter() - t0
        reported = {tuple(sorted((c.a.global_id, c.b.global_id))) for c in clashes}
        row = {"system": "pycinder", "mode": mode, "tessellation_s": tess, "clash_s": clash_s}
        row.update(score(building, reported, mode))  # type: ignore[arg-type]
        row.update(group_counts(clashes))
        if mode == "min_depth":
            row.update(check_depths(building, clashes))
        rows.append(row)
    return rows


def group_counts(clashes: Sequence[Any]) -> dict[str, int]:
    """How many groups the clashes form (:func:`pycinder.bim.groups.group_clashes`): ``groups``
    at the default distance, ``groups_by_element`` by element alone."""
    from ..bim.groups import group_clashes as group

    return {"groups": len(group(clashes)), "groups_by_element": len(group(clashes, 0))}


def check_depths(building: Building, clashes: Sequence[Any]) -> dict[str, Any]:
    """Each hard clash's depth against the exact truth.

    Parameters
    ----------
    building : Building
    clashes : sequence of Clash
        From :func:`pycinder.bim.ifc.find_clashes` with ``min_depth``.

    Returns
    -------
    dict
        ``depths_checked`` (clashes whose pair is in the truth), ``depths_outside`` (of those,
        clashes whose depth is farther from the true depth than the two bounds together: the
        clash's :attr:`~pycinder.bim.ifc.Clash.depth_error` and the tessellation's
        :attr:`Relation.error`) and ``depth_worst`` (the largest difference from the true
        depth, in metres; 0 with nothing checked).
    """
    checked = outside = 0
    worst = 0.0
    for c in clashes:
        r = building.truth.get(tuple(sorted((c.a.global_id, c.b.global_id))))
        if r is None or c.depth is None:
            continue
        checked += 1
        off = abs(c.depth - r.depth)
        worst = max(worst, off)
        outside += off > (c.depth_error or 0.0) + r.error
    return {"depths_checked": checked, "depths_outside": outside, "depth_worst": worst}


def _ifcclash_runs(paths: Sequence[Path], building: Building,
                   say: Callable[[str], None]) -> list[dict[str, Any]]:
    """IfcClash's own steps (:class:`ifcclash.Clasher`): its iterator fills one tree
    (tessellation), then each mode clashes the elements against themselves."""
    ifcopenshell = require("ifcopenshell", "the building benchmark", "bim")
    import ifcopenshell.geom
    import logging
    try:
        from ifcclash.ifcclash import Clasher, ClashSettings
    except ImportError as exc:
        raise ImportError("the building benchmark's IfcClash runs need ifcclash: pip install "
                          "ifcclash") from exc
    settings = ClashSettings()
    settings.logger = logging.getLogger("ifcclash")
    clasher = Clasher(settings)
    t0 = time.perf_counter()
    clasher.tree = ifcopenshell.geom.tree(backend="opencascade.trianglebvh")
    clasher.create_group("a")
    for p in paths:
        clasher.add_collision_objects("a", clasher.load_ifc(str(p)), {"file": str(p)})
    tess = time.perf_counter() - t0
    elements = list(clasher.groups["a"]["elements"].values())
    rows = []
    runs = [("intersection", lambda: clasher.tree.clash_intersection_many(
                elements, elements, tolerance=DEPTH, check_all=True)),
            ("collision", lambda: clasher.tree.clash_collision_many(
                elements, elements, allow_touching=False)),
            ("clearance", lambda: clasher.tree.clash_clearance_many(
                elements, elements, clearance=CLEARANCE, check_all=True))]
    for mode, call in runs:
        say(f"building: IfcClash {mode}, {len(elements):,} elements")
        t0 = time.perf_counter()
        results = call()
        clash_s = time.perf_counter() - t0
        reported = {tuple(sorted((r.a.GlobalId, r.b.GlobalId))) for r in results
                    if r.a.GlobalId != r.b.GlobalId}
        row = {"system": "IfcClash", "mode": mode, "tessellation_s": tess, "clash_s": clash_s}
        row.update(score(building, reported, mode))
        rows.append(row)
    return rows


def run_building(sizes: Sequence[int] = (3000, 20000), *,
                 progress: Callable[[str], None] | None = None,
                 peers: bool = True) -> dict[str, Any]:
    """The building benchmark: each size generated, written as three IFC4 files, read and
    checked by pycinder in each mode and by IfcClash in each of its modes, in the same run.

    Returns
    -------
    dict
        ``rows`` (one per size, system and mode: :func:`score`'s figures, ``tessellation_s``
        and ``clash_s``), ``sizes`` (per size: elements, triangles, truth counts),
        ``left_out`` (IfcClash's reason, when it could not run), ``depth``, ``clearance``.
    """
    say = progress or (lambda msg: None)
    out: dict[str, Any] = {"depth": DEPTH, "clearance": CLEARANCE, "rows": [], "sizes": [],
                           "left_out": {}}
    for n in sizes:
        say(f"building: generating {n:,} elements")
        building = generate(n)
        with tempfile.TemporaryDirectory() as folder:
            paths = write_federated(building, folder)
            rows = _pycinder_runs(paths, building, say)
            if peers:
                try:
                    rows += _ifcclash_runs(paths, building, say)
                except ImportError as exc:
                    out["left_out"]["IfcClash"] = str(exc)
        for row in rows:
            row["elements"] = len(building.parts)
        out["rows"] += rows
        out["sizes"].append({"elements": len(building.parts), "truth": building.counts()})
    from ..gpu.device import get_gpu

    out["adapter"] = get_gpu().description
    return out


def markdown(r: dict[str, Any]) -> list[str]:
    """The report's section for the building benchmark."""
    lines = ["## Building: IFC in, clash modes, against IfcClash", "",
             f"Adapter: {r.get('adapter', '?')}. Hard-clash depth d = {r['depth'] * 1000:g} mm "
             f"(IfcClash's intersection tolerance), clearance c = {r['clearance'] * 1000:g} mm. "
             "Generated IFC4 buildings, three federated files, exact truth "
             "(`pycinder.benchmarks.building`).", ""]
    for s in r["sizes"]:
        counts = ", ".join(f"{v:,} {k}" for k, v in sorted(s["truth"].items()))
        lines.append(f"- {s['elements']:,} elements; pairs within 0.2 m: {counts}")
    lines += ["", "| elements | system | mode | must find | found | recall | touching reported | "
              "grazes (<= d/2) reported | near reported | false | reported | tessellation s | "
              "clash s |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in r["rows"]:
        lines.append(
            f"| {row['elements']:,} | {row['system']} | {row['mode']} | {row['must']:,} | "
            f"{row['found']:,} | {row['recall']:.1%} | {row['touching']:,} | {row['grazes']:,} | "
            f"{row['near']:,} | {row['false']:,} | {row['reported']:,} | "
            f"{row['tessellation_s']:.1f} | {row['clash_s']:.1f} |")
    for name, why in r.get("left_out", {}).items():
        lines += ["", f"{name} was left out: {why}"]
    lines += [""] + [f"- pycinder {row['mode']}, {row['elements']:,} elements: {row['reported']:,}"
                     f" clashes; groups: {row['groups']:,} within 3 m, "
                     f"{row['groups_by_element']:,} by element" for row in r["rows"]
                     if "groups" in row]
    for row in r["rows"]:
        if "depths_checked" in row:
            lines += ["", f"pycinder min_depth, {row['elements']:,} elements: "
                          f"{row['depths_checked']:,} depths checked against the truth, "
                          f"{row['depths_outside']:,} outside their error bounds, largest "
                          f"difference {row['depth_worst'] * 1000:.3g} mm."]
    lines += ["", "must find: for default, min_depth and IfcClash's intersection and collision "
              "modes, the pairs deeper than d; for clearance, the pairs closer than c. false: "
              "pairs reported that the mode must never report (apart for the default and "
              "collision; apart, touching or at most d/2 deep for the hard-clash modes; farther "
              "than 9c/8 for clearance). The default mode promises only its tolerance contract "
              "(pairs at least t apart never reported, pairs at least 2t deep always, t = 1% of "
              "the smaller body's size): touching pairs may go either way."]
    return lines + [""]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m pycinder.benchmarks.building",
                                     description="The building benchmark, as Markdown.")
    parser.add_argument("--elements", type=int, nargs="+", default=[3000])
    parser.add_argument("--no-ifcclash", action="store_true")
    parser.add_argument("--out", default=None, help="write the Markdown here too")
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = run_building(args.elements, peers=not args.no_ifcclash,
                         progress=lambda m: print(m, file=sys.stderr, flush=True))
    text = "\n".join(markdown(r))
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""A robot arm from its URDF: collision meshes and forward kinematics, for batches of poses.

A small URDF reader (links' collision geometry, joints: fixed, revolute, continuous, prismatic,
with mimic joints) and forward kinematics vectorised over configurations:

    urdf -> links (collision meshes, closed) + joints (tree order)
    configurations (C, J) -> world transform of every collision body (C, B, 4, 4)

The arm of the benchmarks is the Franka Emika Panda as pybullet ships it (``pybullet_data``,
the ``bench`` extra): 11 collision meshes of 32 to 1,308 triangles. One of them, ``link6.obj``,
is open (586 boundary edges); it is replaced by its convex hull, for every system alike.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from ..optional import require

JOINT_TYPES = ("fixed", "revolute", "continuous", "prismatic")


def _floats(text: str | None, default: tuple[float, ...]) -> np.ndarray:
    return np.array([float(x) for x in text.split()] if text else default, dtype=np.float64)


def origin_matrix(element: ET.Element | None) -> np.ndarray:
    """(4, 4) transform of a URDF ``<origin xyz=".." rpy=".."/>`` (identity when absent)."""
    if element is None:
        return np.eye(4)
    x, y, z = _floats(element.get("xyz"), (0.0, 0.0, 0.0))
    roll, pitch, yaw = _floats(element.get("rpy"), (0.0, 0.0, 0.0))
    m = trimesh.transformations.euler_matrix(roll, pitch, yaw, "sxyz")
    m[:3, 3] = (x, y, z)
    return m


@dataclass
class Joint:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float = 0.0
    upper: float = 0.0
    mimic: tuple[str, float, float] | None = None
    """(joint, multiplier, offset): this joint's value follows another's."""


@dataclass
class Body:
    """One collision element: a closed mesh in its link's frame."""

    link: str
    mesh: trimesh.Trimesh
    origin: np.ndarray
    source: str
    repaired: str = ""


@dataclass
class Robot:
    """Links, joints in tree order from the root, and collision bodies."""

    name: str
    root: str
    joints: list[Joint]
    bodies: list[Body]
    actuated: list[str] = field(default_factory=list)

    @property
    def limits(self) -> np.ndarray:
        """(J, 2) lower and upper limits of the actuated joints."""
        by_name = {j.name: j for j in self.joints}
        return np.array([(by_name[n].lower, by_name[n].upper) for n in self.actuated])

    def random_configurations(self, count: int, seed: int = 0) -> np.ndarray:
        """(count, J) configurations drawn uniformly within the joint limits."""
        lim = self.limits
        return np.random.default_rng(seed).uniform(lim[:, 0], lim[:, 1], (count, len(lim)))

    def link_transforms(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """World from link, (C, 4, 4) for each link, for configurations ``q`` (C, J)."""
        q = np.atleast_2d(np.asarray(q, dtype=np.float64))
        if q.shape[1] != len(self.actuated):
            raise ValueError(f"{self.name}: configurations need {len(self.actuated)} joint "
                             f"values ({', '.join(self.actuated)}), got {q.shape[1]}")
        values = {n: q[:, k] for k, n in enumerate(self.actuated)}
        world = {self.root: np.tile(np.eye(4), (len(q), 1, 1))}
        for j in self.joints:
            if j.mimic is not None:
                other, multiplier, offset = j.mimic
                value = values[other] * multiplier + offset
            else:
                value = values.get(j.name, np.zeros(len(q)))
            motion = np.tile(np.eye(4), (len(q), 1, 1))
            if j.type in ("revolute", "continuous"):
                motion[:, :3, :3] = _axis_rotations(j.axis, value)
            elif j.type == "prismatic":
                motion[:, :3, 3] = value[:, None] * j.axis
            world[j.child] = world[j.parent] @ j.origin @ motion
        return world

    def poses(self, q: np.ndarray) -> np.ndarray:
        """(C, B, 4, 4) world transform of every collision body for configurations (C, J)."""
        links = self.link_transforms(q)
        return np.stack([links[b.link] @ b.origin for b in self.bodies], axis=1)


def _axis_rotations(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(C, 3, 3) rotations by ``angle`` (C,) about the unit ``axis`` (Rodrigues)."""
    k = axis / np.linalg.norm(axis)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * cross + (1 - c) * (cross @ cross)


def closed_mesh(path: Path, scale: np.ndarray | None = None) -> tuple[trimesh.Trimesh, str]:
    """A mesh file read as one closed solid: vertices merged (OBJ files split them by normal
    and texture coordinate); a mesh that is still open is replaced by its convex hull, and
    the second value says so."""
    mesh = trimesh.load(path, force="mesh", process=False)
    mesh = trimesh.Trimesh(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces))
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    if scale is not None:
        mesh.apply_scale(scale)
    if mesh.is_volume:
        return mesh, ""
    return mesh.convex_hull, "open mesh replaced by its convex hull"


def _mesh_path(filename: str, base: Path) -> Path:
    """A URDF mesh file name resolved against the URDF's folder (``package://`` URIs by their
    path, dropping leading folders until the file is found)."""
    rel = filename.split("://", 1)[1] if "://" in filename else filename
    parts = Path(rel).parts
    for k in range(len(parts)):
        candidate = base.joinpath(*parts[k:])
        if candidate.exists():
            return candidate
    raise FileNotFoundError(f"{filename}: not found under {base}")


def load_urdf(path: str | Path) -> Robot:
    """Read a URDF's links (collision meshes, boxes, spheres, cylinders) and joints."""
    path = Path(path)
    root_el = ET.parse(path).getroot()
    joints, children = [], set()
    for el in root_el.findall("joint"):
        kind = el.get("type", "")
        if kind not in JOINT_TYPES:
            raise ValueError(f"{path.name}: joint {el.get('name')!r} is {kind!r}; supported: "
                             f"{', '.join(JOINT_TYPES)}")
        limit = el.find("limit")
        mimic = el.find("mimic")
        axis = el.find("axis")
        joints.append(Joint(
            el.get("name", ""), kind, el.find("parent").get("link"), el.find("child").get("link"),
            origin_matrix(el.find("origin")),
            _floats(axis.get("xyz") if axis is not None else None, (1.0, 0.0, 0.0)),
            float(limit.get("lower", 0.0)) if limit is not None else -np.pi,
            float(limit.get("upper", 0.0)) if limit is not None else np.pi,
            (mimic.get("joint"), float(mimic.get("multiplier", 1.0)),
             float(mimic.get("offset", 0.0))) if mimic is not None else None))
        children.add(joints[-1].child)
    links = [el.get("name") for el in root_el.findall("link")]
    roots = [n for n in links if n not in children]
    if len(roots) != 1:
        raise ValueError(f"{path.name}: expected one root link, found {roots}")
    # Joints in tree order: a joint after the joint that places its parent.
    ordered, placed, rest = [], {roots[0]}, list(joints)
    while rest:
        ready = [j for j in rest if j.parent in placed]
        if not ready:
            raise ValueError(f"{path.name}: joints not connected to the root: "
                             f"{[j.name for j in rest]}")
        for j in ready:
            ordered.append(j)
            placed.add(j.child)
            rest.remove(j)
    bodies, meshes = [], {}
    for el in root_el.findall("link"):
        for col in el.findall("collision"):
            body = _collision_body(col, el.get("name"), path.parent, meshes)
            if body is not None:
                bodies.append(body)
    actuated = [j.name for j in ordered if j.type != "fixed" and j.mimic is None]
    return Robot(root_el.get("name", path.stem), roots[0], ordered, bodies, actuated)


def _collision_body(col: ET.Element, link: str, base: Path,
                    meshes: dict[tuple, tuple[trimesh.Trimesh, str]]) -> Body | None:
    """A link's collision element as a closed mesh; mesh files read once (``meshes``)."""
    geom = col.find("geometry")
    origin = origin_matrix(col.find("origin"))
    if geom is None or len(geom) == 0:
        return None
    g = geom[0]
    if g.tag == "mesh":
        scale = _floats(g.get("scale"), (1.0, 1.0, 1.0))
        file = _mesh_path(g.get("filename", ""), base)
        key = (str(file), tuple(scale))
        if key not in meshes:
            meshes[key] = closed_mesh(file, scale)
        mesh, repaired = meshes[key]
        return Body(link, mesh, origin, str(file), repaired)
    if g.tag == "box":
        mesh = trimesh.creation.box(_floats(g.get("size"), (1.0, 1.0, 1.0)))
    elif g.tag == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=float(g.get("radius")))
    elif g.tag == "cylinder":
        mesh = trimesh.creation.cylinder(radius=float(g.get("radius")),
                                         height=float(g.get("length")), sections=32)
    else:
        raise ValueError(f"link {link!r}: unsupported collision geometry <{g.tag}>")
    return Body(link, mesh, origin, g.tag)


def panda() -> Robot:
    """The Franka Emika Panda of ``pybullet_data`` (the ``bench`` extra brings pybullet)."""
    data = require("pybullet_data", "the robot benchmark's Panda arm", "bench", "pybullet")
    return load_urdf(Path(data.getDataPath()) / "franka_panda" / "panda.urdf")


def write_meshes(robot: Robot, folder: str | Path) -> list[str]:
    """Each collision body's closed mesh as a PLY file in ``folder``; paths in body order (bodies
    sharing a mesh file share one output)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths, written = [], {}
    for b in robot.bodies:
        if id(b.mesh) not in written:
            out = folder / f"{robot.name}-{len(written)}-{Path(b.source).stem}.ply"
            b.mesh.export(out)
            written[id(b.mesh)] = str(out)
        paths.append(written[id(b.mesh)])
    return paths

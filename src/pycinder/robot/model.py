"""A robot as its URDF gives it: links, joints in tree order, collision bodies, fixed
environment bodies, and forward kinematics vectorised over configurations in NumPy
(:class:`RobotModel`; :class:`~pycinder.robot.robot.Robot` adds the checks)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

import numpy as np
import trimesh

from ..util.optional import require
from .acm import AllowedCollisionMatrix, _text_of

if TYPE_CHECKING:
    from ..detector import Detector

JOINT_TYPES = ("fixed", "revolute", "continuous", "prismatic")
SPHERE_SUBDIVISIONS = 3
CYLINDER_SECTIONS = 32


@dataclass
class Body:
    """One collision body: a mesh fixed to a link (or to the world, in an environment).

    Attributes
    ----------
    name : str
        The body's name in results: its link's name (``link/k`` for a link's k-th further
        collision element), an attached object's or an environment body's name.
    link : str
        The link it moves with (an environment body's own name).
    mesh : trimesh.Trimesh
        Body coordinates.
    origin : (4, 4) float
        Link from body (world from body in an environment).
    source : str
        Where it came from: a mesh file, or ``box``, ``cylinder``, ``sphere``.
    """

    name: str
    link: str
    mesh: trimesh.Trimesh
    origin: np.ndarray
    source: str = ""


@dataclass
class _Joint:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float
    mimic: tuple[str, float, float] | None = None


@dataclass
class _Attached:
    body: Body
    touch: frozenset[str]


# ---------------------------------------------------------------------------------------------
# Environment


class Environment:
    """Fixed bodies around a robot (a table, a shelf): meshes with world transforms.

    Parameters
    ----------
    bodies : iterable of (name, mesh) or (name, mesh, transform (4, 4)), optional

    Examples
    --------
    >>> import numpy as np, trimesh
    >>> from pycinder.robot import Environment
    >>> table = np.eye(4); table[2, 3] = -0.05
    >>> env = Environment([("table", trimesh.creation.box((1.0, 1.0, 0.1)), table)])
    >>> env.names
    ['table']
    """

    def __init__(self, bodies: Iterable[Sequence[Any]] = ()) -> None:
        self.bodies: list[Body] = []
        for b in bodies:
            self.add(*b)

    @property
    def names(self) -> list[str]:
        return [b.name for b in self.bodies]

    def __len__(self) -> int:
        return len(self.bodies)

    def add(self, name: str, mesh: Any, transform: Any = None) -> None:
        """Add a body: ``mesh`` (a Trimesh or (vertices, faces)) at world ``transform``."""
        if name in self.names:
            raise ValueError(f"the environment already has a body named {name!r}")
        t = _checked_transform(transform, f"environment body {name!r}")
        self.bodies.append(Body(name, name, _as_trimesh(mesh, name), t, "mesh"))

    @classmethod
    def from_urdf(cls, path: str | Path, transform: Any = None, *, prefix: str | None = None,
                  package_dirs: Any = None) -> Environment:
        """The collision bodies of a URDF object (pybullet_data's ``table/table.urdf``), placed
        at ``transform`` in its default configuration; names are ``prefix/link`` (prefix:
        the file's stem)."""
        robot = RobotModel.from_urdf(path, package_dirs=package_dirs)
        env = cls()
        place = np.eye(4) if transform is None else np.asarray(transform, np.float64)
        poses = robot.poses(robot.default_configuration()[None])[0]
        prefix = Path(path).stem if prefix is None else prefix
        for b, pose in zip(robot.bodies, poses):
            env.add(f"{prefix}/{b.name}", b.mesh, place @ pose)
        return env


def _checked_transform(transform: Any, what: str) -> np.ndarray:
    """A (4, 4) float64 transform (None: the identity), checked as a query's transforms are
    (finite, affine, not singular, within range: :func:`pycinder.scene.bodies.check_transforms`),
    so that every check may take it as it is; a ValueError names ``what``."""
    from ..scene.bodies import check_transforms

    t = np.eye(4) if transform is None else np.asarray(transform, np.float64)
    if t.shape != (4, 4):
        raise ValueError(f"{what}: transform must be a (4, 4) matrix, got shape {t.shape}")
    try:
        return check_transforms(t[None], 1, [what])[0]
    except ValueError as exc:
        raise ValueError(f"{what}: {str(exc).split(': ', 1)[-1]}") from None


def _as_trimesh(mesh: Any, name: str) -> trimesh.Trimesh:
    if isinstance(mesh, trimesh.Trimesh):
        return mesh
    try:
        v, f = mesh
        return trimesh.Trimesh(np.asarray(v, np.float64), np.asarray(f, np.int64), process=False)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"body {name!r}: expected a trimesh.Trimesh or (vertices (V, 3), "
                         f"faces (F, 3)), got {type(mesh).__name__} ({exc})") from None


# ---------------------------------------------------------------------------------------------
# The robot


@dataclass
class RobotModel:
    """A robot's links, joints and collision bodies, and its forward kinematics: what
    :class:`~pycinder.robot.Robot` (which adds the checks) is made of. See
    :class:`~pycinder.robot.Robot` for the attributes."""

    name: str
    root: str
    links: list[str]
    joints: list[_Joint]
    bodies: list[Body]
    joint_names: list[str]
    limits: np.ndarray
    allowed: AllowedCollisionMatrix = field(default_factory=AllowedCollisionMatrix)
    tolerance: float | None = None
    source: str = ""
    _attached: dict[str, _Attached] = field(default_factory=dict, repr=False)
    _detector: Any = field(default=None, repr=False)
    _padded: dict = field(default_factory=dict, repr=False)
    _plans: dict = field(default_factory=dict, repr=False)
    _kinematics: Any = field(default=None, repr=False)
    _warned_always: set = field(default_factory=set, repr=False)

    def __post_init__(self) -> None:
        self._link_index = {n: k for k, n in enumerate(self.links)}
        self._prepare_kinematics()

    # -- loading --------------------------------------------------------------------------

    @classmethod
    def from_urdf(cls, path: str | Path, *, srdf: str | Path | None = None,
                  package_dirs: str | Path | Sequence[str | Path] | dict[str, str | Path] |
                  None = None, convex_hull: bool | str = False, tolerance: float | None = None,
                  detector: Detector | None = None) -> Self:
        """Read a robot from a URDF file (parsed by yourdfpy).

        Parameters
        ----------
        path : str or Path
            The URDF file.
        srdf : str or Path, optional
            An SRDF whose ``<disable_collisions>`` pairs become :attr:`allowed`, as given.
        package_dirs : path, sequence of paths, or dict of package name to path, optional
            Where ``package://name/...`` mesh files are: a dict maps package names to folders;
            a folder holds packages as sub-folders (or is the package itself). Always searched
            last: the URDF's folder, dropping leading folders of the mesh path until found.
        convex_hull : bool or "open"
            False (default): meshes as they are, open ones tested as surfaces. True: every mesh
            replaced by its convex hull; "open": only meshes that are not closed.
        tolerance : float, optional
            World units of the tolerance contract for the checks (default: 1% of the smaller
            body's size, per pair).
        detector : Detector, optional
            The detector of the checks (default: one made on first use, ``records="none"``,
            ``broad_phase="numpy"``).

        Returns
        -------
        Robot

        Raises
        ------
        FileNotFoundError
            The URDF, or a mesh file (naming the link).
        ValueError
            A joint type that is not fixed, revolute, continuous or prismatic, a broken tree,
            an unreadable mesh or a bad primitive, naming the joint or link and the file.
        """
        yourdfpy = require("yourdfpy", "pycinder.robot: reading URDF files", "robot")
        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(f"{path}: no such URDF file")
        if convex_hull not in (False, True, "open"):
            raise ValueError(f"convex_hull must be False, True or 'open', got {convex_hull!r}")
        if tolerance is not None:
            from ..request import CollisionRequest

            tolerance = CollisionRequest(tolerance=tolerance).tolerance  # checked once
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                urdf = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False,
                                          load_collision_meshes=False,
                                          build_collision_scene_graph=False)
            except Exception as exc:  # yourdfpy raises a variety of errors on bad files
                raise ValueError(f"{path.name}: could not be read as URDF: {exc}") from None
        model = urdf.robot
        joints = [_joint(j, path.name) for j in model.joints]
        links = [link.name for link in model.links]
        children = {j.child for j in joints}
        roots = [n for n in links if n not in children]
        if len(roots) != 1:
            raise ValueError(f"{path.name}: expected one root link, found {roots}")
        ordered, placed, rest = [], {roots[0]}, list(joints)
        while rest:
            ready = [j for j in rest if j.parent in placed]
            if not ready:
                raise ValueError(f"{path.name}: joints not connected to the root link "
                                 f"{roots[0]!r}: {[j.name for j in rest]}")
            for j in ready:
                ordered.append(j)
                placed.add(j.child)
                rest.remove(j)
        link_order = [roots[0]] + [j.child for j in ordered]
        names = {j.name for j in ordered}
        for j in ordered:
            if j.mimic is not None and j.mimic[0] not in names:
                raise ValueError(f"{path.name}: joint {j.name!r} mimics {j.mimic[0]!r}, which "
                                 "the file does not have")
        actuated = [j for j in ordered if j.type != "fixed" and j.mimic is None]
        resolver = _MeshFiles(path, package_dirs)
        bodies: list[Body] = []
        meshes: dict[tuple, trimesh.Trimesh] = {}
        by_name = {link.name: link for link in model.links}
        for name in link_order:
            for k, col in enumerate(by_name[name].collisions):
                body = _collision_body(col, name, k, resolver, meshes, convex_hull)
                if body is not None:
                    bodies.append(body)
        robot = cls(model.name or path.stem, roots[0], link_order, ordered, bodies,
                    [j.name for j in actuated],
                    np.array([(j.lower, j.upper) for j in actuated], np.float64).reshape(-1, 2),
                    tolerance=tolerance, source=path.name)
        robot._detector = detector
        if srdf is not None:
            robot.allowed = AllowedCollisionMatrix.from_srdf(srdf)
            robot._check_names(robot.allowed, _text_of(srdf)[1] if not (
                isinstance(srdf, str) and srdf.lstrip().startswith("<")) else "SRDF text")
        return robot

    def _check_names(self, acm: AllowedCollisionMatrix, where: str) -> None:
        known = set(self.links) | set(self._attached)
        for a, b, _ in acm.pairs():
            for n in (a, b):
                if n not in known:
                    raise ValueError(f"{where}: <disable_collisions> names {n!r}, which is not "
                                     f"a link of {self.source or self.name}")

    # -- kinematics -----------------------------------------------------------------------

    def _prepare_kinematics(self) -> None:
        index = {n: k for k, n in enumerate(self.joint_names)}
        self._kin = []
        for j in self.joints:
            if j.mimic is not None:
                src = j.mimic[0]
                # a mimic of a mimic: follow the chain to an actuated joint
                mult, off = j.mimic[1], j.mimic[2]
                seen = {j.name}
                by = {x.name: x for x in self.joints}
                while src not in index:
                    other = by[src]
                    if other.mimic is None or src in seen:
                        break
                    seen.add(src)
                    mult, off, src = mult * other.mimic[1], mult * other.mimic[2] + off, \
                        other.mimic[0]
                col = index.get(src, -1)
            else:
                col, mult, off = index.get(j.name, -1), 1.0, 0.0
            self._kin.append((self._link_index[j.parent], self._link_index[j.child], col,
                              mult, off))
        self._body_link = np.array([self._link_index[b.link] for b in self.bodies], np.int64)
        self._body_origin = np.array([b.origin for b in self.bodies]).reshape(-1, 4, 4)

    @property
    def dof(self) -> int:
        """Joint values per configuration."""
        return len(self.joint_names)

    def default_configuration(self) -> np.ndarray:
        """(J,) MoveIt's default values: 0 where the limits allow it, else their middle."""
        lo, hi = self.limits[:, 0], self.limits[:, 1]
        return np.where((lo <= 0) & (hi >= 0), 0.0, 0.5 * (lo + hi))

    def random_configurations(self, count: int, seed: int = 0) -> np.ndarray:
        """(count, J) configurations drawn uniformly within the joint limits."""
        rng = np.random.default_rng(seed)
        return rng.uniform(self.limits[:, 0], self.limits[:, 1], (int(count), self.dof))

    def _configurations(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=np.float64)
        if q.ndim == 1:
            q = q[None]
        if q.ndim != 2 or q.shape[1] != self.dof:
            raise ValueError(f"{self.name}: configurations must be (C, {self.dof}) joint values "
                             f"({', '.join(self.joint_names)}), got shape {q.shape}")
        if not np.isfinite(q).all():
            c = int(np.flatnonzero(~np.isfinite(q).all(axis=1))[0])
            raise ValueError(f"{self.name}: configuration {c} has a joint value that is not "
                             "finite")
        return q

    def link_transforms(self, q: Any) -> np.ndarray:
        """World from link of every link (in :attr:`links` order) for configurations ``q``.

        Parameters
        ----------
        q : (C, J) or (J,) float

        Returns
        -------
        (C, L, 4, 4) float64
        """
        q = self._configurations(q)
        c = len(q)
        world = np.empty((c, len(self.links), 4, 4))
        world[:, 0] = np.eye(4)
        for j, (parent, child, col, mult, off) in zip(self.joints, self._kin):
            value = q[:, col] * mult + off if col >= 0 else np.full(c, off)
            placed = world[:, parent] @ j.origin
            if j.type in ("revolute", "continuous"):
                motion = np.tile(np.eye(4), (c, 1, 1))
                motion[:, :3, :3] = _axis_rotations(j.axis, value)
                placed = placed @ motion
            elif j.type == "prismatic":
                placed = placed.copy()
                placed[:, :3, 3] += (placed[:, :3, :3] @ j.axis) * value[:, None]
            world[:, child] = placed
        return world

    def poses(self, q: Any) -> np.ndarray:
        """World from body of every collision body (:attr:`bodies`), then of every attached
        object, for configurations ``q``.

        Parameters
        ----------
        q : (C, J) or (J,) float

        Returns
        -------
        (C, B, 4, 4) float64
        """
        links = self.link_transforms(q)
        link, origin = self._body_links()
        return links[:, link] @ origin

    def _body_links(self) -> tuple[np.ndarray, np.ndarray]:
        """Each body's link (B,) (an index into :attr:`links`) and link-from-body origin
        (B, 4, 4): the collision bodies, then the attached objects (:meth:`poses`' order)."""
        if not self._attached:
            return self._body_link, self._body_origin
        att = [(self._link_index[a.body.link], a.body.origin) for a in self._attached.values()]
        return (np.concatenate([self._body_link, [k for k, _ in att]]),
                np.concatenate([self._body_origin, [o for _, o in att]]))

    # -- attached objects -----------------------------------------------------------------

    def attach(self, name: str, mesh: Any, link: str, transform: Any = None, *,
               touch_links: Iterable[str] = ()) -> None:
        """Fix a mesh (a grasped object) to ``link``; it takes part in self- and environment
        checks, allowed to touch ``link`` and ``touch_links`` (MoveIt's attached objects).

        Parameters
        ----------
        name : str
            Its name in results (not a link's name).
        mesh : trimesh.Trimesh or (vertices (V, 3), faces (F, 3))
        link : str
        transform : (4, 4) float, optional
            Link from object (default identity).
        touch_links : iterable of str
            Further links it may touch (a gripper's fingers).
        """
        if link not in self._link_index:
            raise ValueError(f"{self.name}: cannot attach {name!r} to {link!r}: no such link")
        if name in self._link_index or name in self._attached:
            raise ValueError(f"{self.name}: {name!r} is already a link or an attached object")
        touch = frozenset(touch_links) | {link}
        for t in touch:
            if t not in self._link_index:
                raise ValueError(f"{self.name}: attached {name!r} touches {t!r}: no such link")
        origin = _checked_transform(transform, f"attached {name!r}")
        self._attached[name] = _Attached(Body(name, link, _as_trimesh(mesh, name), origin,
                                              "attached"), touch)
        self._plans.clear()
        self._kinematics = None

    def detach(self, name: str) -> None:
        """Remove an attached object."""
        if self._attached.pop(name, None) is None:
            raise KeyError(f"{self.name}: no attached object {name!r}")
        self._plans.clear()
        self._kinematics = None

    @property
    def attached(self) -> list[str]:
        """Names of the attached objects."""
        return list(self._attached)


def _joint(j: Any, where: str) -> _Joint:
    if j.type not in JOINT_TYPES:
        raise ValueError(f"{where}: joint {j.name!r} is {j.type!r}; supported: "
                         f"{', '.join(JOINT_TYPES)}")
    origin = np.eye(4) if j.origin is None else np.asarray(j.origin, np.float64)
    axis = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, np.float64)
    if j.type != "fixed" and not np.linalg.norm(axis) > 0:
        raise ValueError(f"{where}: joint {j.name!r} has a zero axis")
    axis = axis / np.linalg.norm(axis) if np.linalg.norm(axis) > 0 else axis
    lower, upper = -math.pi, math.pi
    if j.type in ("revolute", "prismatic") and j.limit is not None:
        if j.limit.lower is not None:
            lower = float(j.limit.lower)
        if j.limit.upper is not None:
            upper = float(j.limit.upper)
    if j.type == "prismatic" and (j.limit is None or j.limit.lower is None):
        lower, upper = 0.0, 0.0
    if lower > upper:
        raise ValueError(f"{where}: joint {j.name!r} has lower limit {lower} above upper "
                         f"{upper}")
    mimic = None
    if j.mimic is not None:
        mimic = (j.mimic.joint, float(j.mimic.multiplier if j.mimic.multiplier is not None
                                      else 1.0),
                 float(j.mimic.offset if j.mimic.offset is not None else 0.0))
    return _Joint(j.name, j.type, j.parent, j.child, origin, axis, lower, upper, mimic)


def _axis_rotations(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(C, 3, 3) rotations by ``angle`` (C,) about the unit ``axis`` (Rodrigues)."""
    k = axis
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * cross + (1 - c) * (cross @ cross)


class _MeshFiles:
    """Mesh file names of a URDF resolved to paths (see :meth:`Robot.from_urdf`)."""

    def __init__(self, urdf: Path, package_dirs: Any) -> None:
        self.urdf = urdf
        self.packages: dict[str, Path] = {}
        self.folders: list[Path] = []
        if isinstance(package_dirs, dict):
            self.packages = {k: Path(v) for k, v in package_dirs.items()}
        elif isinstance(package_dirs, (str, Path)):
            self.folders = [Path(package_dirs)]
        elif package_dirs is not None:
            self.folders = [Path(p) for p in package_dirs]

    def __call__(self, filename: str, link: str) -> Path:
        base = self.urdf.parent
        tried: list[Path] = []
        if filename.startswith("file://"):
            tried.append(Path(filename[len("file://"):]))
        elif filename.startswith("package://"):
            package, _, rest = filename[len("package://"):].partition("/")
            if package in self.packages:
                tried.append(self.packages[package] / rest)
            for folder in self.folders:
                tried += [folder / package / rest, folder / rest]
            parts = Path(filename[len("package://"):]).parts
            tried += [base.joinpath(*parts[k:]) for k in range(len(parts))]
        else:
            tried.append(base / filename)
            parts = Path(filename).parts
            tried += [base.joinpath(*parts[k:]) for k in range(1, len(parts))]
        for p in tried:
            if p.is_file():
                return p
        raise FileNotFoundError(f"{self.urdf.name}: link {link!r}: mesh {filename!r} not found "
                                "(give package_dirs for package:// paths)")


def _collision_body(col: Any, link: str, k: int, resolve: _MeshFiles,
                    meshes: dict[tuple, trimesh.Trimesh], convex_hull: bool | str
                    ) -> Body | None:
    g = col.geometry
    where = f"{resolve.urdf.name}: link {link!r}"
    origin = np.eye(4) if col.origin is None else np.asarray(col.origin, np.float64)
    name = link if k == 0 else f"{link}/{k}"
    if g is None:
        return None
    if g.mesh is not None:
        path = resolve(g.mesh.filename, link)
        scale = np.ones(3) if g.mesh.scale is None else \
            np.broadcast_to(np.asarray(g.mesh.scale, np.float64), (3,)).copy()
        key = (str(path), tuple(scale), convex_hull)
        if key not in meshes:
            meshes[key] = _read_mesh(path, scale, convex_hull, where)
        return Body(name, link, meshes[key], origin, str(path.name))
    try:
        if g.box is not None:
            size = np.asarray(g.box.size, np.float64)
            if size.shape != (3,) or not (size > 0).all():
                raise ValueError(f"box size must be three positive numbers, got {g.box.size}")
            mesh, kind = trimesh.creation.box(size), "box"
        elif g.cylinder is not None:
            r, h = float(g.cylinder.radius), float(g.cylinder.length)
            if not (r > 0 and h > 0):
                raise ValueError(f"cylinder radius and length must be positive, got {r}, {h}")
            mesh = trimesh.creation.cylinder(radius=r, height=h, sections=CYLINDER_SECTIONS)
            kind = "cylinder"
        elif g.sphere is not None:
            r = float(g.sphere.radius)
            if not r > 0:
                raise ValueError(f"sphere radius must be positive, got {r}")
            mesh = trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=r)
            kind = "sphere"
        else:
            return None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None
    if convex_hull is True:
        mesh = mesh.convex_hull
    return Body(name, link, mesh, origin, kind)


def _read_mesh(path: Path, scale: np.ndarray, convex_hull: bool | str, where: str
               ) -> trimesh.Trimesh:
    """A mesh file as one mesh: vertices merged (OBJ files split them by normal and texture
    coordinate), scaled; replaced by its convex hull where asked."""
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
        mesh = trimesh.Trimesh(np.asarray(loaded.vertices, np.float64),
                               np.asarray(loaded.faces, np.int64), process=False)
    except Exception as exc:  # trimesh raises many kinds on bad files
        raise ValueError(f"{where}: mesh {path.name} could not be read: {exc}") from None
    if len(mesh.faces) == 0:
        raise ValueError(f"{where}: mesh {path.name} has no faces")
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    mesh = trimesh.Trimesh(np.asarray(mesh.vertices) * scale, np.asarray(mesh.faces),
                           process=False)
    if convex_hull is True or (convex_hull == "open" and not mesh.is_volume):
        mesh = mesh.convex_hull
    return mesh

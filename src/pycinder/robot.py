"""Robots: self- and environment collision of a URDF robot for batches of configurations.

    URDF (yourdfpy) -> links' collision meshes + joints in tree order
    configurations (C, J) -> link transforms (C, L, 4, 4) -> body transforms (C, B, 4, 4)
    pairs to check (every pair of bodies on different links, less the allowed-collision
    matrix; robot against environment) -> scenes of one batched query
    (:meth:`pycinder.Detector.find_collisions_batch`) -> (C,) bool, and pairs when asked

A :class:`Robot` is read from a URDF with :meth:`Robot.from_urdf` (the ``robot`` extra brings
yourdfpy). Its collision geometry is taken as the URDF gives it: meshes as they are (an open mesh
is tested as a surface, see :mod:`pycinder.request`), boxes, cylinders and spheres as meshes.
Forward kinematics is vectorised over configurations in NumPy.

Pairs that need no check are kept in an :class:`AllowedCollisionMatrix`, made the way MoveIt's
Setup Assistant makes it (:meth:`Robot.compute_allowed_collisions`: adjacent links, pairs in
collision in the default configuration, pairs always and never in collision over sampled
configurations) and written and read as an SRDF's ``<disable_collisions>`` elements, so that a
MoveIt user's SRDF is honoured as given.

Disallowed pairs are never put on the GPU: the pairs to check are covered by cliques (sets of
bodies whose every pair is checked), each a scene of the batched query, so a configuration's
scenes test exactly its checked pairs.

Padding is MoveIt's: the robot checked against the environment is the padded robot (each link
grown by its padding), and self-collision is checked with the unpadded robot, as MoveIt's
``PlanningScene`` does. A link (or an attached object named in a padding dict) and an
environment body collide when their surfaces are closer than the link's padding. It runs
through the clearance mode (:mod:`pycinder.focused.modes.clearance`) at the largest padding, and each pair is
kept by its own: a pair closer than its padding is always reported, one more than its padding
plus an eighth of the largest padding apart never is.
"""

from __future__ import annotations

import math
import time
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

from .util.optional import require

if TYPE_CHECKING:
    from .detector import Detector

__all__ = ["AllowedCollisionMatrix", "Body", "Environment", "Robot", "matrix_from_samples"]

JOINT_TYPES = ("fixed", "revolute", "continuous", "prismatic")
REASONS = ("Adjacent", "Default", "Always", "Never", "User")
"""Reasons of MoveIt's ``<disable_collisions>`` elements, as its Setup Assistant writes them."""

DEFAULT_BODIES_PER_QUERY = 12_000
"""Most bodies one batched query holds by default (configurations per query: this divided by
the bodies one configuration's scenes hold)."""

QUERY_SECONDS = 2.0
"""Wall seconds a batched query of :meth:`Robot.check` aims at when no ``batch`` is given:
batches start at :data:`FIRST_BATCH` configurations and grow (at most doubling) while queries
take less, up to :data:`DEFAULT_BODIES_PER_QUERY` bodies, so that a slow adapter (a CPU driver)
gets small batches, far from the GPU timeout, and a fast GPU large ones."""

FIRST_BATCH = 8
"""Configurations of the first batched query of a check (see :data:`QUERY_SECONDS`)."""

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
# The allowed-collision matrix


class AllowedCollisionMatrix:
    """Pairs of links (or of a link and an environment body or attached object) never checked,
    each with a reason, as MoveIt's SRDF ``<disable_collisions link1= link2= reason=/>``.

    Parameters
    ----------
    pairs : iterable of (str, str) or (str, str, str), optional
        Names, and a reason (default ``"User"``).

    Examples
    --------
    >>> from pycinder.robot import AllowedCollisionMatrix
    >>> acm = AllowedCollisionMatrix([("link1", "link2", "Adjacent")])
    >>> acm.allowed("link2", "link1"), acm.reason("link1", "link2"), len(acm)
    (True, 'Adjacent', 1)
    >>> print(acm.to_srdf("arm"))
    <?xml version="1.0"?>
    <robot name="arm">
      <disable_collisions link1="link1" link2="link2" reason="Adjacent"/>
    </robot>
    """

    def __init__(self, pairs: Iterable[Sequence[str]] = ()) -> None:
        self._reasons: dict[frozenset[str], tuple[str, str, str]] = {}
        for p in pairs:
            self.allow(*p)

    def allow(self, a: str, b: str, reason: str = "User") -> None:
        """Allow ``a`` and ``b`` to collide (never check them); the first reason given stays."""
        if a == b:
            raise ValueError(f"allowed collisions are pairs of two names, got {a!r} twice")
        self._reasons.setdefault(frozenset((a, b)), (a, b, str(reason)))

    def disallow(self, a: str, b: str) -> None:
        """Check ``a`` and ``b`` again."""
        self._reasons.pop(frozenset((a, b)), None)

    def allowed(self, a: str, b: str) -> bool:
        """Whether the pair is never checked."""
        return frozenset((a, b)) in self._reasons

    def reason(self, a: str, b: str) -> str | None:
        """The reason the pair is allowed, or None where it is checked."""
        entry = self._reasons.get(frozenset((a, b)))
        return entry[2] if entry is not None else None

    def __len__(self) -> int:
        return len(self._reasons)

    def __contains__(self, pair: Any) -> bool:
        return frozenset(pair) in self._reasons

    def __iter__(self):
        return iter(self.pairs())

    def __eq__(self, other: object) -> bool:
        return isinstance(other, AllowedCollisionMatrix) and \
            {k: v[2] for k, v in self._reasons.items()} == \
            {k: v[2] for k, v in other._reasons.items()}

    def __repr__(self) -> str:
        counts: dict[str, int] = {}
        for _, _, r in self._reasons.values():
            counts[r] = counts.get(r, 0) + 1
        return f"AllowedCollisionMatrix({len(self)} pairs: " + ", ".join(
            f"{n} {r}" for r, n in sorted(counts.items())) + ")"

    def pairs(self, reason: str | None = None) -> list[tuple[str, str, str]]:
        """(name, name, reason) of every allowed pair (of ``reason`` only, when given), sorted."""
        return sorted((*sorted((a, b)), r) for a, b, r in self._reasons.values()
                      if reason is None or r == reason)

    def update(self, other: AllowedCollisionMatrix) -> None:
        """Add the pairs of ``other`` (a pair already here keeps its reason)."""
        for a, b, r in other._reasons.values():
            self.allow(a, b, r)

    def to_srdf(self, robot_name: str) -> str:
        """An SRDF document holding the pairs as ``<disable_collisions>`` elements."""
        root = ET.Element("robot", name=robot_name)
        for a, b, r in self.pairs():
            ET.SubElement(root, "disable_collisions", link1=a, link2=b, reason=r)
        ET.indent(root, "  ")
        return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode")

    def write_srdf(self, path: str | Path, robot_name: str) -> None:
        """Write :meth:`to_srdf` to ``path``."""
        Path(path).write_text(self.to_srdf(robot_name) + "\n")

    @classmethod
    def from_srdf(cls, srdf: str | Path) -> AllowedCollisionMatrix:
        """The ``<disable_collisions>`` pairs of an SRDF file (or of its text, when ``srdf`` is
        a string that starts with ``<``); every other element is ignored."""
        text, where = _text_of(srdf)
        try:
            root = ET.fromstring(text)
        except ET.ParseError as exc:
            raise ValueError(f"{where}: not an SRDF (XML) document: {exc}") from None
        acm = cls()
        for k, el in enumerate(root.iter("disable_collisions")):
            a, b = el.get("link1"), el.get("link2")
            if not a or not b:
                raise ValueError(f"{where}: <disable_collisions> {k + 1} needs link1 and link2")
            if a != b:
                acm.allow(a, b, el.get("reason") or "User")
        return acm


def _text_of(source: str | Path) -> tuple[str, str]:
    if isinstance(source, str) and source.lstrip().startswith("<"):
        return source, "SRDF text"
    path = Path(source)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such SRDF file")
    return path.read_text(), path.name


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
        t = np.eye(4) if transform is None else np.asarray(transform, np.float64)
        if t.shape != (4, 4) or not np.isfinite(t).all():
            raise ValueError(f"environment body {name!r}: transform must be a finite (4, 4) "
                             f"matrix, got shape {t.shape}")
        self.bodies.append(Body(name, name, _as_trimesh(mesh, name), t, "mesh"))

    @classmethod
    def from_urdf(cls, path: str | Path, transform: Any = None, *, prefix: str | None = None,
                  package_dirs: Any = None) -> Environment:
        """The collision bodies of a URDF object (pybullet_data's ``table/table.urdf``), placed
        at ``transform`` in its default configuration; names are ``prefix/link`` (prefix:
        the file's stem)."""
        robot = Robot.from_urdf(path, package_dirs=package_dirs)
        env = cls()
        place = np.eye(4) if transform is None else np.asarray(transform, np.float64)
        poses = robot.poses(robot.default_configuration()[None])[0]
        prefix = Path(path).stem if prefix is None else prefix
        for b, pose in zip(robot.bodies, poses):
            env.add(f"{prefix}/{b.name}", b.mesh, place @ pose)
        return env


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
class _Plan:
    """Scenes of one configuration: each a clique of bodies (indices into the bodies of a check:
    robot, attached, environment) whose every pair is checked, and each pair in one scene."""

    scenes: list[np.ndarray]
    pairs: int
    bodies: int
    checked: np.ndarray
    """(B, B) bool: the pairs checked (a scene may also hold pairs allowed as ``Never``, cheap
    to test and left out of the answers)."""
    exact: bool
    """Whether the scenes hold checked pairs only."""


@dataclass
class Robot:
    """A robot's links, joints and collision bodies, and checks of its configurations.

    Made by :meth:`from_urdf`. Configurations are (C, J) joint values in the order of
    :attr:`joint_names` (the actuated joints: not fixed, not mimicking another).

    Attributes
    ----------
    name : str
    root : str
        The root link.
    links : list of str
        Every link, in tree order.
    bodies : list of Body
        Collision bodies of the links.
    joint_names : list of str
        The actuated joints, in tree order: a configuration's columns.
    limits : (J, 2) float
        Lower and upper limits (continuous joints: -pi, pi).
    allowed : AllowedCollisionMatrix
        Pairs never checked (see :meth:`compute_allowed_collisions`).
    tolerance : float or None
        World units of the tolerance contract (see :mod:`pycinder.request`); None: 1% of the
        smaller body's size, per pair.
    source : str
        The URDF file's name, for messages.
    share_never_pairs : bool
        Let pairs allowed as ``Never`` share a batch's scenes with checked pairs (their answers
        dropped): far fewer scenes and less host work per configuration, more GPU work where
        their boxes overlap. Default False: the scenes hold checked pairs only (on lavapipe the
        GPU stage dominates; on a fast GPU the host stages may).
    """

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
    share_never_pairs: bool = False
    _attached: dict[str, _Attached] = field(default_factory=dict, repr=False)
    _detector: Any = field(default=None, repr=False)
    _padded: dict = field(default_factory=dict, repr=False)
    _plans: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self._link_index = {n: k for k, n in enumerate(self.links)}
        self._prepare_kinematics()

    # -- loading --------------------------------------------------------------------------

    @classmethod
    def from_urdf(cls, path: str | Path, *, srdf: str | Path | None = None,
                  package_dirs: str | Path | Sequence[str | Path] | dict[str, str | Path] |
                  None = None, convex_hull: bool | str = False, tolerance: float | None = None,
                  detector: Detector | None = None) -> Robot:
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
            from .request import CollisionRequest

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
        out = links[:, self._body_link] @ self._body_origin
        if self._attached:
            att = [(self._link_index[a.body.link], a.body.origin) for a in self._attached.values()]
            extra = links[:, [k for k, _ in att]] @ np.array([o for _, o in att])
            out = np.concatenate([out, extra], axis=1)
        return out

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
        origin = np.eye(4) if transform is None else np.asarray(transform, np.float64)
        if origin.shape != (4, 4):
            raise ValueError(f"attached {name!r}: transform must be (4, 4), got {origin.shape}")
        self._attached[name] = _Attached(Body(name, link, _as_trimesh(mesh, name), origin,
                                              "attached"), touch)
        self._plans.clear()

    def detach(self, name: str) -> None:
        """Remove an attached object."""
        if self._attached.pop(name, None) is None:
            raise KeyError(f"{self.name}: no attached object {name!r}")
        self._plans.clear()

    @property
    def attached(self) -> list[str]:
        """Names of the attached objects."""
        return list(self._attached)

    # -- pairs ----------------------------------------------------------------------------

    def _all_bodies(self, environment: Environment | None) -> list[Body]:
        return self.bodies + [a.body for a in self._attached.values()] + \
            (environment.bodies if environment is not None else [])

    def checked_pairs(self, environment: Environment | None = None, *,
                      self_collision: bool = True) -> list[tuple[str, str]]:
        """The pairs of names a check tests: bodies on different links, not allowed by
        :attr:`allowed`, robot against environment; sorted."""
        bodies = self._all_bodies(environment)
        return sorted({tuple(sorted((_owner(bodies[i]), _owner(bodies[j]))))
                       for i, j in self._pair_list(environment, self_collision)})

    def _pair_list(self, environment: Environment | None, self_collision: bool
                   ) -> list[tuple[int, int]]:
        bodies = self._all_bodies(environment)
        nr = len(self.bodies)
        na = len(self._attached)
        touch = [a.touch for a in self._attached.values()]
        kind = ["robot"] * nr + ["attached"] * na + ["env"] * (len(bodies) - nr - na)
        allowed = self.allowed
        out = []
        for i in range(len(bodies)):
            for j in range(i + 1, len(bodies)):
                ki, kj = kind[i], kind[j]
                if ki == "env" and kj == "env":
                    continue
                if not self_collision and ki != "env" and kj != "env":
                    continue
                a, b = _owner(bodies[i]), _owner(bodies[j])
                if a == b or allowed.allowed(a, b):
                    continue
                if ki == "robot" and kj == "attached" and bodies[i].link in touch[j - nr]:
                    continue
                out.append((i, j))
        return out

    def _plan(self, environment: Environment | None, self_collision: bool
              ) -> tuple[_Plan, list[Body]]:
        key = (id(environment), len(environment) if environment is not None else 0,
               self_collision, len(self.allowed), hash(tuple(self.allowed.pairs())),
               self.share_never_pairs)
        bodies = self._all_bodies(environment)
        plan = self._plans.get(key)
        if plan is None:
            pairs = self._pair_list(environment, self_collision)
            # Pairs MoveIt found never colliding may share a scene with checked ones: their
            # boxes seldom overlap, so they cost little, and they let far fewer scenes cover
            # the checked pairs (host work grows with scenes); their answers are dropped.
            robot = len(self.bodies) + len(self._attached)
            never = [(i, j) for i in range(robot) for j in range(i + 1, robot)
                     if self.allowed.reason(_owner(bodies[i]), _owner(bodies[j])) == "Never"
                     ] if self.share_never_pairs else []
            scenes = _clique_cover(len(bodies), pairs, never)
            checked = np.zeros((len(bodies), len(bodies)), dtype=bool)
            for i, j in pairs:
                checked[i, j] = checked[j, i] = True
            exact = all(checked[np.ix_(sc, sc)].sum() == len(sc) * (len(sc) - 1)
                        for sc in scenes)
            plan = self._plans[key] = _Plan(scenes, len(pairs), sum(len(s) for s in scenes),
                                            checked, exact)
        return plan, bodies

    # -- checks ---------------------------------------------------------------------------

    @property
    def detector(self) -> Detector:
        """The detector of the checks (made on first use: ``records="none"``, and the broad
        phase in NumPy: a batch's scenes hold a few bodies each)."""
        if self._detector is None:
            from .detector import Detector

            self._detector = Detector(records="none", broad_phase="numpy")
        return self._detector

    def in_collision(self, q: Any, *, environment: Environment | None = None,
                     self_collision: bool = True) -> bool:
        """Whether configuration ``q`` (J,) collides (see :meth:`check`)."""
        q = np.asarray(q, np.float64)
        if q.ndim != 1:
            raise ValueError(f"{self.name}: in_collision takes one configuration ({self.dof} "
                             f"joint values), got shape {q.shape}; use check for many")
        return bool(self.check(q[None], environment=environment,
                               self_collision=self_collision)[0])

    def check(self, qs: Any, *, environment: Environment | None = None,
              self_collision: bool = True, return_pairs: bool = False,
              batch: int | None = None, padding: Any = None
              ) -> np.ndarray | tuple[np.ndarray, list[list[tuple[str, str]]]]:
        """Which configurations collide: with themselves (pairs of links on different links,
        less :attr:`allowed`), with attached objects, and with the environment.

        Parameters
        ----------
        qs : (C, J) float
            Configurations, columns in :attr:`joint_names` order.
        environment : Environment, optional
            Fixed bodies to check the robot and its attached objects against.
        self_collision : bool
            Check the robot's own pairs (False: only against the environment).
        return_pairs : bool
            Also return, per configuration, the colliding pairs of names (link, attached object
            or environment body names), each pair sorted, the list sorted.
        batch : int, optional
            Configurations per query. Default: paced, from :data:`FIRST_BATCH` configurations
            growing while queries take less than :data:`QUERY_SECONDS`, up to
            :data:`DEFAULT_BODIES_PER_QUERY` bodies per query. A batch too large for the
            device's pixel budget is split.
        padding : float or dict of str to float, optional
            MoveIt's padding, in world units: one for every link, or per link or attached
            object name (names left out: 0). It applies against the environment: a link and an
            environment body collide when their surfaces are closer than the link's padding;
            self-collision is checked unpadded, as MoveIt checks it (see the module's
            docstring).

        Returns
        -------
        collides : (C,) bool
        pairs : list of list of (str, str)
            Only with ``return_pairs``.
        """
        if not isinstance(self_collision, bool) or not isinstance(return_pairs, bool):
            raise ValueError("self_collision and return_pairs must be True or False")
        if environment is not None and not isinstance(environment, Environment):
            raise TypeError(f"environment must be a pycinder.robot.Environment, got "
                            f"{type(environment).__name__}")
        qs = self._configurations(qs)
        plan, bodies = self._plan(environment, self_collision)
        pads = self._paddings(padding, bodies)
        collides = np.zeros(len(qs), dtype=bool)
        pairs: list[list[tuple[str, str]]] = [[] for _ in range(len(qs))]
        for start, stop in self._batches(len(qs), batch, plan):
            self._check_batch(qs[start:stop], start, plan, bodies, environment, collides,
                              pairs if return_pairs else None, pads)
        return (collides, pairs) if return_pairs else collides

    def _batches(self, count: int, batch: int | None, plan: _Plan) -> Iterator[tuple[int, int]]:
        """``(start, stop)`` of each query's configurations: ``batch`` at a time when given;
        else paced (see :data:`QUERY_SECONDS`), the time between one range and the next being
        the caller's query."""
        most = self._batch_size(batch, plan)
        size = most if batch is not None else min(FIRST_BATCH, most)
        start = 0
        while start < count:
            t0 = time.perf_counter()
            yield start, min(start + size, count)
            start += size
            if batch is None:
                pace = QUERY_SECONDS / max(time.perf_counter() - t0, 1e-3)
                size = max(1, min(most, int(size * min(pace, 2.0))))

    def _paddings(self, padding: Any, bodies: list[Body]) -> np.ndarray | None:
        """(B,) the padding of each body of a check (None without padding)."""
        if padding is None:
            return None
        robot = len(self.bodies) + len(self._attached)
        links = len(self.bodies)
        if isinstance(padding, dict):
            known = set(self.links) | set(self._attached)
            unknown = sorted(set(padding) - known)
            if unknown:
                raise ValueError(f"{self.name}: padding names {unknown[:3]}, which are neither "
                                 "links nor attached objects")
            values = [padding.get(_owner(b), 0.0) if k < robot else 0.0
                      for k, b in enumerate(bodies)]
        else:  # the links' padding (attached objects are padded only by name)
            values = [padding if k < links else 0.0 for k in range(len(bodies))]
        pads = np.array([float(v) if isinstance(v, (int, float, np.floating))
                         and not isinstance(v, bool) else np.nan for v in values])
        if not np.isfinite(pads).all() or (pads < 0).any():
            raise ValueError(f"{self.name}: padding must be non-negative world units, got "
                             f"{padding!r}")
        return pads if pads.any() else None

    def _padded_detector(self, clearance: float) -> Detector:
        """The detector of padded checks whose largest padding sum is ``clearance``."""
        from .detector import Detector

        cache = self._padded
        if clearance not in cache:
            cache.clear()
            cache[clearance] = Detector(records="none", broad_phase="numpy",
                                        clearance=clearance)
        return cache[clearance]

    def _batch_size(self, batch: int | None, plan: _Plan) -> int:
        if batch is None:
            return max(1, DEFAULT_BODIES_PER_QUERY // max(plan.bodies, 1))
        if isinstance(batch, bool) or not isinstance(batch, (int, np.integer)) or batch < 1:
            raise ValueError(f"batch must be a positive whole number of configurations, got "
                             f"{batch!r}")
        return int(batch)

    def _check_batch(self, qs: np.ndarray, start: int, plan: _Plan, bodies: list[Body],
                     environment: Environment | None, collides: np.ndarray,
                     pairs: list[list[tuple[str, str]]] | None,
                     pads: np.ndarray | None = None) -> None:
        from .errors import GpuMemoryError

        if not plan.scenes or not len(qs):
            return
        poses = self.poses(qs)
        if environment is not None and len(environment):
            env = np.array([b.origin for b in environment.bodies])
            poses = np.concatenate([poses, np.broadcast_to(env, (len(qs), *env.shape))], axis=1)
        meshes = [b.mesh for b in bodies]
        names = [b.name for b in bodies]
        scene_meshes = [[meshes[i] for i in s] for s in plan.scenes]
        scene_names = [[names[i] for i in s] for s in plan.scenes]
        scenes = [(scene_meshes[k], poses[c, s], scene_names[k])
                  for c in range(len(qs)) for k, s in enumerate(plan.scenes)]
        try:
            results = self._query(scenes, plan, pads)
        except GpuMemoryError:
            if len(qs) == 1:
                raise
            half = len(qs) // 2
            self._check_batch(qs[:half], start, plan, bodies, environment, collides, pairs,
                              pads)
            self._check_batch(qs[half:], start + half, plan, bodies, environment, collides,
                              pairs, pads)
            return
        k = len(plan.scenes)
        if plan.exact:
            hit = np.array([len(r.pairs) > 0 for r in results]).reshape(len(qs), k)
        else:
            hit = np.array([bool(plan.checked[sc[r.pairs[:, 0]], sc[r.pairs[:, 1]]].any())
                            for r, sc in zip(results, plan.scenes * len(qs))]
                           ).reshape(len(qs), k)
        collides[start:start + len(qs)] = hit.any(axis=1)
        if pairs is not None:
            for c in np.flatnonzero(hit.any(axis=1)):
                found = set()
                for s in np.flatnonzero(hit[c]):
                    scene = plan.scenes[s]
                    for a, b in results[c * k + s].pairs.tolist():
                        if not plan.checked[scene[a], scene[b]]:
                            continue
                        found.add(tuple(sorted((_owner(bodies[scene[a]]),
                                                _owner(bodies[scene[b]])))))
                pairs[start + c] = sorted(found)

    def _query(self, scenes: list, plan: _Plan, pads: np.ndarray | None) -> list:
        """The batch's results; with padding, each scene's pairs kept by their own padding
        (environment pairs by the robot body's, the robot's own pairs by none)."""
        if pads is None:
            return self.detector.find_collisions_batch(scenes, tolerance=self.tolerance)
        robot = len(self.bodies) + len(self._attached)
        clearance = max(float(pads.max()), 1e-12)
        results = self._padded_detector(clearance).find_collisions_batch(
            scenes, tolerance=self.tolerance)
        for k, result in enumerate(results):
            scene = np.asarray(plan.scenes[k % len(plan.scenes)])
            a, b = scene[result.pairs[:, 0]], scene[result.pairs[:, 1]]
            # Against the environment the padded robot; its own pairs unpadded (MoveIt's).
            limit = np.where((a >= robot) | (b >= robot), pads[a] + pads[b], 0.0)
            keep = result.distances < limit + result.distance_errors
            result.pairs = result.pairs[keep]
            result.distances = result.distances[keep]
            result.distance_errors = result.distance_errors[keep]
        return results

    def interpolate(self, qs: Any, resolution: float) -> np.ndarray:
        """A path through waypoints ``qs`` (W, J), linearly interpolated so that no joint moves
        more than ``resolution`` between consecutive configurations (radians or metres).

        Returns
        -------
        (M, J) float64
            Starts with the first waypoint and ends with the last; every waypoint is on it.
        """
        qs = self._configurations(qs)
        if isinstance(resolution, bool) or not isinstance(resolution, (int, float)) or \
                not math.isfinite(resolution) or resolution <= 0:
            raise ValueError(f"resolution must be a positive number, got {resolution!r}")
        parts = [qs[:1]]
        for a, b in zip(qs[:-1], qs[1:]):
            steps = max(1, int(math.ceil(np.abs(b - a).max() / resolution - 1e-12)))
            s = np.arange(1, steps + 1)[:, None] / steps
            parts.append(a + s * (b - a))
        return np.concatenate(parts)

    def check_path(self, qs: Any, resolution: float = 0.01, *,
                   environment: Environment | None = None, self_collision: bool = True,
                   batch: int | None = None) -> int | None:
        """The first colliding configuration of a path, densely interpolated.

        Parameters
        ----------
        qs : (W, J) float
            Waypoints.
        resolution : float
            Most a joint moves between checked configurations (see :meth:`interpolate`).
        environment, self_collision, batch
            As :meth:`check`; batches are checked in order and the check stops at the first
            batch with a collision.

        Returns
        -------
        int or None
            Index into ``robot.interpolate(qs, resolution)`` of the first configuration that
            collides; None when none does.
        """
        path = self.interpolate(qs, resolution)
        plan, _ = self._plan(environment, self_collision)
        for start, stop in self._batches(len(path), batch, plan):
            hit = self.check(path[start:stop], environment=environment,
                             self_collision=self_collision, batch=stop - start)
            if hit.any():
                return start + int(np.flatnonzero(hit)[0])
        return None

    # -- the allowed-collision matrix -----------------------------------------------------

    def adjacent_links(self) -> list[tuple[str, str]]:
        """Pairs of links with collision geometry that MoveIt's Setup Assistant calls adjacent:
        joined by a joint, or through links without collision geometry (sorted pairs)."""
        geometric = {b.link for b in self.bodies}
        neighbours: dict[str, set[str]] = {n: set() for n in self.links}
        for j in self.joints:
            neighbours[j.parent].add(j.child)
            neighbours[j.child].add(j.parent)
        out = set()
        for start in geometric:
            seen, todo = {start}, [start]
            while todo:
                n = todo.pop()
                for m in neighbours[n]:
                    if m in seen:
                        continue
                    seen.add(m)
                    if m in geometric:
                        out.add(tuple(sorted((start, m))))
                    else:
                        todo.append(m)
        return sorted(out)

    def compute_allowed_collisions(self, samples: int = 10_000, *, seed: int = 0,
                                   always_fraction: float = 0.95, always_samples: int = 100,
                                   batch: int | None = None) -> AllowedCollisionMatrix:
        """An allowed-collision matrix made by MoveIt Setup Assistant's rules, in its order
        (a pair takes the first reason that applies):

        1. ``Adjacent``: :meth:`adjacent_links`;
        2. ``Default``: pairs in collision in :meth:`default_configuration`;
        3. ``Always``: pairs in collision in at least ``always_fraction`` of the first
           ``always_samples`` random configurations;
        4. ``Never``: pairs in collision in none of ``samples`` random configurations.

        Random configurations are uniform within the joint limits, from ``seed``; the checks are
        :meth:`check`'s, without :attr:`allowed` and without attached objects.

        Returns
        -------
        AllowedCollisionMatrix
            A new matrix (assign it to :attr:`allowed`, or write it with
            :meth:`AllowedCollisionMatrix.write_srdf`).
        """
        if not isinstance(samples, (int, np.integer)) or samples < 1:
            raise ValueError(f"samples must be a positive whole number, got {samples!r}")
        if not 0 < always_fraction <= 1:
            raise ValueError(f"always_fraction must be in (0, 1], got {always_fraction!r}")
        saved, attached = self.allowed, self._attached
        try:
            self.allowed, self._attached = AllowedCollisionMatrix(), {}
            self._plans.clear()
            _, default = self.check(self.default_configuration()[None], return_pairs=True)
            qs = self.random_configurations(max(samples, always_samples), seed)
            _, found = self.check(qs, return_pairs=True, batch=batch)
        finally:
            self.allowed, self._attached = saved, attached
            self._plans.clear()
        return matrix_from_samples(self.adjacent_links(), default[0], found,
                                   sorted({b.link for b in self.bodies}), samples=samples,
                                   always_samples=always_samples,
                                   always_fraction=always_fraction)

    def write_srdf(self, path: str | Path) -> None:
        """Write :attr:`allowed` as an SRDF file."""
        self.allowed.write_srdf(path, self.name)


def matrix_from_samples(adjacent: Iterable[tuple[str, str]],
                        default: Iterable[tuple[str, str]],
                        sampled: Sequence[Iterable[tuple[str, str]]], links: Sequence[str], *,
                        samples: int, always_samples: int = 100,
                        always_fraction: float = 0.95) -> AllowedCollisionMatrix:
    """MoveIt Setup Assistant's rules (see :meth:`Robot.compute_allowed_collisions`) applied to
    colliding pairs found by any checker.

    Parameters
    ----------
    adjacent : iterable of (str, str)
        Adjacent links.
    default : iterable of (str, str)
        Pairs colliding in the default configuration.
    sampled : sequence of iterable of (str, str)
        Colliding pairs of each random configuration, in order.
    links : sequence of str
        Links with collision geometry.
    samples, always_samples, always_fraction
        As :meth:`Robot.compute_allowed_collisions`.

    Returns
    -------
    AllowedCollisionMatrix
    """
    acm = AllowedCollisionMatrix()
    for a, b in adjacent:
        acm.allow(a, b, "Adjacent")
    for a, b in default:
        acm.allow(a, b, "Default")
    early: dict[tuple[str, str], int] = {}
    for per in sampled[:always_samples]:
        for p in per:
            p = tuple(sorted(p))
            early[p] = early.get(p, 0) + 1
    trials = min(always_samples, len(sampled))
    for p, n in sorted(early.items()):
        if n >= always_fraction * trials:
            acm.allow(*p, "Always")
    sometimes = {tuple(sorted(p)) for per in sampled[:samples] for p in per}
    links = sorted(links)
    for i, a in enumerate(links):
        for b in links[i + 1:]:
            if (a, b) not in sometimes:
                acm.allow(a, b, "Never")
    return acm


def _owner(body: Body) -> str:
    """The name a body's collisions are reported under: its link (robot), its own name
    (attached object, environment body)."""
    return body.name if body.source == "attached" else body.link


def _clique_cover(n: int, pairs: list[tuple[int, int]],
                  extra: Sequence[tuple[int, int]] = ()) -> list[np.ndarray]:
    """Scenes covering every pair of ``pairs`` (of ``n`` bodies), each a clique of the graph of
    ``pairs`` and ``extra`` (so no other pair is tested): grown greedily from an uncovered pair
    by the body that covers most uncovered pairs."""
    adjacent = [set() for _ in range(n)]
    for i, j in list(pairs) + list(extra):
        adjacent[i].add(j)
        adjacent[j].add(i)
    uncovered = {(min(i, j), max(i, j)) for i, j in pairs}
    scenes = []
    for i, j in sorted(uncovered):
        if (i, j) not in uncovered:
            continue
        clique = [i, j]
        candidates = adjacent[i] & adjacent[j]
        while candidates:
            best = max(sorted(candidates), key=lambda v: sum(
                (min(v, u), max(v, u)) in uncovered for u in clique))
            if not any((min(best, u), max(best, u)) in uncovered for u in clique):
                break
            clique.append(best)
            candidates &= adjacent[best]
        for a in range(len(clique)):
            for b in range(a + 1, len(clique)):
                uncovered.discard((min(clique[a], clique[b]), max(clique[a], clique[b])))
        scenes.append(np.array(sorted(clique), dtype=np.int64))
    return scenes


# ---------------------------------------------------------------------------------------------
# URDF pieces


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

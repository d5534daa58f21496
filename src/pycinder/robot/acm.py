"""The allowed-collision matrix: pairs of links (or of a link and an environment body or
attached object) never checked, made the way MoveIt's Setup Assistant makes it and read and
written as an SRDF's ``<disable_collisions>`` elements (:class:`AllowedCollisionMatrix`,
:func:`matrix_from_samples`)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..util.text import plural

REASONS = ("Adjacent", "Default", "Always", "Never", "User")
"""Reasons of MoveIt's ``<disable_collisions>`` elements, as its Setup Assistant writes them."""


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


ALWAYS_SAMPLES = 100
"""Random configurations MoveIt Setup Assistant's "Always" rule samples (and the fewest a check
must hold before :meth:`pycinder.robot.Robot.check` warns of pairs in collision in nearly all)."""
ALWAYS_FRACTION = 0.95
"""Share of those configurations a pair must collide in to be "Always" in collision."""


class AlwaysCollidingWarning(UserWarning):
    """Some of a robot's own pairs collided in nearly every configuration of a check (at least
    :data:`ALWAYS_FRACTION` of :data:`ALWAYS_SAMPLES` or more): pairs that always touch, which an
    SRDF or :meth:`pycinder.robot.Robot.compute_allowed_collisions` allows. Said once per pair
    and robot."""

    @classmethod
    def of(cls, robot: str, pairs: Sequence[tuple[str, str]], checked: int
           ) -> AlwaysCollidingWarning:
        """The warning for ``pairs`` of the robot named ``robot`` over ``checked``
        configurations."""
        listed = ", ".join(f"{a}-{b}" for a, b in pairs)
        return cls(
            f"{robot}: {plural(len(pairs), 'pair')} collided in at least {ALWAYS_FRACTION:.0%} "
            f"of the {checked:,} configurations checked: {listed}. Pairs "
            "that always touch (adjacent links, a hand's fingers) are left out of MoveIt's "
            "checks by its allowed-collision matrix: load the robot's SRDF "
            "(Robot.from_urdf(..., srdf=...)), or make one with robot.allowed = "
            "robot.compute_allowed_collisions() (robot.write_srdf keeps it), or allow a pair "
            "with robot.allowed.allow(a, b).")


def always_colliding(counts: np.ndarray, checked: int, owners: Sequence[str]
                     ) -> list[tuple[str, str]]:
    """The pairs of names in collision in at least :data:`ALWAYS_FRACTION` of ``checked``
    configurations.

    Parameters
    ----------
    counts : (B, B) int
        Configurations each pair of bodies collided in (either triangle).
    checked : int
        Configurations checked.
    owners : (B,) sequence of str
        The name each body's collisions are reported under (its link, or attached object).

    Returns
    -------
    list of (str, str)
        Each pair sorted, once, the list sorted.
    """
    both = np.asarray(counts) + np.asarray(counts).T
    a, b = np.nonzero(np.triu(both, 1) >= ALWAYS_FRACTION * checked)
    return sorted({tuple(sorted((owners[i], owners[j]))) for i, j in zip(a.tolist(), b.tolist())
                   if owners[i] != owners[j]})


def matrix_from_samples(adjacent: Iterable[tuple[str, str]],
                        default: Iterable[tuple[str, str]],
                        sampled: Sequence[Iterable[tuple[str, str]]], links: Sequence[str], *,
                        samples: int, always_samples: int = ALWAYS_SAMPLES,
                        always_fraction: float = ALWAYS_FRACTION) -> AllowedCollisionMatrix:
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

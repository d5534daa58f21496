"""What each pass is, for the pass tables: every pass class carries a :class:`PassInfo`, and the
tables in the docs are generated from the classes (:func:`pass_table`), so no table can leave a
pass out or list it out of order.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal


@dataclass(frozen=True)
class PassInfo:
    """One row of a pass table.

    Attributes
    ----------
    number : str
        The pass's number, in the order the passes run ("F1", "B3", ...).
    name : str
        A short name ("cull").
    purpose : str
        What it does, in a line.
    kind : {"compute", "render"}
    state : str
        Depth, stencil and cull state of a render pass ("-" for compute passes).
    when : str
        When it runs ("every round", "when vertices changed", ...).
    """

    number: str
    name: str
    purpose: str
    kind: Literal["compute", "render"] = "compute"
    state: str = "-"
    when: str = "every frame"

    @property
    def title(self) -> str:
        """``"F1 cull"``: how labels, profiles and errors name the pass."""
        return f"{self.number} {self.name}"


HEADER = ("pass", "name", "kind", "depth / stencil / cull", "runs", "purpose")
"""The columns of a pass table."""


def rows(infos: Iterable[PassInfo]) -> list[tuple[str, ...]]:
    """One row of :data:`HEADER`'s columns per pass."""
    return [(i.number, i.name, i.kind, i.state, i.when, i.purpose) for i in infos]


def pass_table(infos: Iterable[PassInfo]) -> str:
    """The passes as a reStructuredText grid table (:data:`HEADER`'s columns)."""
    header = HEADER
    rows_ = [header] + rows(infos)
    widths = [max(len(r[k]) for r in rows_) for k in range(len(header))]
    rule = "+" + "+".join("-" * (w + 2) for w in widths) + "+"

    def line(row: tuple[str, ...]) -> str:
        return "|" + "|".join(f" {c:<{w}} " for c, w in zip(row, widths)) + "|"

    out = [rule, line(rows_[0]), rule.replace("-", "=")]
    for row in rows_[1:]:
        out += [line(row), rule]
    return "\n".join(out)


__all__ = ["HEADER", "PassInfo", "pass_table", "rows"]

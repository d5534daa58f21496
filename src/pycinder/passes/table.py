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


def pass_table(infos: Iterable[PassInfo]) -> str:
    """The passes as a reStructuredText grid table (number, name, kind, state, when, purpose)."""
    header = ("pass", "name", "kind", "depth / stencil / cull", "runs", "purpose")
    rows = [header] + [(i.number, i.name, i.kind, i.state, i.when, i.purpose) for i in infos]
    widths = [max(len(r[k]) for r in rows) for k in range(len(header))]
    rule = "+" + "+".join("-" * (w + 2) for w in widths) + "+"

    def line(row: tuple[str, ...]) -> str:
        return "|" + "|".join(f" {c:<{w}} " for c, w in zip(row, widths)) + "|"

    out = [rule, line(rows[0]), rule.replace("-", "=")]
    for row in rows[1:]:
        out += [line(row), rule]
    return "\n".join(out)


__all__ = ["PassInfo", "pass_table"]

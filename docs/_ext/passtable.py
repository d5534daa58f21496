"""``pass-table``: a strategy's passes as a table, generated from the pass classes.

``.. pass-table:: focused`` (or ``broad``, ``scene``, ``planner``, ...) renders the
:class:`PassInfo` of every pass class the strategy runs, in the order it runs them, so that no
page can leave a pass out.
"""

from __future__ import annotations

import importlib

from docutils import nodes
from sphinx.util.docutils import SphinxDirective

SOURCES = {
    "focused": ("pycinder.focused.frame.frames", "PASSES"),
    "broad": ("pycinder.focused.broad", "PASSES"),
    "scene": ("pycinder.wholescene.frame", "PASS_INFOS"),
    "clearance": ("pycinder.clearance", "PASSES"),
    "hardclash": ("pycinder.hardclash", "PASSES"),
    "planner": ("pycinder.focused.plan.gpu", "PASSES"),
    "robot": ("pycinder.robot.cull", "PASSES"),
}
"""Where each strategy lists its pass classes (module, attribute)."""


class PassTable(SphinxDirective):
    """The pass table of one strategy."""

    required_arguments = 1
    has_content = False

    def run(self) -> list[nodes.Node]:
        from pycinder.gpu.table import HEADER, rows

        module, name = SOURCES[self.arguments[0]]
        passes = getattr(importlib.import_module(module), name)
        return [_table(HEADER, rows(getattr(p, "INFO", p) for p in passes))]


def _table(header: tuple[str, ...], body: list[tuple[str, ...]]) -> nodes.table:
    """A docutils table (it renders in Markdown and reStructuredText pages alike)."""
    table = nodes.table(classes=["pass-table"])
    group = nodes.tgroup(cols=len(header))
    table += group
    for _ in header:
        group += nodes.colspec(colwidth=1)

    def row(cells: tuple[str, ...]) -> nodes.row:
        out = nodes.row()
        for text in cells:
            entry = nodes.entry()
            entry += nodes.paragraph(text=text)
            out += entry
        return out

    head = nodes.thead()
    head += row(header)
    group += head
    tbody = nodes.tbody()
    for cells in body:
        tbody += row(cells)
    group += tbody
    return table


def setup(app):  # noqa: ANN001, ANN201
    app.add_directive("pass-table", PassTable)
    return {"parallel_read_safe": True, "parallel_write_safe": True}

"""``pass-table``: a strategy's passes as a table, generated from the pass classes; and
``pass-files``: where every pass lives (pass code, file, shader, class).

``.. pass-table:: focused`` (or ``broad``, ``scene``, ``planner``, ...) renders the
:class:`PassInfo` of every pass class the strategy runs, in the order it runs them, so that no
page can leave a pass out. ``.. pass-files::`` renders one row per pass class of every strategy,
from the classes themselves (their ``INFO``, ``SHADER`` and module), so that the code layout's
table cannot name a file or shader that has moved.
"""

from __future__ import annotations

import importlib

from docutils import nodes
from sphinx.util.docutils import SphinxDirective

SOURCES = {
    "focused": ("pycinder.focused.frame.frames", "PASSES"),
    "broad": ("pycinder.focused.broad", "PASSES"),
    "scene": ("pycinder.wholescene.scene_frame", "PASS_INFOS"),
    "clearance": ("pycinder.focused.modes.clearance", "PASSES"),
    "hardclash": ("pycinder.focused.modes.hardclash", "PASSES"),
    "planner": ("pycinder.focused.plan.plan_gpu", "PASSES"),
    "robot": ("pycinder.robot.k2_pair_cull", "PASSES"),
}
"""Where each strategy lists its pass classes (module, attribute)."""

SCENE_CLASSES = ("pycinder.wholescene.raycast.RaycastPasses",
                 "pycinder.wholescene.filter.FilterPass",
                 "pycinder.wholescene.reduce.MipReduce")
"""The scene strategy's pass classes (its table lists :class:`PassInfo` rows, not classes)."""

FILES_HEADER = ("pass", "file", "shader", "class")
"""The columns of the ``pass-files`` table."""


def pass_classes() -> list[type]:
    """Every pass class of every strategy, each once, in the order the docs list strategies."""
    out: list[type] = []
    for key, (module, name) in SOURCES.items():
        if key != "scene":
            out += [c for c in getattr(importlib.import_module(module), name) if c not in out]
    for dotted in SCENE_CLASSES:
        module, name = dotted.rsplit(".", 1)
        out.append(getattr(importlib.import_module(module), name))
    return out


def pass_files() -> list[tuple[str, str, str, str]]:
    """One row of :data:`FILES_HEADER` per pass class: its pass code (or codes), its module's
    file under ``src/pycinder/``, its shader and its class."""
    rows = []
    for cls in pass_classes():
        infos = getattr(cls, "INFOS", None) or (cls.INFO,)
        codes = infos[0].number if len(infos) == 1 else f"{infos[0].number}-{infos[-1].number}"
        path = cls.__module__.removeprefix("pycinder.").replace(".", "/") + ".py"
        rows.append((codes, path, f"shaders/{cls.SHADER}.wgsl", cls.__name__))
    return rows


class PassTable(SphinxDirective):
    """The pass table of one strategy."""

    required_arguments = 1
    has_content = False

    def run(self) -> list[nodes.Node]:
        from pycinder.gpu.table import HEADER, rows

        module, name = SOURCES[self.arguments[0]]
        passes = getattr(importlib.import_module(module), name)
        return [_table(HEADER, rows(getattr(p, "INFO", p) for p in passes))]


class PassFiles(SphinxDirective):
    """Where every pass lives: pass code, file, shader, class."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        return [_table(FILES_HEADER, pass_files())]


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
    app.add_directive("pass-files", PassFiles)
    return {"parallel_read_safe": True, "parallel_write_safe": True}

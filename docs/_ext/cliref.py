"""``pycinder-cli``: the help text of ``pycinder`` and of each of its commands, from the parser.

Rendered at build time from :func:`pycinder.cli.build_parser` (each command's parser comes from
its module's ``add_parser``), so the reference follows the code.
"""

from __future__ import annotations

import argparse
import os

from docutils import nodes
from sphinx.util.docutils import SphinxDirective


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


class CliHelp(SphinxDirective):
    """Sections with ``pycinder --help`` and ``pycinder COMMAND --help``."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        from pycinder.cli import build_parser

        os.environ["COLUMNS"] = "100"  # argparse wraps at the terminal's width
        parser = build_parser()
        out: list[nodes.Node] = [nodes.literal_block(text=parser.format_help().rstrip())]
        for name, sub in _subcommands(parser).items():
            section = nodes.section(ids=[f"pycinder-{name}"])
            section += nodes.title(text=f"pycinder {name}")
            text = sub.format_help().rstrip()
            section += nodes.literal_block(text=text, language="text")
            out.append(section)
        return out


def setup(app):  # noqa: ANN001, ANN201
    app.add_directive("pycinder-cli", CliHelp)
    return {"parallel_read_safe": True, "parallel_write_safe": True}

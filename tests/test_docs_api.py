"""Every public name has an entry in the API pages (docs/api/*.md), so a new one cannot go
undocumented: an ``auto...`` directive naming it (``.. autoclass:: pycinder.Detector``)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

import pycinder
import pycinder.batch

API = Path(__file__).resolve().parents[1] / "docs" / "api"
ENTRY = re.compile(r"^\.\. auto(?:class|function|data|exception|method|attribute)::\s*(\S+)",
                   re.MULTILINE)


def documented() -> set[str]:
    names: set[str] = set()
    for page in sorted(API.glob("*.md")):
        names.update(ENTRY.findall(page.read_text(encoding="utf-8")))
    return names


def resolve(dotted: str) -> object:
    """The object a directive names: the longest importable module, then attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(dotted)


def _entries(module: object) -> list[str]:
    return [f"{module.__name__}.{name}" for name in module.__all__]


@pytest.mark.parametrize("name", _entries(pycinder) + _entries(pycinder.batch))
def test_public_name_has_an_entry(name: str) -> None:
    obj = resolve(name)
    short = name.rsplit(".", 1)[1]
    same = [e for e in documented() if e.rsplit(".", 1)[-1] == short and resolve(e) is obj]
    assert same, f"{name} has no entry in docs/api/*.md: add an auto... directive for it"


def test_cli_reference() -> None:
    assert "```{pycinder-cli}" in (API / "cli.md").read_text(encoding="utf-8")

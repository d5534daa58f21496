"""Every public name has an entry in the API pages (docs/api/*.md), so a new one cannot go
undocumented: an ``auto...`` directive naming it (``.. autoclass:: pycinder.Detector``)."""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
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


DOCS = API.parent
PAGES = [p for p in DOCS.rglob("*.md") if "_build" not in p.parts] + [
    DOCS.parent / "README.md", DOCS.parent / "benchmarks" / "README.md"]
MENTION = re.compile(r"(?<![\w./-])pycinder(?:\.\w+)+")
FROM_IMPORT = re.compile(r"from\s+(pycinder(?:\.\w+)*)\s+import\s+\(?([\w, ]+)")


def mentioned_paths() -> set[str]:
    """Every dotted path the docs and READMEs name (``pycinder.ifc.read_ifc``), and every name
    their examples import (``from pycinder.robot import Robot`` -> ``pycinder.robot.Robot``)."""
    names: set[str] = set()
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        names.update(MENTION.findall(text))
        for module, imported in FROM_IMPORT.findall(text):
            names.update(f"{module}.{n.strip()}" for n in imported.split(",") if n.strip())
    return names


@pytest.mark.parametrize("name", sorted(mentioned_paths()))
def test_documented_import_path_works(name: str) -> None:
    resolve(name)


@pytest.mark.parametrize("earlier", sorted(pycinder.MOVED))
def test_earlier_module_path_is_the_moved_module(earlier: str) -> None:
    """A module that moved imports under its earlier path as itself, in a fresh interpreter,
    every way a user writes it, and its classes pickle by their own module."""
    now = pycinder.MOVED[earlier]
    parent, short = earlier.rsplit(".", 1)
    code = f"""
import importlib, pickle, sys
import {earlier} as a
import {now} as b
from {parent} import {short} as c
import {parent}
assert a is b is c is sys.modules[{earlier!r}] is {earlier}, "not one module"
assert a.__name__ == a.__spec__.name == {now!r}, (a.__name__, a.__spec__.name)
classes = [v for v in vars(b).values() if isinstance(v, type) and v.__module__ == {now!r}]
assert all(pickle.loads(pickle.dumps(k)) is k for k in classes)
print(len(classes))
"""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr

"""The package's shape: its layers and the absence of circles, checked on its import graph.

The layers live in one place, ``[tool.importlinter]`` in pyproject.toml (drawn in the docs' How it
works page, which includes that section). import-linter checks them, and that no two modules of
any package import each other, even through others; grimp's graph of every module (its
``__init__`` included, imports inside functions and under ``TYPE_CHECKING`` counted) must have no
circle at all. The same checks run on a copy of the package with one circle added, and fail.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import grimp
import networkx as nx
import pytest

from pycinder.util.environ import path_first

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "pycinder"

MOST_LINES = 800
"""Most lines of one module of the package."""
MOST_TOP_MODULES = 15
"""Most modules directly in ``src/pycinder/`` (the rest live in subpackages)."""


def lint_imports(cwd: Path, pythonpath: Path | None = None) -> subprocess.CompletedProcess:
    """``lint-imports`` with the contracts of ``cwd``'s pyproject.toml, on the package found
    first on ``pythonpath`` (default: the installed one)."""
    env = None if pythonpath is None else path_first(pythonpath)
    return subprocess.run(
        [sys.executable, "-c", "from importlinter.cli import lint_imports_command as c; c()",
         "--config", "pyproject.toml", "--no-cache"],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def circles(package: str = "pycinder") -> list[list[str]]:
    """Every set of modules of ``package`` that import each other, directly or through others."""
    graph = grimp.build_graph(package, cache_dir=None)
    g = nx.DiGraph()
    for module in graph.modules:
        g.add_node(module)
        g.add_edges_from((module, other) for other in graph.find_modules_directly_imported_by(
            module))
    return sorted(sorted(c) for c in nx.strongly_connected_components(g) if len(c) > 1)


def test_the_layers_and_acyclic_contracts_hold() -> None:
    run = lint_imports(ROOT)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "0 broken" in run.stdout


def test_no_circle_between_modules() -> None:
    assert circles() == []


def test_modules_are_small_and_the_top_is_thin() -> None:
    long = {str(p.relative_to(PACKAGE)): n for p in PACKAGE.rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MOST_LINES}
    assert not long, f"modules over {MOST_LINES} lines: {long}"
    top = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(top) <= MOST_TOP_MODULES, top


@pytest.fixture(scope="module")
def circled(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the package and its contracts in which ``util.text``, at the bottom, imports
    the detector, which imports it back through the layers above."""
    root = tmp_path_factory.mktemp("circled")
    shutil.copytree(PACKAGE, root / "pycinder", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", root / "pyproject.toml")
    text = root / "pycinder" / "util" / "text.py"
    text.write_text(text.read_text(encoding="utf-8") + "\n\ndef _circle() -> None:\n"
                    "    from ..detector import Detector  # noqa: F401\n", encoding="utf-8")
    return root


def test_the_checks_fail_when_a_circle_is_added(circled: Path) -> None:
    run = lint_imports(circled, pythonpath=circled)
    assert run.returncode != 0
    out = run.stdout
    assert "BROKEN" in out and "pycinder.util.text -> pycinder.detector" in out, out
    found = subprocess.run(
        [sys.executable, "-c", "import test_layers; print(test_layers.circles())"],
        cwd=Path(__file__).parent, env=path_first(circled, Path(__file__).parent),
        capture_output=True, text=True, timeout=300)
    assert found.returncode == 0, found.stderr
    assert "pycinder.util.text" in found.stdout and "pycinder.detector" in found.stdout

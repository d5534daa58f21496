"""The package's shape: its layers and the absence of circles, checked on its import graph.

The layers live in one place, ``[tool.importlinter]`` in pyproject.toml (drawn in the docs' How it
works page, which includes that section). import-linter checks them, and that no two modules of
any package import each other, even through others; grimp's graph of every module (its
``__init__`` included, imports inside functions and under ``TYPE_CHECKING`` counted) must have no
circle at all. The same checks run on a copy of the package with one circle added, and fail.
"""

from __future__ import annotations

import re
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
MOST_CLI_LINES = 300
"""Most lines of one module of the command-line tool (one module per command)."""
SHADER_OWNERS = {"broad": "focused/broad", "plan": "focused/plan", "frame": "focused/frame",
                 "measure": "focused/measure", "wholescene": "wholescene", "robot": "robot",
                 "debug": "debug"}
"""Each shader's prefix and the folder of the package that owns it."""


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


def test_one_base_name_per_module() -> None:
    """No two modules of the package share a base name (``cull.py`` was three different things),
    and no module is named as another package (``batching.py`` beside ``batch/``,
    ``wholescene/frame.py`` beside ``focused/frame/``): a search for a name finds the one thing
    it names. A module may carry the name of the package that holds it (``robot/robot.py``)."""
    seen: dict[str, list[str]] = {}
    for path in PACKAGE.rglob("*.py"):
        if path.name not in ("__init__.py", "__main__.py"):
            seen.setdefault(path.stem, []).append(str(path.relative_to(PACKAGE)))
    assert not {n: p for n, p in seen.items() if len(p) > 1}
    packages = {p.parent.relative_to(PACKAGE) for p in PACKAGE.rglob("__init__.py")
                if p.parent != PACKAGE}
    for package in packages:
        named = [m for m in seen.get(package.name, []) if Path(m).parent != package]
        assert not named, f"{named} share a name with the package {package}"
    assert len({p.name for p in packages}) == len(packages), sorted(packages)


def test_every_shader_is_prefixed_by_its_owner() -> None:
    """``frame_cull.wgsl`` belongs to ``focused/frame``: every shader's name starts with its
    owner's, and its owner's folder names it (or a shader that does includes it)."""
    shaders = sorted((PACKAGE / "shaders").glob("*.wgsl"))
    assert shaders
    named = {}
    for owner, folder in SHADER_OWNERS.items():
        named[owner] = "".join(p.read_text(encoding="utf-8")
                               for p in (PACKAGE / folder).rglob("*.py"))
    wgsl = {p.stem: p.read_text(encoding="utf-8") for p in shaders}
    for path in shaders:
        owner = path.stem.split("_")[0]
        assert owner in SHADER_OWNERS and "_" in path.stem, f"{path.name} has no owner's prefix"
        used = f'"{path.stem}"' in named[owner] or any(
            f"//!include {path.stem}" in text for text in wgsl.values())
        assert used, f"{path.name}: nothing in {SHADER_OWNERS[owner]} or the shaders uses it"


def test_every_pass_names_its_file_and_shader() -> None:
    """The code layout's table (``.. pass-files::``): each pass class's module carries its pass
    code in its name, and its shader exists under its owner's prefix."""
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        import passtable
    finally:
        sys.path.remove(str(ROOT / "docs" / "_ext"))
    rows = passtable.pass_files()
    assert len(rows) >= 29
    for code, path, shader, _ in rows:
        assert (PACKAGE / path).is_file() and (PACKAGE / shader).is_file(), (code, path, shader)
        first = re.match(r"([BCFHKP])(\d+)", code)
        if first:
            # f7_f8_retry.py holds F7 and F8; b1_boxes.py holds B1 and the passes up to the next
            # file's first (B2, B3).
            letter, number = first.group(1).lower(), int(first.group(2))
            named = re.match(rf"{letter}(\d+)(?:_{letter}(\d+))?_", Path(path).stem)
            assert named, f"{path} does not carry the code of pass {code}"
            low, high = int(named.group(1)), int(named.group(2) or named.group(1))
            assert low <= number and (named.group(2) is None or number <= high), (code, path)
    page = (ROOT / "docs" / "guide" / "how-it-works.md").read_text(encoding="utf-8")
    assert "```{pass-files}" in page, "the code layout's table of passes left the docs"


def test_the_cli_is_one_small_module_per_command() -> None:
    cli = PACKAGE / "cli"
    assert cli.is_dir() and (cli / "__init__.py").is_file()
    long = {p.name: n for p in cli.glob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MOST_CLI_LINES}
    assert not long, f"cli modules over {MOST_CLI_LINES} lines: {long}"


def test_the_package_holds_no_benchmark() -> None:
    """The benchmark harness (timing peers, with the bench extra) lives beside its results in the
    checkout's ``benchmarks/``, not in the wheel; no module of the package imports it."""
    assert not (PACKAGE / "benchmarks").exists()
    graph = grimp.build_graph("pycinder", cache_dir=None)
    assert not [m for m in graph.modules if m.startswith("pycinder.benchmarks")]
    uses = [str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
            if re.search(r"^\s*(from|import) benchmarks\b", p.read_text(encoding="utf-8"), re.M)]
    assert uses in ([], ["cli/bench.py"]), uses


def test_the_tests_mirror_the_source() -> None:
    """A test of ``focused/plan`` lives in ``tests/focused/plan``: every folder of tests names a
    package of the source, but ``data`` (the files the tests read) and ``harness`` (the
    benchmark harness's tests, which lives in the checkout's ``benchmarks/``)."""
    tests = Path(__file__).resolve().parent
    folders = [p for p in tests.rglob("*") if p.is_dir() and "__pycache__" not in p.parts
               and p.relative_to(tests).parts[0] not in ("data", "harness")]
    assert folders
    for folder in folders:
        assert (PACKAGE / folder.relative_to(tests) / "__init__.py").is_file(), folder

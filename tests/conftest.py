import os
import re
from collections.abc import Iterator

os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")

import numpy as np
import pytest

import pycinder

OPTIONAL = {
    "manifold3d": "manifold3d (test, bench)", "fcl": "python-fcl (test, distance, bench)",
    "coal": "coal (test, bench)", "pymeshlab": "pymeshlab (test, scan)",
    "ifcopenshell": "ifcopenshell (bim)", "bcf": "bcf-client (bim)", "ifcclash": "ifcclash (bim)",
    "ray": "ray (cluster)", "pyarrow": "pyarrow (cluster)", "pygfx": "pygfx (test, demo)",
    "rendercanvas": "rendercanvas (test, demo)", "glfw": "glfw (demo)",
    "warp": "warp-lang (test, bench)", "pybullet": "pybullet (test, bench)",
    "pybullet_data": "pybullet (test, bench)", "yourdfpy": "yourdfpy (test, robot)",
    "scipy": "scipy (test, demo, bench)", "rtree": "rtree (test, demo, bench)",
    "networkx": "networkx (test, files, demo)", "lxml": "lxml (test, files)",
    "PIL": "pillow (test, demo)", "imageio": "imageio (test, demo)",
    "imageio_ffmpeg": "imageio-ffmpeg (test, demo)", "matplotlib": "matplotlib (test, bench)",
    "rich": "rich (demo, bench, cluster)", "sphinx": "sphinx (docs)", "numpydoc": "numpydoc (docs)",
    "myst_parser": "myst-parser (docs)", "build": "build (test)",
}
"""Packages outside pycinder's own dependencies, by module, with the package and the extras
that bring them: a test that needs one that is missing is skipped, naming it, so that the suite
runs with any subset of the extras (see :func:`_skip_when_optional_is_missing`)."""


def missing_optional(exc: BaseException) -> str | None:
    """The optional package (:data:`OPTIONAL`) whose absence ``exc`` (an ImportError, or one
    raised from one, as :func:`pycinder.util.optional.require` raises) reports, or None."""
    seen = 0
    while exc is not None and seen < 8:
        if isinstance(exc, ModuleNotFoundError):
            # trimesh re-raises a missing module's error from its message alone: no name
            name = exc.name or next(iter(re.findall(r"No module named '([\w.]+)'", str(exc))), "")
            root = name.split(".")[0]
            if root in OPTIONAL:
                return OPTIONAL[root]
        exc, seen = exc.__cause__ or exc.__context__, seen + 1
    return None


def _skip_when_optional_is_missing() -> Iterator[None]:
    try:
        return (yield)
    except ImportError as exc:
        package = missing_optional(exc)
        if package is None:
            raise
        pytest.skip(f"needs {package}, which is not installed")


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item: pytest.Item) -> Iterator[None]:
    """Fixtures that need a missing optional package skip their test, naming it."""
    return (yield from _skip_when_optional_is_missing())


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Iterator[None]:
    """A test that needs a missing optional package skips, naming it."""
    return (yield from _skip_when_optional_is_missing())


@pytest.fixture(scope="session")
def detector() -> pycinder.Detector:
    """The default detector (focused strategy, default tolerance), reused across tests."""
    return pycinder.Detector()


@pytest.fixture(scope="session")
def bunny():
    from pycinder.testing import bunny as load

    return load()


def assert_matches_truth(found: np.ndarray, truth, *, context: str = "") -> dict:
    """Every pair that must be found is found, and no separate pair is reported."""
    score = truth.score(found)
    assert not score["false"], f"{context}: separate pairs reported: {score['false']}"
    assert not score["missed"], f"{context}: pairs that must be found were missed: {score['missed']}"
    return score


def pytest_terminal_summary(terminalreporter) -> None:
    """One line per test that compared stored answers, saying which comparison it made (bit
    for bit or within bounds: see ``tests/test_answers.py``)."""
    lines = [f"{report.nodeid}: compared {value}"
             for reports in terminalreporter.stats.values() for report in reports
             if getattr(report, "when", None) == "call"
             for name, value in getattr(report, "user_properties", ()) if name == "comparison"]
    if lines:
        terminalreporter.write_sep("-", "stored answers")
        for line in lines:
            terminalreporter.write_line(line)

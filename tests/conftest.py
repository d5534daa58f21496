import math
import os
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")

import numpy as np
import pytest
import trimesh

import pycinder
from pycinder import testing as exact

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


SURFACE_SAMPLES = 1500
"""Surface points of an open body tested for lying inside a solid (besides its vertices)."""


def _depth_inside(solid: trimesh.Trimesh, other: trimesh.Trimesh) -> float:
    """How deep the deepest of ``other``'s surface points (its vertices and evenly sampled
    points) lies inside the closed ``solid`` (negative: none inside)."""
    points = np.vstack([other.vertices, trimesh.sample.sample_surface_even(
        other, SURFACE_SAMPLES, seed=0)[0]])
    return float(np.max(trimesh.proximity.signed_distance(solid, points)))


@dataclass(frozen=True)
class Geometry:
    """The bodies of one answer's query, to judge by exact geometry a pair on which two answers
    differ: where the tolerance contract (``docs/tolerance.md``) lets it go either way.

    meshes : the query's bodies (trimesh meshes or (vertices, faces) pairs)
    transforms : their (4, 4) world-from-body transforms
    tolerance : the query's tolerance; None: the documented default of each pair
    """

    meshes: Sequence
    transforms: Sequence | np.ndarray
    tolerance: float | None = None

    def verdict(self, i: int, j: int) -> str:
        """``"apart"`` (at least ``t`` apart: never to be reported), ``"deep"`` (at least
        ``2 t`` deep: always to be reported) or ``"band"`` (in between: either answer keeps the
        contract) for bodies ``i`` and ``j`` at their pair's tolerance ``t``.

        Two solids are judged as the benchmarks score (:func:`pycinder.testing.ground_truth`:
        manifold3d's volume and distance, and a surface point ``2 t`` inside, which proves the
        depth; a depth it cannot prove is left in the band). With an open body, by the
        surfaces' exact distance (python-fcl), an edge crossing the other's surface with both
        ends ``2 t`` from it, and, for a solid, how deep the other's surface lies inside it."""
        t = float(exact.mesh_pair_tolerances(self.meshes, self.transforms,
                                            np.array([[i, j]]), self.tolerance)[0])
        a = exact.world_mesh(self.meshes[i], self.transforms[i])
        b = exact.world_mesh(self.meshes[j], self.transforms[j])
        if a.is_volume and b.is_volume:
            truth = exact.ground_truth([a, b], None, tolerance=t)
            return "deep" if len(truth.overlap) else "apart" if len(truth.separate) else "band"
        inside = max((_depth_inside(s, o) for s, o in ((a, b), (b, a)) if s.is_volume),
                     default=-math.inf)
        distance = exact.surface_distance(a, b)
        if distance >= t and inside <= 0.0:
            return "apart"
        if inside >= 2 * t or (distance <= 0.0 and exact.crosses_deeply(a, b, 2 * t)):
            return "deep"
        return "band"

    def verdicts(self, pairs: np.ndarray) -> list[str]:
        """:meth:`verdict` of each pair of ``pairs`` (K, 2)."""
        return [self.verdict(i, j) for i, j in np.asarray(pairs, np.int64).tolist()]


class CommandCount:
    """Counts pycinder's own queue submissions and buffer maps from here on (``submits``,
    ``maps``), through ``monkeypatch``."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        import sys

        from pycinder.gpu.buffers import Readback

        self.submits = self.maps = 0
        queue_type = type(pycinder.Detector().gpu.device.queue)
        submit = queue_type.submit
        start = Readback.start  # every map of pycinder's is asked for here

        def counted_submit(queue, *args, **kwargs):
            # wgpu-py itself submits an empty command buffer before a buffer's first map for
            # reading (a driver workaround); count pycinder's own submissions.
            if "pycinder" in sys._getframe(1).f_code.co_filename:
                self.submits += 1
            return submit(queue, *args, **kwargs)

        def counted_map(readback, *args, **kwargs):
            self.maps += 1
            return start(readback, *args, **kwargs)

        monkeypatch.setattr(queue_type, "submit", counted_submit)
        monkeypatch.setattr(Readback, "start", counted_map)

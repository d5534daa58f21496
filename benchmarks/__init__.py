"""Benchmarks against python-fcl, coal, NVIDIA Warp, trimesh and IfcClash: ``pycinder bench``.

The harness runs from a checkout of the repository and is not in the wheel: ``pip install -e
".[bench]"``, then ``python -m benchmarks.hostcpu`` (or any module's ``--help``) from the
repository's root, or ``pycinder bench``. Scenes and their exact truth are in
:mod:`pycinder.testing` (:mod:`pycinder.testing.scenes`, :mod:`pycinder.testing.robots`,
:mod:`pycinder.testing.buildings`), which the tests share; the peer systems are in
:mod:`.peers`, the loop that times them interleaved on the same frames in :mod:`.runner`, and
the report (JSON, Markdown, plots) in :mod:`.report`. Needs the ``bench`` extra.
"""

from __future__ import annotations

from pathlib import Path

from pycinder.util.environ import path_first

ROOT = Path(__file__).resolve().parents[1]
"""The checkout's root, which holds this package: where the benchmarks' fresh processes find
it."""


def checkout_env() -> dict[str, str]:
    """This process's environment with the checkout's root first on ``PYTHONPATH``, so that a
    fresh process (``python -m benchmarks.soak``, ...) imports this harness wherever it runs."""
    return path_first(ROOT)

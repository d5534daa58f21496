"""``pycinder bench [SCENE...]``: time pycinder against python-fcl, coal, trimesh and Warp.

The harness is the top-level package ``benchmarks`` of the repository, not part of the wheel:
the command runs from a checkout (``pip install -e ".[bench]"``), whose root it finds from the
package's own path (:func:`checkout_root`), and elsewhere exits 2 saying so
(:data:`NOT_IN_THE_WHEEL`).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

from .common import add_progress, progress

NOT_IN_THE_WHEEL = (
    "the benchmarks are not in the wheel: they run from a checkout of the repository (none "
    "holds this pycinder, {package}). Clone the repository, run pip install -e \".[bench]\" in "
    "it, and run pycinder bench (or make bench) there")
"""The error of ``pycinder bench`` where pycinder is not installed from a checkout."""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``bench`` command to the ``pycinder`` command's subparsers."""
    p = subparsers.add_parser("bench", help="time pycinder against python-fcl, coal, trimesh "
                                            "and Warp")
    p.add_argument("scenes", nargs="*", metavar="SCENE",
                   help="floor, stairs, many, deforming, narrow, sweep-extent, sweep-bodies, "
                        "sweep-triangles, sweep-tolerance, manager, contacts, contract, modes, "
                        "batch, broadphase, hostcpu, soak, building, building-small "
                        "(default: all but the building benchmarks, which need "
                        "'pycinder[bim]'; the soak alone takes several minutes)")
    p.add_argument("--repeat", type=int, default=5, help="frames timed per scene")
    p.add_argument("--peers", nargs="*", default=["python-fcl", "coal", "trimesh", "warp"],
                   help="systems to compare (default: python-fcl coal trimesh warp); one that "
                        "is not installed is left out and named")
    p.add_argument("--soak-frames", type=int, default=100_000,
                   help="frames of the memory soak (scene 'soak')")
    p.add_argument("--out", default="benchmarks/results", metavar="DIR",
                   help="folder for the results' JSON, Markdown and plots (default "
                        "benchmarks/results)")
    p.add_argument("--stem", default="results", help="file name stem of the JSON and Markdown")
    add_progress(p)
    p.set_defaults(func=cmd_bench, strict=False, json=False)
    return p


def package_dir() -> Path:
    """The folder of the ``pycinder`` package this command runs from."""
    import pycinder

    return Path(pycinder.__file__).resolve().parent


def checkout_root(package: Path | None = None) -> Path | None:
    """The root of the repository checkout that holds ``package`` (default: this pycinder's
    folder, :func:`package_dir`) in its ``src`` layout: the folder two levels above it, where
    ``pyproject.toml`` and ``benchmarks/runner.py`` are; None for an installed wheel."""
    root = (package or package_dir()).parents[1]
    if (root / "pyproject.toml").is_file() and (root / "benchmarks" / "runner.py").is_file():
        return root
    return None


def _harness_importable() -> bool:
    """Whether ``benchmarks.runner`` imports as it is (the checkout's root on ``sys.path``)."""
    try:
        return importlib.util.find_spec("benchmarks.runner") is not None
    except ImportError:  # no package named benchmarks, or a module of that name
        return False


def load_harness() -> tuple[ModuleType, ModuleType]:
    """The harness's ``benchmarks.runner`` and ``benchmarks.report``, importing them from this
    pycinder's checkout (:func:`checkout_root`, put first on ``sys.path``) when they do not
    import as they are.

    Raises
    ------
    RuntimeError
        Where pycinder is not installed from a checkout (:data:`NOT_IN_THE_WHEEL`).
    """
    if not _harness_importable():
        root = checkout_root()
        if root is None:
            raise RuntimeError(NOT_IN_THE_WHEEL.format(package=package_dir()))
        sys.path.insert(0, str(root))
        for name in [n for n in sys.modules if n.split(".")[0] == "benchmarks"]:
            del sys.modules[name]  # another package named benchmarks, or a stale namespace
    return (importlib.import_module("benchmarks.runner"),
            importlib.import_module("benchmarks.report"))


def cmd_bench(args: argparse.Namespace) -> int:
    """Run the benchmarks' scenes (default: :data:`benchmarks.runner.DEFAULT_SCENES`), write the
    results' JSON, Markdown and plots in ``--out`` and print their paths; return 0."""
    runner, report = load_harness()
    scenes = args.scenes or runner.DEFAULT_SCENES
    report.require_matplotlib()  # before a long run, not after it
    options = {"repeat": args.repeat, "peers": args.peers, "soak_frames": args.soak_frames}
    enabled = args.progress
    with progress(enabled, "benchmarks") as update:
        shown = enabled if enabled is not None else sys.stderr.isatty()

        def note(msg: str) -> None:
            update(0, 0, msg)
            if not shown:
                print(msg, flush=True)

        results = runner.run(scenes, **options, progress=note)
    for p in report.write(results, args.out, stem=args.stem):
        print(f"wrote {p}")
    return 0

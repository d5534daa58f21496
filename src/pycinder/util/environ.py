"""The environment of a child Python process that must import a given source tree first."""

from __future__ import annotations

import os
from pathlib import Path


def path_first(*first: str | os.PathLike[str]) -> dict[str, str]:
    """This process's environment with ``first`` ahead of its own ``PYTHONPATH`` entries: a
    package found there wins, and what this process imports from its ``PYTHONPATH`` (packages
    installed with ``pip install --target`` and put on the path, as on a machine without a
    package index) is still found by the child.

    Parameters
    ----------
    *first : path
        Folders to search first, in order.

    Returns
    -------
    dict of str to str
    """
    kept = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    return {**os.environ,
            "PYTHONPATH": os.pathsep.join([*(str(Path(p)) for p in first), *kept])}


__all__ = ["path_first"]

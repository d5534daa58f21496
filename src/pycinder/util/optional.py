"""Optional dependencies, imported on first use, with the extra that installs them."""

from __future__ import annotations

import importlib
from types import ModuleType


def require(module: str, needed_for: str, extra: str, package: str | None = None) -> ModuleType:
    """Import ``module``, or raise an ImportError that says what needs it and how to install it.

    Parameters
    ----------
    module : str
        The module to import (``"fcl"``, ``"PIL.ImageDraw"``, ...).
    needed_for : str
        What needs it, to start the message ("CollisionManager.min_distance_*"; a file's name
        first where a file needs it: "parts.3mf: reading 3MF files").
    extra : str
        The pycinder extra that brings it (``"distance"``, ``"bench"``, ...).
    package : str, optional
        The package's name on PyPI, where it differs from the module's.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        name = package or module.split(".")[0]
        raise ImportError(f"{needed_for} needs {name}: pip install 'pycinder[{extra}]' (from a "
                          f"clone: pip install '.[{extra}]')") from exc

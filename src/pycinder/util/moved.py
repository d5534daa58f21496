"""Modules that moved keep their earlier import paths: ``import pycinder.ifc`` gives the module
that now lives at ``pycinder.bim.ifc`` (the same module object, not a copy), so code, pickles
and docs written against the earlier path keep working.

:func:`install` puts a finder on ``sys.meta_path`` that answers only for the earlier names; the
package's ``__getattr__`` calls :func:`attribute` so that ``pycinder.ifc`` works as an attribute
too. Both import the new module on first use, so start-up imports nothing more.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
from collections.abc import Mapping
from types import ModuleType


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds each earlier name and loads it as the module at its new name."""

    def __init__(self, moved: Mapping[str, str]) -> None:
        self.moved = dict(moved)
        self._own_specs: dict[str, importlib.machinery.ModuleSpec | None] = {}

    def find_spec(self, name: str, path: object = None,
                  target: object = None) -> importlib.machinery.ModuleSpec | None:
        if name not in self.moved:
            return None
        return importlib.machinery.ModuleSpec(name, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        module = importlib.import_module(self.moved[spec.name])
        self._own_specs[spec.name] = module.__spec__
        return module

    def exec_module(self, module: ModuleType) -> None:
        # The module ran when it was imported at its new name. The import system has just set its
        # __spec__ to the earlier name's spec: give it back its own.
        module.__spec__ = self._own_specs[module.__spec__.name]


def install(moved: Mapping[str, str]) -> None:
    """Answer the earlier names in ``moved`` (earlier name -> new name) from now on."""
    if not any(isinstance(f, _MovedFinder) and f.moved == dict(moved) for f in sys.meta_path):
        sys.meta_path.append(_MovedFinder(moved))


def attribute(package: str, moved: Mapping[str, str], name: str) -> ModuleType:
    """``package.name`` where ``package.name`` is an earlier name in ``moved`` (for the package's
    module-level ``__getattr__``); AttributeError for any other name."""
    full = f"{package}.{name}"
    if full in moved:
        return importlib.import_module(full)
    raise AttributeError(f"module {package!r} has no attribute {name!r}")

"""Warnings and errors that pycinder raises for bad input, and how warnings find the user's line."""

from __future__ import annotations

import os
import sys
import warnings

_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


class OpenMeshWarning(UserWarning):
    """A body is not a closed, consistently oriented surface, or is wound inside out: ray counts
    through it can be wrong."""


class DegenerateFaceWarning(UserWarning):
    """A body has faces of zero area."""


class ClippedBodyWarning(UserWarning):
    """A user view's near or far plane cuts a body."""


class LossWarning(UserWarning):
    """A lossy option may have dropped collisions; the result's stats say how many."""


def _stacklevel() -> int:
    """The stack level of the first frame outside pycinder, so a warning points at user code."""
    frame = sys._getframe(2)
    level = 2
    while frame is not None:
        path = os.path.abspath(frame.f_code.co_filename)
        if not path.startswith(_PACKAGE_DIR + os.sep):
            return level
        frame = frame.f_back
        level += 1
    return level


def warn_at_caller(message: str, category: type[Warning]) -> None:
    """``warnings.warn`` with the stack level of the first caller outside the package."""
    warnings.warn(message, category, stacklevel=_stacklevel())


class GpuError(RuntimeError):
    """The GPU could not do what a query asked; the message says what and what to do."""


class GpuTimeoutError(GpuError):
    """A wait on the GPU passed its deadline (``CollisionRequest.timeout``)."""


class GpuMemoryError(GpuError, MemoryError):
    """A query needs more GPU memory than the device allows, or than ``memory_budget`` permits
    where it cannot be split into rounds."""


class PrecisionWarning(UserWarning):
    """A pair's bodies are too large for its tolerance in single precision: its tolerance was
    raised to what the GPU can resolve (only for default tolerances)."""

"""Warnings and errors that pycinder raises for bad input, and how warnings find the user's line."""

from __future__ import annotations

import os
import sys
import warnings

_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


class MeshWarning(UserWarning):
    """Something about the meshes of some bodies, and the rule applied to them: one warning a
    kind of problem per query, however many bodies have it.

    Parameters
    ----------
    message : str
        The summary: how many bodies, the first few by name, the rule and the repair.
    bodies : sequence of str, optional
        Every body concerned, by label (``body 4 ('Wall [2Xy...]')``).
    details : sequence of str, optional
        What each has, in the order of ``bodies`` (``"2 boundary edges (holes)"``).
    summary : str, optional
        The message in one short line, naming no body (``"3 bodies are open: tested as
        surfaces"``); default the message.

    Attributes
    ----------
    bodies : list of str
    details : list of str
    summary : str
    """

    def __init__(self, message: str, bodies: list[str] | None = None,
                 details: list[str] | None = None, summary: str | None = None) -> None:
        super().__init__(message)
        self.bodies = list(bodies or [])
        self.details = list(details or [])
        self.summary = summary or message


class OpenMeshWarning(MeshWarning):
    """Bodies are not closed, consistently oriented surfaces (tested as surfaces, or as solids
    where their edges balance), or are wound inside out: ray counts through them can be wrong."""


class RewoundMeshWarning(MeshWarning):
    """Closed bodies were wound inconsistently: each was wound again, outward, and is tested as
    a solid."""


class DegenerateFaceWarning(MeshWarning):
    """Bodies have faces of zero area, or faces that repeat a vertex index."""


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


def warn_at_caller(message: str | Warning, category: type[Warning] | None = None) -> None:
    """``warnings.warn`` with the stack level of the first caller outside the package (a
    message and its category, or a warning instance)."""
    if isinstance(message, Warning):
        warnings.warn(message, stacklevel=_stacklevel())
    else:
        warnings.warn(message, category, stacklevel=_stacklevel())


class GpuError(RuntimeError):
    """The GPU could not do what a query asked; the message says what and what to do."""


class GpuTimeoutError(GpuError):
    """A wait on the GPU passed its deadline (``CollisionRequest.timeout``).

    The message says what was waited for, whether the device was lost, which passes the
    submission held and whether the GPU started and finished it (see
    :mod:`pycinder.gpu.watch`).

    Attributes
    ----------
    device_lost : bool or None
        Whether the device was lost (None where nothing was known).
    progress : str or None
        Whether the GPU started and finished the submission waited for, in words.
    """

    def __init__(self, message: str, *, device_lost: bool | None = None,
                 progress: str | None = None) -> None:
        super().__init__(message)
        self.device_lost = device_lost
        self.progress = progress

    def __reduce__(self) -> tuple:
        return _rebuild_timeout, (str(self), self.device_lost, self.progress)


def _rebuild_timeout(message: str, device_lost: bool | None, progress: str | None
                     ) -> GpuTimeoutError:
    return GpuTimeoutError(message, device_lost=device_lost, progress=progress)


class GpuDeviceLostError(GpuError):
    """The GPU device was lost (the driver reset it, or it was destroyed) while a query used it:
    the detector that raised it has made a new device and can be used again."""


def with_message(exc: BaseException, message: str, lost: bool = False) -> GpuError:
    """``exc`` as a :class:`GpuError` of its own type (or :class:`GpuError` for another
    exception) with ``message``, keeping a :class:`GpuTimeoutError`'s attributes; a
    :class:`GpuDeviceLostError` where the device was ``lost`` (as the caller found) or ``exc``
    says so, unless it is a timeout (which says it in its ``device_lost``)."""
    if isinstance(exc, GpuTimeoutError):
        return GpuTimeoutError(message, device_lost=exc.device_lost or lost,
                               progress=exc.progress)
    text = str(exc).lower()
    if lost or "device is lost" in text or "device was lost" in text:
        return GpuDeviceLostError(message)
    if isinstance(exc, GpuError):
        return type(exc)(message)
    return GpuError(message)


class GpuMemoryError(GpuError, MemoryError):
    """A query needs more GPU memory than the device allows, or than ``memory_budget`` permits
    where it cannot be split into rounds."""


class PrecisionWarning(UserWarning):
    """A pair's bodies are too large for its tolerance in single precision: its tolerance was
    raised to what the GPU can resolve (only for default tolerances)."""

"""Keep the libraries below pycinder from printing on correct runs, without hiding real errors.

Two lines reached stderr on every correct run:

* ``error: XDG_RUNTIME_DIR is invalid or not set in the environment.`` (twice). libwayland-client
  prints it from ``wl_display_connect``, which Mesa's Vulkan device-selection layer
  (``VK_LAYER_MESA_device_select``, an implicit layer) calls while wgpu enumerates Vulkan devices,
  to find the GPU that drives a Wayland display. Without ``XDG_RUNTIME_DIR`` there is no Wayland
  session to find, so that probe can only fail: in that case, and unless the user configured the
  layer (``MESA_VK_DEVICE_SELECT``) or disabled it already, :func:`quiet_native_probes` sets the
  loader's documented switch ``NODEVICE_SELECT=1`` for this process, before wgpu creates its
  instance. wgpu still chooses its adapter by power preference; nothing else changes.
* ``Forcing backend: OpenGL (7)``: wgpu-py's log line when ``WGPU_BACKEND_TYPE`` is set. The user
  asked for that backend, and ``stats.adapter`` names it; :class:`_ForcedBackendNote` drops
  exactly that record from the ``wgpu`` logger, and every other warning of wgpu still shows.
"""

from __future__ import annotations

import logging
import os


class _ForcedBackendNote(logging.Filter):
    """Drops wgpu-py's note that ``WGPU_BACKEND_TYPE`` forced a backend (only that record)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith("Forcing backend:")


_FILTER = _ForcedBackendNote()


def wayland_session_possible(environ: dict[str, str] | os._Environ[str] = os.environ) -> bool:
    """Whether libwayland could find a display socket: it needs an absolute ``XDG_RUNTIME_DIR``,
    or an absolute ``WAYLAND_DISPLAY``."""
    return environ.get("XDG_RUNTIME_DIR", "").startswith("/") or \
        environ.get("WAYLAND_DISPLAY", "").startswith("/")


def quiet_native_probes() -> None:
    """Apply both measures of the module's doc (idempotent); run before wgpu makes its
    instance, which ``import pycinder`` does."""
    if not wayland_session_possible() and "MESA_VK_DEVICE_SELECT" not in os.environ:
        os.environ.setdefault("NODEVICE_SELECT", "1")
    logger = logging.getLogger("wgpu")
    if _FILTER not in logger.filters:
        logger.addFilter(_FILTER)

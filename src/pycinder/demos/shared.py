"""One wgpu device for the demos: pygfx draws on the device the detector computes on.

pycinder asks wgpu to configure its *default* device for both libraries
(:func:`pycinder.share_default_device`), which must happen before anything creates that device:
before the first pygfx renderer and the first :class:`~pycinder.Detector` of the process.
:func:`shared_device` does it once per process; every demo calls it first.
"""

from __future__ import annotations

from types import ModuleType

import wgpu

from ..gpu.device import fit_default_device_to_adapter, get_gpu, share_default_device

INSTALL_HINT = ("the demos draw with pygfx and rendercanvas: pip install 'pycinder[demo]' "
                "(from a clone: pip install '.[demo]')")

_device: wgpu.GPUDevice | None = None


def import_pygfx() -> ModuleType:
    """pygfx, imported on first use, or an ImportError that says what to install."""
    try:
        import pygfx
        import rendercanvas  # noqa: F401  (the canvases)
    except ImportError as exc:
        raise ImportError(f"{INSTALL_HINT} ({exc})") from exc
    return pygfx


def shared_device() -> wgpu.GPUDevice:
    """wgpu's default device, configured for pycinder and pygfx, created on the first call.

    Raises
    ------
    ImportError
        pygfx or rendercanvas is missing.
    RuntimeError
        Something created wgpu's default device before the demos could configure it, or the
        adapter cannot give pygfx what it needs (the message names the backend).
    """
    global _device
    if _device is not None:
        return _device
    import_pygfx()  # pygfx adds its own needs to the default device's configuration on import
    try:
        share_default_device()
    except RuntimeError as exc:
        raise RuntimeError(
            "wgpu's default device was created before the demo could configure it for both "
            f"pycinder and pygfx; start the demo in a fresh process ({exc})") from exc
    adapter = fit_default_device_to_adapter("pycinder demos")
    try:
        device = wgpu.get_default_device()
    except Exception as exc:  # wgpu raises different types per backend
        backend = adapter.info["backend_type"]
        raise RuntimeError(f"the demos cannot create a device for pygfx on the {backend} "
                           f"backend: {exc}") from exc
    get_gpu()  # pycinder checks the shared device offers what it needs, and says if not
    _device = device
    return device

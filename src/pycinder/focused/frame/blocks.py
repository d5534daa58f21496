"""Parameter blocks: the uniforms of a frame's passes, written by field name.

Each pass declares its parameters as a :class:`~pycinder.gpu.structs.Struct`. A
:class:`ParamBlocks` holds, in one uniform buffer, one block per name (several names may share a
struct: the retry round's copy of a pass's parameters), repeated ``copies`` times (once per
round), each :data:`~pycinder.gpu.bindings.PARAM_STRIDE` bytes from the next so that a pass
binds its own block at its offset.
"""

from __future__ import annotations

import numpy as np
import wgpu

from ...gpu.bindings import PARAM_STRIDE
from ...gpu.buffers import GrowableBuffer
from ...gpu.structs import Struct


class ParamBlocks:
    """Named parameter blocks in one uniform buffer, made once and rewritten every frame.

    Parameters
    ----------
    device : wgpu.GPUDevice
    label : str
    structs : dict of str to Struct
        The blocks of one copy, by name.
    indirect : bool
        Blocks may hold indirect dispatch arguments (see :meth:`indirect`).
    """

    def __init__(self, device: wgpu.GPUDevice, label: str, structs: dict[str, Struct],
                 indirect: bool = False) -> None:
        for name, struct in structs.items():
            if struct.size > PARAM_STRIDE:
                raise ValueError(f"{label}: {name} ({struct.name}, {struct.size} bytes) is over "
                                 f"a parameter block's {PARAM_STRIDE} bytes")
        self.device = device
        self.structs = dict(structs)
        self._index = {name: k for k, name in enumerate(structs)}
        usage = wgpu.BufferUsage.UNIFORM | wgpu.BufferUsage.COPY_DST
        self.buffer = GrowableBuffer(device, label, usage | wgpu.BufferUsage.INDIRECT
                                     if indirect else usage)
        self.host = np.zeros((1, len(structs), PARAM_STRIDE), dtype=np.uint8)
        self._views: dict[tuple[str, int], np.ndarray] = {}
        """The structured views of :meth:`__call__`, made once per host copy."""

    def begin(self, copies: int = 1) -> None:
        """Start a frame of ``copies`` copies of every block, all fields zero."""
        copies = max(int(copies), 1)
        if self.host.shape[0] != copies:
            self.host = np.zeros((copies, len(self.structs), PARAM_STRIDE), dtype=np.uint8)
            self._views = {}
        else:
            self.host[:] = 0
        self.buffer.ensure(self.host.nbytes)

    def __call__(self, name: str, copy: int = 0) -> np.ndarray:
        """Block ``name`` of copy ``copy``, to write by field name (a one-element structured
        array of its struct, viewing the host copy)."""
        view = self._views.get((name, copy))
        if view is None:
            struct = self.structs[name]
            view = self.host[copy, self._index[name], :struct.size].view(struct.dtype)
            self._views[(name, copy)] = view
        return view

    def write(self) -> None:
        """Upload every block of the frame."""
        self.device.queue.write_buffer(self.buffer.buffer, 0, self.host)

    def indirect(self, name: str, copy: int, field: str) -> tuple[wgpu.GPUBuffer, int]:
        """``(buffer, offset)`` of the indirect dispatch arguments (three u32 fields, ``field``
        the first) in block ``name`` of copy ``copy`` (blocks made with ``indirect=True``)."""
        offset = (copy * len(self.structs) + self._index[name]) * PARAM_STRIDE
        return self.buffer.buffer, offset + self.structs[name].offset(field)

    def binding(self, name: str, copy: int = 0) -> tuple[wgpu.GPUBuffer, int, int]:
        """``(buffer, offset, size)`` of one block, to bind as a uniform."""
        offset = (copy * len(self.structs) + self._index[name]) * PARAM_STRIDE
        return self.buffer.buffer, offset, -(-self.structs[name].size // 16) * 16


__all__ = ["ParamBlocks"]

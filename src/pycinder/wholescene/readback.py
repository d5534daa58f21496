"""How the whole-scene strategy brings its records back (paper 4.3.2), one small class per mode.

Each mode says which output of the self-interference filter it needs, which passes it adds on
the GPU after the filter (:attr:`ReadbackMode.passes`, encoded by the frame), which buffer and
how many bytes it reads, and how those bytes become records.
All modes first read the filter's 16-byte counters, and stop there when nothing survived: the
paper's occlusion-query early-out (4.3.2.3).

=========  ==============  =========================================  ==========================
mode       filter output   reads                                      lossless
=========  ==============  =========================================  ==========================
full       the image       the whole filtered image                   yes
compact    appended rows   the surviving records (16 bytes each)      yes
mipmap     packed image    level ``mipmap_levels`` of the 2x2 chain   no: ``possibly_lost``
adaptive   packed image    the deepest level that merged no two pairs yes
=========  ==============  =========================================  ==========================
"""

from __future__ import annotations

import numpy as np
import wgpu

from ..gpu.device import Gpu
from ..records import decode_compact, decode_image
from ..request import CollisionRequest
from ..result import Stats
from .filter import COUNTERS_BYTES, RECORD_BYTES, FilterPass
from .reduce import MipReduce


class ReadbackMode:
    """A readback mode of the whole-scene strategy.

    Parameters
    ----------
    gpu : Gpu
    width, height : int
        The resolution.
    request : CollisionRequest
    """

    name = ""
    filter_output = "compact"
    """Which entry point of ``wholescene_filter.wgsl`` writes what this mode reads."""

    def __init__(self, gpu: Gpu, width: int, height: int, request: CollisionRequest) -> None:
        self.gpu, self.width, self.height = gpu, width, height
        self.passes: tuple[MipReduce, ...] = ()
        """Passes the frame encodes after the filter, in order."""

    def copy_header(self, encoder: wgpu.GPUCommandEncoder, filter_pass: FilterPass,
                    staging: wgpu.GPUBuffer) -> int:
        """Record the copy of the header (the filter's counters first) into ``staging``.

        Returns the bytes of ``staging`` to read: :attr:`header_bytes`.
        """
        encoder.copy_buffer_to_buffer(filter_pass.counters, 0, staging, 0, COUNTERS_BYTES)
        return COUNTERS_BYTES

    @property
    def header_bytes(self) -> int:
        return COUNTERS_BYTES

    def source(self, filter_pass: FilterPass, header: np.ndarray, survivors: int, stats: Stats
               ) -> tuple[wgpu.GPUBuffer, int]:
        """The buffer to read and how many bytes of it."""
        raise NotImplementedError

    def decode(self, data: np.ndarray, view_index: int, encode: str, edge_start: np.ndarray
               ) -> np.ndarray:
        """Records from the bytes read."""
        rows = data.reshape(-1, 4)
        rows = rows[rows[:, 1] != 0]  # packed images are zero where nothing survived
        return decode_compact(rows, self.width, view_index, encode, edge_start)


class Full(ReadbackMode):
    name = "full"
    filter_output = "full"

    def source(self, filter_pass, header, survivors, stats):
        return filter_pass.out.buffer, self.width * self.height * RECORD_BYTES

    def decode(self, data, view_index, encode, edge_start):
        return decode_image(data, self.width, view_index, encode, edge_start)


class Compact(ReadbackMode):
    name = "compact"
    filter_output = "compact"

    def source(self, filter_pass, header, survivors, stats):
        return filter_pass.out.buffer, survivors * RECORD_BYTES

    def decode(self, data, view_index, encode, edge_start):
        return decode_compact(data, self.width, view_index, encode, edge_start)


class Mipmap(ReadbackMode):
    """Keep one record per 2x2 block, ``mipmap_levels`` times (4.3.2.2): lossy, and every block
    where two different pairs met is counted in ``stats.possibly_lost``."""

    name = "mipmap"
    filter_output = "packed"

    def __init__(self, gpu: Gpu, width: int, height: int, request: CollisionRequest) -> None:
        super().__init__(gpu, width, height, request)
        self.reduce = MipReduce(gpu, width, height, self.levels(request))
        self.passes = (self.reduce,)

    def levels(self, request: CollisionRequest) -> int:
        return int(request.mipmap_levels)

    @property
    def header_bytes(self) -> int:
        lost_bytes = 4 * (self.reduce.levels + 1)
        return COUNTERS_BYTES + -(-lost_bytes // 8) * 8

    def copy_header(self, encoder, filter_pass, staging):
        super().copy_header(encoder, filter_pass, staging)
        encoder.copy_buffer_to_buffer(self.reduce.lost, 0, staging, COUNTERS_BYTES,
                                      4 * (self.reduce.levels + 1))
        return self.header_bytes

    def lost(self, header: np.ndarray) -> np.ndarray:
        """Cumulative count of blocks that merged two pairs, per level (levels + 1,)."""
        n = self.reduce.levels + 1
        return np.cumsum(header[COUNTERS_BYTES // 4:COUNTERS_BYTES // 4 + n].astype(np.int64))

    def level(self, header: np.ndarray, stats: Stats) -> int:
        stats.possibly_lost = int(self.lost(header)[self.reduce.levels])
        return self.reduce.levels

    def source(self, filter_pass, header, survivors, stats):
        level = self.level(header, stats)
        stats.mip_level = level
        if level == 0:
            return filter_pass.out.buffer, self.width * self.height * RECORD_BYTES
        return self.reduce.level_buffer(level), self.reduce.level_bytes(level)


class Adaptive(Mipmap):
    """Reduce only as far as no block merged two pairs (4.3.2.3's loss colour, as a counter)."""

    name = "adaptive"

    def levels(self, request: CollisionRequest) -> int:
        return max(1, int(np.log2(min(self.width, self.height))) - 1)

    def level(self, header, stats):
        return int(np.flatnonzero(self.lost(header) == 0).max())


READBACK_MODES: dict[str, type[ReadbackMode]] = {
    m.name: m for m in (Full, Compact, Mipmap, Adaptive)}

"""The focused passes' buffers, made once per detector, and the state of one frame.

:class:`AtlasBuffers` holds every buffer the passes F0-F8 read and write (the shapes, the
tiles, what the passes hand each other, the records and readbacks of each frame in flight), and
how many items each buffer holds now (:attr:`AtlasBuffers.caps`). :class:`FrameState` is what
one frame's passes are encoded with: nothing about a frame is kept in attributes of the passes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import wgpu

from ...gpu.buffers import GrowableBuffer, Readback
from ...gpu.layout import COUNTERS, INDIRECT_ARGS, RECORD, TILE, WORKGROUP
from ...request import RecordMode
from ...scene.pack import ShapePack
from ..plan.plan_numpy import HEIGHT_CLASSES
from .blocks import ParamBlocks

LIST_CAPACITY = 8
"""Crossings kept per pixel within a tile's box (both bodies together)."""

RETRY_LISTS = 4
"""The retry rounds' lists are this many times longer than the frame's."""

PIXEL_BYTES = 12
"""Per atlas pixel: crossings listed, winding outside the box, tile."""
ENTRY_BYTES = 8
"""Per listed crossing: depth and flags, face."""
EDGE_ENTRY_BYTES = 16
"""Per listed edge segment of pass F5: tile and side, edge, segment, steps."""
TRIANGLE_BYTES = 48
"""Per clipped triangle of pass F2: three vertices in tile coordinates and their side."""

SLOTS = 2
"""Frames that can be in flight at once (each has its own records and staging buffers)."""

MERGED_WRITE_BYTES = 1 << 16
"""Vertex bytes below which a shape's new vertices are written together with those of the
shapes next to it in the positions buffer (one ``write_buffer`` for the run)."""

_U = wgpu.BufferUsage


GROUP_WORDS, CLASS_WORDS = 16, 4
"""Words of ``tile_counts`` the retry rounds' layout (pass F7, ``frame_retry.wgsl``) keeps per
workgroup of its per-tile dispatches, and per height class of the tiles."""


def layout_words(tiles: int) -> int:
    """Words of ``tile_counts`` the retry rounds' layout needs for a frame of ``tiles`` tiles."""
    return GROUP_WORDS * -(-tiles // WORKGROUP) + CLASS_WORDS * len(HEIGHT_CLASSES)


@dataclass
class FrameState:
    """What one frame's passes are encoded with.

    Attributes
    ----------
    tiles : int
        Tiles of the frame.
    pairs : int
        Candidate pairs (the per-pair flags follow the per-tile counts).
    atlas_width : int
        Atlas pixels per row.
    round_rows : list of int
        Atlas rows of each round.
    round_threads : (R,) int
        Cull threads of each round.
    round_tiles : (R + 1,) int
        The first tile of each round (and the number of tiles at the end).
    items : int
        Cull items a round may keep (face and edge items each): the largest round's cull
        threads, or more where a retry round needed more (:attr:`Caps.items`).
    capacity : int
        List entries per pixel in the frame's rounds.
    retry_rows : int
        Atlas rows of each of the frame's retry rounds, which end it (lists
        :data:`RETRY_LISTS` times longer, for the tiles pass F7 chooses and lays out in them);
        0: it has none.
    retry_rounds : int
        Its retry rounds.
    any_open : bool
        Some tile has an open body: pass F6 runs.
    records : RecordMode
    slot : int
        The frame's slot (its records and readback buffers).
    speculative : int
        Records copied into the first readback (the rest need a second map).
    """

    tiles: int
    pairs: int
    atlas_width: int
    round_rows: list[int]
    round_threads: np.ndarray
    round_tiles: np.ndarray
    items: int
    capacity: int
    retry_rows: int
    retry_rounds: int
    any_open: bool
    records: RecordMode
    slot: int
    speculative: int = 0

    @property
    def rounds(self) -> int:
        return len(self.round_rows)

    @property
    def retry(self) -> bool:
        """The frame ends with retry rounds."""
        return self.retry_rows > 0 and self.retry_rounds > 0

    def capacity_of(self, retry: bool) -> int:
        """List entries per pixel of the frame's rounds (of its retry rounds)."""
        return self.capacity * (RETRY_LISTS if retry else 1)

    @property
    def pair_offset(self) -> int:
        """Word of ``tile_counts`` where the per-pair hit flags start."""
        return 2 * self.tiles

    @property
    def retry_offset(self) -> int:
        """Word of ``tile_counts`` where the per-tile retry flags start."""
        return 2 * self.tiles + self.pairs

    @property
    def layout_offset(self) -> int:
        """Word of ``tile_counts`` where the retry rounds' layout starts (pass F7's words)."""
        return 3 * self.tiles + self.pairs

    @property
    def list_offset(self) -> int:
        """Word of ``tile_counts`` where the list of the tiles laid out in the retry rounds
        starts (one word per tile of the frame)."""
        return self.layout_offset + layout_words(self.tiles)


@dataclass
class Caps:
    """Items the buffers that passes fill on the GPU hold now (grown when a frame needs more).

    ``items``: the cull's face and edge items a round may keep, at least (a frame's own rounds
    need their cull threads at most; a retry round, whose tiles come from every round, may need
    more: then it grows)."""

    tris: int = 1 << 16
    records: int = 1 << 16
    edges: int = 1 << 16
    items: int = 0


class AtlasBuffers:
    """Every buffer of the focused passes, made once and grown when a frame needs more.

    Parameters
    ----------
    device : wgpu.GPUDevice
    """

    def __init__(self, device: wgpu.GPUDevice) -> None:
        storage = _U.STORAGE | _U.COPY_DST

        def grow(label: str, usage: int = storage) -> GrowableBuffer:
            return GrowableBuffer(device, label, usage)

        # The shapes (rewritten when the set of shapes changes).
        self.positions = grow("positions")
        self.faces = grow("faces")
        self.edges = grow("edges")
        self.clusters = grow("clusters")
        self.cluster_bounds = grow("cluster bounds", _U.STORAGE)
        self.which = grow("clusters to bound")
        # One frame's tiles and what the passes hand each other (the tiles as pass F7 left them
        # can be read back, to check its layout).
        self.tiles = grow("tiles", storage | _U.COPY_SRC)
        self.entries = grow("tile entries")
        self.face_items = grow("face items", _U.STORAGE)
        self.edge_items = grow("edge items", _U.STORAGE)
        self.tris = grow("clipped triangles", _U.STORAGE)
        self.tri_face = grow("triangle faces", _U.STORAGE)
        self.cuts = grow("faces to cut", _U.STORAGE)
        self.edge_list = grow("edges to sample", _U.STORAGE)
        self.active = grow("active pixels", _U.STORAGE)
        self.pixels = grow("pixel counts", _U.STORAGE | _U.COPY_DST)
        self.lists = grow("pixel crossings", _U.STORAGE)
        self.tile_counts = grow("tile counts", _U.STORAGE | _U.COPY_SRC | _U.COPY_DST)
        # Per frame in flight: its per-tile counts (copied on the GPU, mapped only when needed),
        # its records, and the staging buffers they are read through.
        self.tile_copies = [grow(f"tile counts {k}", _U.COPY_SRC | _U.COPY_DST)
                            for k in range(SLOTS)]
        self.records_slots = [grow(f"records {k}", _U.STORAGE | _U.COPY_SRC)
                              for k in range(SLOTS)]
        self.counters = device.create_buffer(label="counters", size=4 * COUNTERS,
                                             usage=_U.STORAGE | _U.COPY_SRC | _U.COPY_DST)
        self.args = device.create_buffer(label="indirect args", size=INDIRECT_ARGS.size,
                                         usage=_U.STORAGE | _U.INDIRECT)
        self.readbacks = [Readback(device, f"focused readback {k}") for k in range(SLOTS)]
        self.readbacks_more = [Readback(device, f"focused tiles and records {k}")
                               for k in range(SLOTS)]
        # What the rounds bind (not the readback's copies, nor pass F0's list).
        self._bound = [v for v in vars(self).values() if isinstance(v, GrowableBuffer)
                       and v is not self.which] + self.records_slots
        self.caps = Caps()
        self.layout: tuple | None = None
        """The layout of the shapes uploaded (index buffers are rewritten when it changes)."""
        self.uploaded: list | None = None
        """The shape objects whose vertices the positions buffer holds."""
        self.bound_pending: np.ndarray | None = None
        """Clusters whose bounds pass F0 recomputes at the start of the next frame."""

    def upload(self, pack: ShapePack, shapes: list) -> int:
        """Upload the shapes; returns the vertex bytes written.

        Index buffers are written when the layout (topologies, vertex counts) changed; vertices
        only for shapes that are new objects (a shape object is made for new vertex content).
        Cluster bounds of those shapes are recomputed by pass F0 at the start of the next frame
        (:attr:`bound_pending`).
        """
        if pack.layout != self.layout:
            for buf, data in ((self.positions, pack.positions), (self.faces, pack.faces),
                              (self.edges, pack.edges), (self.clusters, pack.clusters)):
                buf.ensure(data.nbytes)
                buf.write(data)
            self.cluster_bounds.ensure(32 * len(pack.clusters))
            self.layout = pack.layout
            changed = list(range(len(shapes)))
            written = pack.positions.nbytes
        else:
            uploaded = self.uploaded
            changed = [k for k, s in enumerate(shapes) if s is not uploaded[k]]
            written = self._write_vertices(pack, shapes, changed)
        self.uploaded = list(shapes)
        if changed:
            k = np.asarray(changed, dtype=np.int64)
            which = _ranges(pack.cluster_start[k], pack.cluster_start[k + 1]).astype(np.uint32)
            if self.bound_pending is not None:
                which = np.union1d(which, self.bound_pending).astype(np.uint32)
            self.bound_pending = which
        return written

    def _write_vertices(self, pack: ShapePack, shapes: list, changed: list[int]) -> int:
        """Write the vertices of shapes ``changed`` where the pack puts them (the pack's own
        positions are those of the frame that made it: each shape's are written); returns the
        bytes written. Consecutive shapes are written together when they are small (each write
        costs about as much as copying 64 kB)."""
        written = 0
        run: list[np.ndarray] = []
        run_start = 0
        for pos, k in enumerate(changed):
            vertices = shapes[k].vertices
            written += vertices.nbytes
            if vertices.nbytes >= MERGED_WRITE_BYTES:
                self.positions.write(vertices, offset=12 * int(pack.vertex_start[k]))
                continue
            if not run:
                run_start = k
            run.append(vertices)
            last = pos + 1 == len(changed) or changed[pos + 1] != k + 1 \
                or shapes[k + 1].vertices.nbytes >= MERGED_WRITE_BYTES
            if last:
                data = run[0] if len(run) == 1 else np.concatenate(run)
                self.positions.write(data, offset=12 * int(pack.vertex_start[run_start]))
                run = []
        return written

    def version(self) -> tuple[int, ...]:
        """Which buffers the rounds bind now: it changes whenever one is made anew (grown)."""
        return tuple(g.generation for g in self._bound)

    def records(self, slot: int = 0) -> GrowableBuffer:
        """The records buffer of frame slot ``slot`` (its limit is every slot's)."""
        return self.records_slots[slot]

    def args_at(self, name: str) -> tuple[wgpu.GPUBuffer, int]:
        """``(buffer, offset)`` of indirect arguments ``name`` (a field of
        :data:`~pycinder.gpu.layout.INDIRECT_ARGS`)."""
        return self.args, INDIRECT_ARGS.offset(name)

    @property
    def limits(self) -> Caps:
        """The most items each grown buffer may ever hold on this device."""
        return Caps(tris=self.tris.limit // TRIANGLE_BYTES,
                    records=self.records().limit // RECORD.size,
                    edges=self.edge_list.limit // EDGE_ENTRY_BYTES,
                    items=self.face_items.limit // 8)

    def ensure_frame(self, state: FrameState, entries: np.ndarray,
                     tiles: np.ndarray | None) -> None:
        """Write the frame's tiles (None: they are copied on the GPU, from the planner's pass
        P3: only their buffer is sized) and entries, and size every buffer its passes use."""
        if tiles is None:
            self.tiles.ensure(TILE.size * state.tiles)
        else:
            self.tiles.ensure(tiles.nbytes)
            self.tiles.write(tiles)
        self.entries.ensure(entries.nbytes)
        self.entries.write(entries)
        self.face_items.ensure(8 * max(state.items, 1))
        self.edge_items.ensure(8 * max(state.items, 1))
        # Per tile (found, undecided), per pair a hit flag, per tile a retry flag, the retry
        # rounds' layout and the list of their tiles.
        self.tile_counts.ensure(4 * (state.list_offset + state.tiles))
        width = state.atlas_width
        rows = max(max(state.round_rows) if state.round_rows else 1, state.retry_rows)
        self.pixels.ensure(PIXEL_BYTES * width * rows)
        self.lists.ensure(ENTRY_BYTES * width * max(state.capacity * rows,
                                                    state.capacity_of(True) * state.retry_rows))
        self.active.ensure(4 * width * rows)
        caps, limits = self.caps, self.limits
        caps.tris = min(caps.tris, limits.tris)
        caps.records = min(caps.records, limits.records)
        caps.edges = min(caps.edges, limits.edges)
        self.tris.ensure(TRIANGLE_BYTES * caps.tris)
        self.tri_face.ensure(4 * caps.tris)
        self.cuts.ensure(8 * caps.tris)
        self.edge_list.ensure(EDGE_ENTRY_BYTES * caps.edges)
        self.records(state.slot).ensure(RECORD.size * caps.records)


def _ranges(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """The integers of every range ``[starts[i], ends[i])``, range after range."""
    counts = ends - starts
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    # Each value is the previous one plus 1, or its range's start after a range ends.
    steps = np.ones(total, dtype=np.int64)
    firsts = np.cumsum(counts) - counts
    kept = counts > 0
    steps[firsts[kept]] = starts[kept] - np.concatenate([[0], (ends[kept] - 1)[:-1]])
    return np.cumsum(steps)


@dataclass(frozen=True)
class Round:
    """One round of a frame: its atlas rows and cull threads, and which parameter blocks it
    binds.

    Attributes
    ----------
    block : int
        Its copy of the per-round parameter blocks (the retry rounds' come after the frame's
        rounds').
    threads : int
        Cull threads.
    rows : int
        Atlas rows.
    retry_round : int
        A retry round's number, from 1: only the tiles pass F7 laid out in it are culled, with
        longer lists; 0: a round of the frame.
    slot : int
        The frame's slot.
    first_tile, end_tile : int
        Its tiles, ``[first_tile, end_tile)`` of the frame (a retry round's: every tile, of
        which it culls those laid out in it).
    """

    block: int
    threads: int
    rows: int
    retry_round: int
    slot: int
    first_tile: int
    end_tile: int

    @property
    def retry(self) -> bool:
        return self.retry_round > 0

    @property
    def kind(self) -> str:
        return "retry" if self.retry else "rounds"


@dataclass
class Encoding:
    """What the passes of one frame are encoded with: the buffers, the frame's and the rounds'
    parameter blocks, and the frame's state."""

    buffers: AtlasBuffers
    frame_params: ParamBlocks
    round_params: ParamBlocks
    state: FrameState


__all__ = ["CLASS_WORDS", "EDGE_ENTRY_BYTES", "ENTRY_BYTES", "GROUP_WORDS", "LIST_CAPACITY",
           "PIXEL_BYTES", "RETRY_LISTS", "SLOTS", "AtlasBuffers", "Caps", "Encoding",
           "FrameState", "Round", "layout_words"]

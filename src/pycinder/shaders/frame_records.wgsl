// Appending records, shared by passes F4, F5 and F6 (each declares `records`, `counters` and
// `tile_counts`, and its Params hold `record_cap`, `pair_records` and `pair_offset`).
//
// tile_counts[pair_offset + pair] counts the records kept for a pair: non-zero once the pair is
// found, which is what the early-outs of later tiles test. With records "found" only the first
// `pair_records` samples of a pair are kept (what contacts of "all" do not need is not written,
// read back or decoded); with "all" every one is.
//!include frame_stop.wgsl

fn append_record(t: Tile, row: Record) {
    if (params.record_cap == 0u) {
        return;  // records "none": the per-tile counts say everything
    }
    let pair = params.pair_offset + t.pair;
    if (atomicLoad(&tile_counts[pair]) >= params.pair_records) {
        return;
    }
    if (atomicAdd(&tile_counts[pair], 1u) >= params.pair_records) {
        return;
    }
    let slot = atomicAdd(&counters[C_RECORDS], 1u);
    if (slot < params.record_cap) {
        records[slot] = row;
    }
}

// Mark the pair of tile `t` found (its count stays as it is when records were kept), and the
// frame as having found something.
fn mark_found(t: Tile) {
    atomicMax(&tile_counts[params.pair_offset + t.pair], 1u);
    atomicMax(&counters[C_FOUND], 1u);
}

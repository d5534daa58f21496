// Focused strategy, pass F1 (compute): cull clusters per tile.
//
// One thread per (tile, side, cluster of that side's body): of a round's tiles, or (cull_retry) of
// the tiles pass F7 laid out in a retry round. A cluster's faces are kept when its
// bounds meet the tile's window and are not wholly on the far side of the box from the counting
// side (its faces could cross rays through the window there); its edges are kept when its
// bounds meet the box itself (only there can an edge lie inside the other body or cross its
// surface).
//!include frame_tiles.wgsl
//!include frame_stop.wgsl


@group(0) @binding(0) var<storage, read> tiles: array<Tile>;
@group(0) @binding(1) var<storage, read> clusters: array<Cluster>;
@group(0) @binding(2) var<storage, read> bounds: array<vec4f>;
// Per entry e = 2 * tile + side: x = the first thread of the entry (a prefix over the whole
// frame), y = the first cluster of the entry's body; one more entry at the end holds the total.
@group(0) @binding(3) var<storage, read> entries: array<vec2u>;
@group(0) @binding(4) var<storage, read_write> face_items: array<vec2u>;
@group(0) @binding(5) var<storage, read_write> edge_items: array<vec2u>;
@group(0) @binding(6) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(7) var<uniform> params: CullParams;
// Per tile (found, undecided), then per candidate pair a hit flag (set by passes F4-F6), then
// (for the retry rounds) per tile the retry round it is run again in and the list of those tiles
// (set by frame_retry.wgsl).
@group(0) @binding(8) var<storage, read> counts: array<u32>;

@compute @workgroup_size(WORKGROUP)
fn cull(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let local = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (local >= params.total) {
        return;
    }
    let first = params.first_entry;
    let i = entries[first].x + local;
    // The entry holding thread i: the last e with entries[e].x <= i.
    var lo = first;
    var hi = first + params.n_entries;
    loop {
        if (hi - lo <= 1u) {
            break;
        }
        let mid = (lo + hi) / 2u;
        if (entries[mid].x <= i) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let e = lo;
    cull_cluster(e / 2u, e % 2u, entries[e].y + (i - entries[e].x));
}

// A retry round: one workgroup per (tile, side) of the tiles pass F7 laid out in the retry
// rounds (listed in `counts` from `list_offset`), its threads over the side's clusters; a tile of
// another retry round is left to it.
@compute @workgroup_size(WORKGROUP)
fn cull_retry(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let k = wg.y * ROW + wg.x;
    if (k >= 2u * atomicLoad(&counters[C_RETRY_TILES])) {
        return;
    }
    let tile_index = counts[params.list_offset + k / 2u];
    if (counts[params.retry_offset + tile_index] != params.retry_round) {
        return;
    }
    let e = 2u * tile_index + k % 2u;
    let n = entries[e + 1u].x - entries[e].x;
    for (var j = lid; j < n; j += WORKGROUP) {
        cull_cluster(tile_index, k % 2u, entries[e].y + j);
    }
}

fn cull_cluster(tile_index: u32, side: u32, c: u32) {
    let t = tiles[tile_index];
    if ((t.flags & FLAG_SKIP_IF_HIT) != 0u && counts[params.pair_offset + t.pair] != 0u) {
        return;  // another tile of this pair already found it colliding
    }
    if (frame_decided(t)) {
        return;  // the frame asks only whether anything collides, and something does
    }
    // Half a pixel more, so rounding never culls what touches the window.
    let box = tile_box(t, side, bounds[2u * c].xyz, bounds[2u * c + 1u].xyz, 0.5);
    let mid_p = box[0];
    let ext = box[1];
    let w = f32(t.window.z);
    let h = f32(t.window.w);
    if (mid_p.x + ext.x < 0.0 || mid_p.x - ext.x > w || mid_p.y + ext.y < 0.0 || mid_p.y - ext.y > h) {
        return;
    }
    let back = (t.flags & FLAG_COUNT_BACK) != 0u;
    let z_lo = mid_p.z - ext.z;
    let z_hi = mid_p.z + ext.z;
    // Faces serve the ray counts, which only a solid needs; two open bodies are tested by their
    // edges and faces in pass F6, which reads the faces directly.
    let faces_needed = select(z_lo <= t.slab.y, z_hi >= t.slab.x, back)
        && !(is_open(t, 0u) && is_open(t, 1u));
    let item = vec2u(tile_index, c | (side << 31u));
    if (faces_needed) {
        let slot = atomicAdd(&counters[C_FACE_ITEMS], 1u);
        if (slot < params.face_cap) {
            face_items[slot] = item;
        }
    }
    if (z_hi >= t.slab.x && z_lo <= t.slab.y && clusters[c].edge_count > 0u) {
        let slot = atomicAdd(&counters[C_EDGE_ITEMS], 1u);
        if (slot < params.edge_cap) {
            edge_items[slot] = item;
        }
    }
}

// Focused strategy, pass F4 (compute): every surface point of both bodies that pass F3 listed in
// a tile's box (a face crossing a pixel centre's ray), tested against the other body.
//
// The point lies exactly on its body's surface, at the pixel centre and the crossing's depth; the
// other body's winding there comes from the same pixel's list. Non-zero: the surfaces overlap
// there, and the point is appended as a record. Edge samples (pass F5) miss overlaps that lie in
// the middle of faces, between edges; these points do not. One thread per pixel that pass F3
// listed a crossing at.
//!include frame_tiles.wgsl
//!include frame_lists.wgsl
//!include frame_records.wgsl


@group(0) @binding(0) var<storage, read> tiles: array<Tile>;
@group(0) @binding(1) var<storage, read> pixels: array<u32>;
@group(0) @binding(2) var<storage, read> crossings: array<vec2u>;
@group(0) @binding(3) var<storage, read_write> tile_counts: array<atomic<u32>>;
// Per record: tile, pixel u | v << 16, f32 bits of the point's z, face | kind | side (layout.py).
@group(0) @binding(4) var<storage, read_write> records: array<Record>;
@group(0) @binding(5) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(6) var<uniform> params: SurfaceTestParams;
@group(0) @binding(7) var<storage, read> active_pixels: array<u32>;

@compute @workgroup_size(WORKGROUP)
fn surface_test(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (i >= atomicLoad(&counters[C_ACTIVE])) {
        return;
    }
    let pixel = active_pixels[i];
    let gid = vec2u(pixel % params.atlas_width, pixel / params.atlas_width);
    let listed = pixels[3u * pixel];
    let tile_index = pixels[3u * pixel + 2u] - 1u;
    let t = tiles[tile_index];
    if (((t.flags & FLAG_SKIP_IF_HIT) != 0u
            && atomicLoad(&tile_counts[params.pair_offset + t.pair]) != 0u)
            || frame_decided(t)) {
        return;
    }
    let cap = params.capacity;
    if (listed > cap) {
        atomicAdd(&tile_counts[2u * tile_index + 1u], 1u);
        atomicAdd(&counters[C_UNDECIDED], 1u);
        return;
    }
    let back = (t.flags & FLAG_COUNT_BACK) != 0u;
    var found = 0u;
    for (var k = 0u; k < listed; k++) {
        let entry = crossings[pixel * cap + k];
        let side = entry.x & 1u;
        if (is_open(t, 1u - side)) {
            continue;  // the other body has no inside
        }
        let z = bitcast<f32>(entry.x & 0xFFFFFFFCu);
        if (winding_at(pixel, listed, cap, 1u - side, z, back) != 0) {
            found++;
            let u = gid.x - t.window.x;
            let v = gid.y - t.window.y;
            append_record(t, Record(tile_index, u | (v << 16u), bitcast<u32>(z + t.slab.x),
                                   entry.y | (RECORD_SURFACE << RECORD_KIND_SHIFT)
                                     | (side << RECORD_SIDE_BIT)));
        }
    }
    if (found > 0u) {
        atomicAdd(&tile_counts[2u * tile_index], found);
        mark_found(t);
    }
}

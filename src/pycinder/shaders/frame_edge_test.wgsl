// Focused strategy, pass F5 (compute): every edge of both bodies inside the box, sampled, and each
// sample tested against the other body with the crossings of pass F3.
//
// An edge is clipped to the box and sampled at steps of at most one pixel along u, v and z. A
// sample is tested at the centre of its pixel, at its own depth: the other body's winding there is
// the outside-the-box winding of the pixel plus the listed crossings between the sample and the
// counting side. A non-zero winding means the sample lies inside the other body: the pair
// collides, and the sample is appended as a record. Samples at pixels whose list overflowed are
// counted as undecided (the host then retries their tiles with thinner boxes).
//
// Two entry points: `list_edges` (one workgroup per kept cluster, its threads striding over the
// cluster's edges) lists the edges that reach into the box; `edge_test` (one thread per listed
// edge segment) samples and tests them. Most of a cluster's edges miss a small box: sampling in
// threads of its own runs side by side with other sampling, not masked beside edges that return at
// once.
//
// A long part (a fine tolerance makes a box thousands of pixels deep) is listed as segments of at
// most SEGMENT_SAMPLES samples, each tested by a thread of its own: llvmpipe (the CPU driver of
// lavapipe and of OpenGL without a GPU) silently ends a thread's loops after 65,535 steps in all,
// and a segment's samples times the steps of `winding_at` (one per listed crossing, at most the
// retry round's 32) stay well below that.
//!include frame_tiles.wgsl
//!include frame_lists.wgsl
//!include frame_records.wgsl


@group(0) @binding(0) var<storage, read> tiles: array<Tile>;
@group(0) @binding(1) var<storage, read> clusters: array<Cluster>;
@group(0) @binding(2) var<storage, read> positions: array<f32>;
@group(0) @binding(3) var<storage, read> edges: array<u32>;
@group(0) @binding(4) var<storage, read> edge_items: array<vec2u>;
@group(0) @binding(5) var<storage, read> pixels: array<u32>;
@group(0) @binding(6) var<storage, read> crossings: array<vec2u>;
// Per tile: [2t] samples found inside, [2t + 1] samples undecided; then a hit flag per pair.
@group(0) @binding(7) var<storage, read_write> tile_counts: array<atomic<u32>>;
// Per record: tile, pixel u | v << 16, f32 bits of the sample's z, edge | kind | side (layout.py).
@group(0) @binding(8) var<storage, read_write> records: array<Record>;
@group(0) @binding(9) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(10) var<uniform> params: EdgeTestParams;
// Segments of the edges reaching into their tile's box: tile << 1 | side, packed edge, segment,
// steps of the edge's part in the box (counter C_EDGES counts segments).
@group(0) @binding(11) var<storage, read_write> edge_list: array<vec4u>;

// Most samples one thread tests (see above).
const SEGMENT_SAMPLES: u32 = 1024u;

fn position(v: u32) -> vec3f {
    return vec3f(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
}

// The part of edge `e` of side `side` inside the box of tile `t`: its start and its span
// (`inside` false when it misses the box).
struct EdgeInBox {
    start: vec3f,
    span: vec3f,
    inside: bool,
};

fn edge_in_box(t: Tile, side: u32, e: u32) -> EdgeInBox {
    var out: EdgeInBox;
    out.inside = false;
    let a = tile_point(t, side, position(edges[2u * e]));
    let b = tile_point(t, side, position(edges[2u * e + 1u]));
    // Clip the edge to the box.
    let box_lo = vec3f(0.0, 0.0, t.slab.x);
    let box_hi = vec3f(f32(t.window.z), f32(t.window.w), t.slab.y);
    let d = b - a;
    var t0 = 0.0;
    var t1 = 1.0;
    for (var k = 0u; k < 3u; k++) {
        if (d[k] == 0.0) {
            if (a[k] < box_lo[k] || a[k] > box_hi[k]) {
                return out;
            }
        } else {
            let ta = (box_lo[k] - a[k]) / d[k];
            let tb = (box_hi[k] - a[k]) / d[k];
            t0 = max(t0, min(ta, tb));
            t1 = min(t1, max(ta, tb));
        }
    }
    if (t0 > t1) {
        return out;
    }
    out.start = a + t0 * d;
    out.span = (t1 - t0) * d;
    out.inside = true;
    return out;
}

// Steps between the samples of an edge's part: at most a pixel along u, v and z each.
fn part_steps(span: vec3f) -> u32 {
    return u32(ceil(max(max(abs(span.x), abs(span.y)), abs(span.z))));
}

// Sample segment `segment` of the part of edge `e` (of side `side` of tile `tile_index`) inside
// the box, whose samples are `steps + 1` points from its start to its end, and test the samples.
fn test_edge(t: Tile, tile_index: u32, side: u32, e: u32, segment: u32, steps: u32) {
    let part = edge_in_box(t, side, e);
    if (!part.inside) {
        return;
    }
    let p = part.start;
    let span = part.span;
    let first = segment * SEGMENT_SAMPLES;
    let last = min(first + SEGMENT_SAMPLES - 1u, steps);
    let other = 1u - side;
    let back = (t.flags & FLAG_COUNT_BACK) != 0u;
    let cap = params.capacity;
    let w = t.window.z;
    let h = t.window.w;
    var found = 0u;
    var undecided = 0u;
    for (var i = first; i <= last; i++) {
        let s = p + span * (f32(i) / f32(max(steps, 1u)));
        let x = min(u32(max(s.x, 0.0)), w - 1u);
        let y = min(u32(max(s.y, 0.0)), h - 1u);
        let pixel = (t.window.y + y) * params.atlas_width + t.window.x + x;
        let listed = pixels[3u * pixel];
        if (listed > cap) {
            undecided++;
            continue;
        }
        let winding = winding_at(pixel, listed, cap, other, s.z - t.slab.x, back);
        if (winding != 0) {
            found++;
            append_record(t, Record(tile_index, x | (y << 16u), bitcast<u32>(s.z),
                                   e | (RECORD_EDGE << RECORD_KIND_SHIFT) | (side << RECORD_SIDE_BIT)));
        }
    }
    atomicAdd(&counters[C_SAMPLES], last + 1u - first);
    if (found > 0u) {
        atomicAdd(&tile_counts[2u * tile_index], found);
        mark_found(t);
    }
    if (undecided > 0u) {
        atomicAdd(&tile_counts[2u * tile_index + 1u], undecided);
        atomicAdd(&counters[C_UNDECIDED], undecided);
    }
}

fn pair_found(t: Tile) -> bool {
    return (params.early_out != 0u
            && atomicLoad(&tile_counts[params.pair_offset + t.pair]) != 0u)
        || frame_decided(t);
}

@compute @workgroup_size(WORKGROUP)
fn list_edges(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let item_index = wg.y * ROW + wg.x;
    if (item_index >= min(atomicLoad(&counters[C_EDGE_ITEMS]), params.item_cap)) {
        return;
    }
    let item = edge_items[item_index];
    let c = item.y & 0x7FFFFFFFu;
    let side = item.y >> 31u;
    let info = clusters[c];
    let tile_index = item.x;
    let t = tiles[tile_index];
    if (is_open(t, 1u - side)) {
        return;  // the other body has no inside (its surface is tested by pass F6)
    }
    if (pair_found(t)) {
        return;  // pass F4 or an earlier tile already found this pair
    }
    // A cluster owns up to about twice as many edges as faces: the workgroup strides over them.
    for (var k = lid; k < info.edge_count; k += WORKGROUP) {
        let e = info.edge_start + k;
        let part = edge_in_box(t, side, e);
        if (part.inside) {
            let steps = part_steps(part.span);
            let segments = steps / SEGMENT_SAMPLES + 1u;  // steps + 1 samples
            let slot = atomicAdd(&counters[C_EDGES], segments);
            for (var s = 0u; s < segments && slot + s < params.list_cap; s++) {
                edge_list[slot + s] = vec4u((tile_index << 1u) | side, e, s, steps);
            }
        }
    }
}

@compute @workgroup_size(WORKGROUP)
fn edge_test(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (i >= min(atomicLoad(&counters[C_EDGES]), params.list_cap)) {
        return;
    }
    let listed = edge_list[i];
    let tile_index = listed.x >> 1u;
    let t = tiles[tile_index];
    if (pair_found(t)) {
        return;  // a sample of another edge already found this pair
    }
    test_edge(t, tile_index, listed.x & 1u, listed.y, listed.z, listed.w);
}

// What the broad phase's shaders share (pycinder/focused/broad): the frame's parameters and the
// helpers of more than one pass. The structs (Params, Body, SortStep) and the constants shared
// with the host (SORT_BLOCK, PAD_SCALE, the GRID_* and COUNT_* word indices, ...) are generated
// in front of the source from pycinder/focused/broad/broad_common.py.
//!include layout

@group(0) @binding(0) var<uniform> params: Params;

const WIDE: u32 = 0xFFFFFFFFu;      // the column of wide boxes (after every cell's)
const MAX_CELL: i32 = 65534;        // cells per axis, 0..MAX_CELL (16 bits of the column)

fn thread_index(wg: vec3u, lid: u32, size: u32) -> u32 {
    return (wg.y * ROW + wg.x) * size + lid;
}

// Bits of a float whose unsigned order is the float's order.
fn ordered(x: f32) -> u32 {
    let u = bitcast<u32>(x);
    return select(u | 0x80000000u, ~u, (u & 0x80000000u) != 0u);
}

fn unordered(u: u32) -> f32 {
    return bitcast<f32>(select(~u, u & 0x7FFFFFFFu, (u & 0x80000000u) != 0u));
}

// The box's width across the sweep axis (the larger of its widths on the two column axes).
fn width(lo: vec3f, hi: vec3f) -> f32 {
    let a = (params.axis + 1u) % 3u;
    let b = (params.axis + 2u) % 3u;
    return max(max(hi[a] - lo[a], hi[b] - lo[b]), 0.0);
}

fn column_key(cell: vec2i) -> u32 {
    return (u32(cell.x) << 16u) | u32(cell.y);
}

// The order of sort elements (within key, column, ordered start, body).
fn before(a: vec4u, b: vec4u) -> bool {
    if (a.x != b.x) {
        return a.x < b.x;
    }
    if (a.y != b.y) {
        return a.y < b.y;
    }
    if (a.z != b.z) {
        return a.z < b.z;
    }
    return a.w < b.w;
}

// Broad phase on the GPU: world boxes, a bitonic sort into columns along one axis, a sweep.
//
//   world_boxes  one thread per body: its world box, grown outward so that it holds the exact box
//                despite float32 rounding; the largest box extent and the range of box centres
//                along each axis (atomics, for the grid)
//   columns      one thread per body (and per padding slot of the sort): its sort element
//                (within key, column, order-preserving bits of the box's start on the sweep
//                axis, body). Columns are the cells of a 2D grid across the sweep axis, at least
//                as wide as the widest box, holding the box's centre: boxes that overlap are in
//                the same or neighbouring columns
//   sort_local   one workgroup per block of SORT_BLOCK elements: the whole bitonic network up to
//                blocks of SORT_BLOCK (step k = 2), or the steps j < SORT_BLOCK of merge k
//   sort_step    one compare-exchange per thread: step j of merge k, for j >= SORT_BLOCK
//   gather       the boxes in sorted order, so that the sweep reads them in sequence
//   sweep        one thread per sorted box: in its own and the 8 neighbouring columns (found by
//                binary search), the boxes after it in (start, body) order that start before it
//                ends are tested on all three axes and their groups; each overlapping pair
//                (i, j), i < j, is appended through an atomic counter, once (by the box that
//                starts first)
//!include layout

const SORT_THREADS: u32 = 256u;
const SORT_BLOCK: u32 = 512u;   // 2 * SORT_THREADS elements per workgroup
const PAD_SCALE: f32 = 1.9073486328125e-06;  // 2^-19: see pycinder/passes/broadphase.py

struct Body {
    rows: array<vec4f, 3>,  // world-from-body rows (linear part, translation less the origin)
    lo: vec4f,              // body-space box minimum; w: bounding-sphere radius
    hi: vec4f,              // body-space box maximum; w unused
    keys: vec4u,            // within key, group, 0, 0
};

struct Params {
    n: u32,             // bodies
    count: u32,         // sort elements (a power of two, at least SORT_BLOCK)
    axis: u32,          // sweep axis
    capacity: u32,      // pairs the pairs buffer holds
    use_groups: u32,    // 1: only pairs of different groups
    base_pad: f32,      // added to every box's padding (rounding of the float64 reference)
    _p0: u32,
    _p1: u32,
};

struct SortStep {
    k: u32,     // merge size (sort_local: the first merge size)
    j: u32,     // compare distance (sort_local: the last merge size)
    _p0: u32,
    _p1: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> bodies: array<Body>;
@group(0) @binding(2) var<storage, read_write> boxes_lo: array<vec4f>;  // w: within key bits
@group(0) @binding(3) var<storage, read_write> boxes_hi: array<vec4f>;  // w: group bits
@group(0) @binding(4) var<storage, read_write> elements: array<vec4u>;
@group(0) @binding(5) var<uniform> step: SortStep;
@group(0) @binding(6) var<storage, read_write> sorted_lo: array<vec4f>;
@group(0) @binding(7) var<storage, read_write> sorted_hi: array<vec4f>;
@group(0) @binding(8) var<storage, read_write> sorted_body: array<u32>;
@group(0) @binding(9) var<storage, read_write> counter: array<atomic<u32>, 4>;
@group(0) @binding(10) var<storage, read_write> pairs: array<vec2u>;
// Per axis: the largest box extent (f32 bits), the largest centre (order-preserving bits) and the
// complement of the smallest (so that every entry starts at 0 and grows by atomicMax).
@group(0) @binding(11) var<storage, read_write> grid: array<atomic<u32>, 12>;

const COLUMN_CELLS: f32 = 65000.0;  // most cells along an axis (16 bits of the column)
const COLUMN_MARGIN: f32 = 1.0625;  // cells wider than the widest box, by more than rounding

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

var<workgroup> local_grid: array<atomic<u32>, 12>;  // this workgroup's share of `grid`

@compute @workgroup_size(WORKGROUP)
fn world_boxes(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    if (lid < 12u) {
        atomicStore(&local_grid[lid], 0u);
    }
    workgroupBarrier();
    let i = thread_index(wg, lid, WORKGROUP);
    if (i < params.n) {
        let b = bodies[i];
        let lo = b.lo.xyz;
        let hi = b.hi.xyz;
        let radius = b.lo.w;
        let centre = 0.5 * (lo + hi);
        let reach = max(abs(lo), abs(hi));
        var wlo: vec3f;
        var whi: vec3f;
        for (var k = 0u; k < 3u; k++) {
            let row = b.rows[k];
            let m = row.xyz;
            // The transformed box's extent along world axis k (the corners' extremes)...
            let box_lo = row.w + dot(min(m * lo, m * hi), vec3f(1.0));
            let box_hi = row.w + dot(max(m * lo, m * hi), vec3f(1.0));
            // ...and the transformed sphere's (an ellipsoid: radius times the row's norm).
            let c = row.w + dot(m, centre);
            let half = radius * length(m);
            // Grown by the rounding bound of this row's arithmetic (see broadphase.py).
            let pad = PAD_SCALE * (abs(row.w) + dot(abs(m), reach + vec3f(radius)))
                + params.base_pad;
            wlo[k] = max(box_lo, c - half) - pad;
            whi[k] = min(box_hi, c + half) + pad;
            atomicMax(&local_grid[k], bitcast<u32>(max(whi[k] - wlo[k], 0.0)));
            let mid = ordered(0.5 * (wlo[k] + whi[k]));
            atomicMax(&local_grid[4u + k], mid);
            atomicMax(&local_grid[8u + k], ~mid);
        }
        boxes_lo[i] = vec4f(wlo, bitcast<f32>(b.keys.x));
        boxes_hi[i] = vec4f(whi, bitcast<f32>(b.keys.y));
    }
    workgroupBarrier();
    if (lid < 12u) {
        atomicMax(&grid[lid], atomicLoad(&local_grid[lid]));
    }
}

struct Cells {
    start: vec2f,   // smallest centre on the two column axes
    size: vec2f,    // cell size on them
};

fn cells() -> Cells {
    var out: Cells;
    for (var e = 0u; e < 2u; e++) {
        let k = (params.axis + 1u + e) % 3u;
        let widest = bitcast<f32>(atomicLoad(&grid[k]));
        let low = unordered(~atomicLoad(&grid[8u + k]));
        let high = unordered(atomicLoad(&grid[4u + k]));
        out.start[e] = low;
        out.size[e] = max(max(widest * COLUMN_MARGIN, (high - low) / COLUMN_CELLS), 1e-30);
    }
    return out;
}

fn cell_of(c: Cells, lo: vec4f, hi: vec4f) -> vec2i {
    let mid = 0.5 * (lo.xyz + hi.xyz);
    let a = (params.axis + 1u) % 3u;
    let b = (params.axis + 2u) % 3u;
    let p = (vec2f(mid[a], mid[b]) - c.start) / c.size;
    return clamp(vec2i(floor(p)), vec2i(0), vec2i(65535));
}

fn column_key(cell: vec2i) -> u32 {
    return (u32(cell.x) << 16u) | u32(cell.y);
}

@compute @workgroup_size(WORKGROUP)
fn columns(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = thread_index(wg, lid, WORKGROUP);
    if (i >= params.count) {
        return;
    }
    if (i >= params.n) {
        elements[i] = vec4u(0xFFFFFFFFu);  // sorts last
        return;
    }
    let lo = boxes_lo[i];
    let hi = boxes_hi[i];
    let cell = cell_of(cells(), lo, hi);
    elements[i] = vec4u(bitcast<u32>(lo.w), column_key(cell), ordered(lo[params.axis]), i);
}

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

var<workgroup> block: array<vec4u, SORT_BLOCK>;

@compute @workgroup_size(SORT_THREADS)
fn sort_local(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let base = (wg.y * ROW + wg.x) * SORT_BLOCK;
    if (base >= params.count) {
        return;  // past the last block, in the last row of workgroups (uniform per workgroup)
    }
    block[lid] = elements[base + lid];
    block[lid + SORT_THREADS] = elements[base + lid + SORT_THREADS];
    workgroupBarrier();
    for (var k = step.k; k <= step.j; k <<= 1u) {
        for (var j = min(k >> 1u, SORT_THREADS); j > 0u; j >>= 1u) {
            let i = 2u * lid - (lid & (j - 1u));
            let ascending = ((base + i) & k) == 0u;
            let a = block[i];
            let b = block[i + j];
            if (before(b, a) == ascending) {
                block[i] = b;
                block[i + j] = a;
            }
            workgroupBarrier();
        }
    }
    elements[base + lid] = block[lid];
    elements[base + lid + SORT_THREADS] = block[lid + SORT_THREADS];
}

@compute @workgroup_size(SORT_THREADS)
fn sort_step(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let t = thread_index(wg, lid, SORT_THREADS);
    if (t >= params.count / 2u) {
        return;
    }
    let j = step.j;
    let i = 2u * t - (t & (j - 1u));
    let ascending = (i & step.k) == 0u;
    let a = elements[i];
    let b = elements[i + j];
    if (before(b, a) == ascending) {
        elements[i] = b;
        elements[i + j] = a;
    }
}

@compute @workgroup_size(WORKGROUP)
fn gather(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let p = thread_index(wg, lid, WORKGROUP);
    if (p >= params.n) {
        return;
    }
    let body = elements[p].w;
    sorted_lo[p] = boxes_lo[body];
    sorted_hi[p] = boxes_hi[body];
    sorted_body[p] = body;
}

// The first sorted position whose element comes after `e` (n if none).
fn first_after(e: vec4u) -> u32 {
    var lo = 0u;
    var hi = params.n;
    while (lo < hi) {
        let mid = (lo + hi) / 2u;
        if (before(e, elements[mid])) {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    return lo;
}

@compute @workgroup_size(WORKGROUP)
fn sweep(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let p = thread_index(wg, lid, WORKGROUP);
    if (p >= params.n) {
        return;
    }
    let a_lo = sorted_lo[p];
    let a_hi = sorted_hi[p];
    let a = sorted_body[p];
    let own = elements[p];
    let end = a_hi[params.axis];
    let cell = vec2i(i32(own.y >> 16u), i32(own.y & 0xFFFFu));  // as the columns pass found it
    for (var d = 0u; d < 9u; d++) {
        let other = cell + vec2i(i32(d % 3u) - 1, i32(d / 3u) - 1);
        if (any(other < vec2i(0)) || any(other > vec2i(65535))) {
            continue;
        }
        let column = column_key(other);
        // The boxes of that column (and this within key) after this one in (start, body) order:
        // of each overlapping pair, the one that starts first (or has the lower index) finds
        // the other, in the other's column.
        for (var q = first_after(vec4u(own.x, column, own.z, own.w)); q < params.n; q++) {
            let e = elements[q];
            let b_lo = sorted_lo[q];
            if (e.x != own.x || e.y != column || b_lo[params.axis] > end) {
                break;
            }
            let b_hi = sorted_hi[q];
            if (any(b_lo.xyz > a_hi.xyz) || any(a_lo.xyz > b_hi.xyz)) {
                continue;
            }
            if (params.use_groups != 0u && bitcast<u32>(a_hi.w) == bitcast<u32>(b_hi.w)) {
                continue;
            }
            let b = sorted_body[q];
            let slot = atomicAdd(&counter[0], 1u);
            if (slot < params.capacity) {
                pairs[slot] = vec2u(min(a, b), max(a, b));
            }
        }
    }
}

// Broad phase on the GPU: world boxes, a bitonic sort along one axis, and a sweep.
//
//   world_boxes  one thread per body (and per padding slot of the sort): its world box, grown
//                outward so that it holds the exact box despite float32 rounding, and its sort
//                element (within key, order-preserving bits of the box's start on the axis, body)
//   sort_local   one workgroup per block of SORT_BLOCK elements: the whole bitonic network up to
//                blocks of SORT_BLOCK (params k0 = 2), or the steps j < SORT_BLOCK of merge k
//   sort_step    one compare-exchange per thread: step j of merge k, for j >= SORT_BLOCK
//   gather       the boxes in sorted order, so that the sweep reads them in sequence
//   sweep        one thread per sorted box: the boxes after it that start before it ends on the
//                axis (and have its within key) are tested on all three axes and their groups;
//                each overlapping pair (i, j), i < j, is appended through an atomic counter
//
// Sort elements sort by (within key, start on the axis, body): boxes of one within key are
// contiguous, so a sweep stops at the first box of another key.
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

fn thread_index(wg: vec3u, lid: u32, size: u32) -> u32 {
    return (wg.y * ROW + wg.x) * size + lid;
}

// Bits of a float whose unsigned order is the float's order.
fn ordered(x: f32) -> u32 {
    let u = bitcast<u32>(x);
    return select(u | 0x80000000u, ~u, (u & 0x80000000u) != 0u);
}

@compute @workgroup_size(WORKGROUP)
fn world_boxes(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = thread_index(wg, lid, WORKGROUP);
    if (i >= params.count) {
        return;
    }
    if (i >= params.n) {
        elements[i] = vec4u(0xFFFFFFFFu, 0xFFFFFFFFu, 0xFFFFFFFFu, 0u);  // sorts last
        return;
    }
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
        let pad = PAD_SCALE * (abs(row.w) + dot(abs(m), reach + vec3f(radius))) + params.base_pad;
        wlo[k] = max(box_lo, c - half) - pad;
        whi[k] = min(box_hi, c + half) + pad;
    }
    boxes_lo[i] = vec4f(wlo, bitcast<f32>(b.keys.x));
    boxes_hi[i] = vec4f(whi, bitcast<f32>(b.keys.y));
    elements[i] = vec4u(b.keys.x, ordered(wlo[params.axis]), i, 0u);
}

fn before(a: vec4u, b: vec4u) -> bool {
    if (a.x != b.x) {
        return a.x < b.x;
    }
    if (a.y != b.y) {
        return a.y < b.y;
    }
    return a.z < b.z;
}

var<workgroup> block: array<vec4u, SORT_BLOCK>;

@compute @workgroup_size(SORT_THREADS)
fn sort_local(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let base = (wg.y * ROW + wg.x) * SORT_BLOCK;
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
    let body = elements[p].z;
    sorted_lo[p] = boxes_lo[body];
    sorted_hi[p] = boxes_hi[body];
    sorted_body[p] = body;
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
    let end = a_hi[params.axis];
    for (var q = p + 1u; q < params.n; q++) {
        let b_lo = sorted_lo[q];
        // Sorted by within key, then start: past the first box of another key or one that
        // starts after this one ends, no box can meet this one.
        if (bitcast<u32>(b_lo.w) != bitcast<u32>(a_lo.w) || b_lo[params.axis] > end) {
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

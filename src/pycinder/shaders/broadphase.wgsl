// Broad phase on the GPU: world boxes, a bitonic sort into columns along one axis, a sweep.
//
//   world_boxes  one thread per body: its world box, grown outward so that it holds the exact box
//                despite float32 rounding; the range of box centres along each axis and the
//                histogram of widths across the sweep axis (atomics, for the grid)
//   grid_setup   one thread: the widest boxes (at most WIDE_BODIES) are wide; the cells of the
//                grid across the sweep axis are wider than every other box
//   columns      one thread per body (and per padding slot of the sort): its sort element
//                (within key, column, order-preserving bits of the box's start on the sweep
//                axis, body). The column is the grid cell holding the box's centre (boxes that
//                overlap are in the same or neighbouring columns), or WIDE
//   sort_local   one workgroup per block of SORT_BLOCK elements: the whole bitonic network up to
//                blocks of SORT_BLOCK (step k = 2), or the steps j < SORT_BLOCK of merge k
//   sort_step    one compare-exchange per thread: step j of merge k, for j >= SORT_BLOCK
//   gather       the boxes in sorted order, so that the sweep reads them in sequence; the list
//                of wide boxes
//   sweep        one thread per sorted box that is not wide: in its own and the 8 neighbouring
//                columns (found by binary search), the boxes after it in (start, body) order
//                that start before it ends are tested on all three axes and their groups; each
//                overlapping pair (i, j), i < j, is appended through an atomic counter, once (by
//                the box that starts first)
//   wide_sweep   one thread per sorted box: tested against every wide box
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
// Grid words: per axis k, the largest box centre (order-preserving bits) at G_HIGH + k and the
// complement of the smallest at G_LOW + k (every word starts at 0 and grows by atomicMax); the
// histogram of the boxes' widths across the sweep axis (by their float bits >> HIST_SHIFT, from
// 2^-31 to 2^33 in quarter octaves; narrower and wider ones in the first and last bins); and
// what grid_setup makes of them at G_SETUP: the cell size on the two column axes, the width from
// which a box is wide (f32 bits), and how many boxes are wide.
@group(0) @binding(11) var<storage, read_write> grid: array<atomic<u32>, GRID_WORDS>;
// Sorted positions of the boxes whose sweep ran out of its budget (counter[2] of them).
@group(0) @binding(12) var<storage, read_write> unfinished: array<u32>;

const G_HIGH: u32 = 4u;
const G_LOW: u32 = 8u;
const G_SETUP: u32 = 12u;
const G_HIST: u32 = 16u;
const HIST_BINS: u32 = 256u;
const HIST_SHIFT: u32 = 21u;        // float bits >> 21: quarter octaves
const HIST_OFFSET: u32 = 384u;      // the first bin's (2^-31)
const G_WIDE: u32 = 272u;           // G_HIST + HIST_BINS: sorted positions of the wide boxes
const GRID_WORDS: u32 = 304u;       // G_WIDE + WIDE_BODIES
const SWEEP_BUDGET: u32 = 4096u;    // loop steps of one box's sweep (see the sweep)
const WIDE_BODIES: u32 = 32u;       // most boxes kept out of the grid for their width
const WIDE: u32 = 0xFFFFFFFFu;      // the column of wide boxes (after every cell's)
const MAX_CELL: i32 = 65534;        // cells per axis, 0..MAX_CELL (16 bits of the column)
const COLUMN_CELLS: f32 = 65000.0;  // cells along an axis at most, before clamping
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

// The box's width across the sweep axis (the larger of its widths on the two column axes).
fn width(lo: vec3f, hi: vec3f) -> f32 {
    let a = (params.axis + 1u) % 3u;
    let b = (params.axis + 2u) % 3u;
    return max(max(hi[a] - lo[a], hi[b] - lo[b]), 0.0);
}

var<workgroup> local_grid: array<atomic<u32>, G_SETUP>;   // this workgroup's centre extremes
var<workgroup> local_hist: array<atomic<u32>, HIST_BINS>;  // and widths

@compute @workgroup_size(WORKGROUP)
fn world_boxes(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    if (lid < G_SETUP) {
        atomicStore(&local_grid[lid], 0u);
    }
    for (var h = lid; h < HIST_BINS; h += WORKGROUP) {
        atomicStore(&local_hist[h], 0u);
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
            let mid = ordered(0.5 * (wlo[k] + whi[k]));
            atomicMax(&local_grid[G_HIGH + k], mid);
            atomicMax(&local_grid[G_LOW + k], ~mid);
        }
        let bits = bitcast<u32>(width(wlo, whi)) >> HIST_SHIFT;
        atomicAdd(&local_hist[min(max(bits, HIST_OFFSET) - HIST_OFFSET, HIST_BINS - 1u)], 1u);
        boxes_lo[i] = vec4f(wlo, bitcast<f32>(b.keys.x));
        boxes_hi[i] = vec4f(whi, bitcast<f32>(b.keys.y));
    }
    workgroupBarrier();
    if (lid >= G_HIGH && lid < G_SETUP) {
        atomicMax(&grid[lid], atomicLoad(&local_grid[lid]));
    }
    for (var h = lid; h < HIST_BINS; h += WORKGROUP) {
        let count = atomicLoad(&local_hist[h]);
        if (count != 0u) {
            atomicAdd(&grid[G_HIST + h], count);
        }
    }
}

// One thread: the widest boxes (at most WIDE_BODIES, whole histogram bins, unless more than that
// are wider than the last bin's start) are kept out of the grid, whose cells are then as wide as
// the widest of the others (the upper edge of its bin). The columns pass decides which boxes are
// wide by the same threshold, so the cells hold every other box whatever the histogram says.
@compute @workgroup_size(1)
fn grid_setup() {
    var wide = 0u;
    var threshold = 0.0;  // every box is wide when there are few
    for (var h = HIST_BINS; h > 0u; h--) {
        let count = atomicLoad(&grid[G_HIST + h - 1u]);
        if (wide + count > WIDE_BODIES) {
            // The bin's upper edge; above the last bin (which holds every wider box), infinity.
            threshold = select(bitcast<f32>((h + HIST_OFFSET) << HIST_SHIFT),
                               bitcast<f32>(0x7F800000u), h == HIST_BINS);
            break;
        }
        wide += count;
    }
    for (var e = 0u; e < 2u; e++) {
        let k = (params.axis + 1u + e) % 3u;
        let low = unordered(~atomicLoad(&grid[G_LOW + k]));
        let high = unordered(atomicLoad(&grid[G_HIGH + k]));
        let size = max(max(threshold * COLUMN_MARGIN, (high - low) / COLUMN_CELLS), 1e-30);
        atomicStore(&grid[G_SETUP + e], bitcast<u32>(size));
    }
    atomicStore(&grid[G_SETUP + 2u], bitcast<u32>(threshold));
    atomicStore(&grid[G_SETUP + 3u], wide);
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
    var column = WIDE;
    if (width(lo.xyz, hi.xyz) < bitcast<f32>(atomicLoad(&grid[G_SETUP + 2u]))) {
        let a = (params.axis + 1u) % 3u;
        let b = (params.axis + 2u) % 3u;
        let start = vec2f(unordered(~atomicLoad(&grid[G_LOW + a])),
                          unordered(~atomicLoad(&grid[G_LOW + b])));
        let size = vec2f(bitcast<f32>(atomicLoad(&grid[G_SETUP])),
                         bitcast<f32>(atomicLoad(&grid[G_SETUP + 1u])));
        let mid = 0.5 * (lo.xyz + hi.xyz);
        let cell = (vec2f(mid[a], mid[b]) - start) / size;
        column = column_key(clamp(vec2i(floor(cell)), vec2i(0), vec2i(MAX_CELL)));
    }
    elements[i] = vec4u(bitcast<u32>(lo.w), column, ordered(lo[params.axis]), i);
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
    let e = elements[p];
    sorted_lo[p] = boxes_lo[e.w];
    sorted_hi[p] = boxes_hi[e.w];
    sorted_body[p] = e.w;
    if (e.y == WIDE) {
        let slot = atomicAdd(&counter[1], 1u);
        if (slot < WIDE_BODIES) {
            atomicStore(&grid[G_WIDE + slot], p);
        } else {
            atomicAdd(&counter[3], 1u);  // never: grid_setup counted them (the host checks)
        }
    }
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

// Test sorted boxes p and q; append their pair when they overlap (and are of different groups).
fn test_pair(p: u32, q: u32, a_lo: vec4f, a_hi: vec4f) {
    let b_lo = sorted_lo[q];
    let b_hi = sorted_hi[q];
    if (any(b_lo.xyz > a_hi.xyz) || any(a_lo.xyz > b_hi.xyz)) {
        return;
    }
    if (params.use_groups != 0u && bitcast<u32>(a_hi.w) == bitcast<u32>(b_hi.w)) {
        return;
    }
    let a = sorted_body[p];
    let b = sorted_body[q];
    let slot = atomicAdd(&counter[0], 1u);
    if (slot < params.capacity) {
        pairs[slot] = vec2u(min(a, b), max(a, b));
    }
}

// One thread per sorted box outside the wide column: in its own and the 8 neighbouring columns,
// the boxes after it in (start, body) order that start before it ends. On llvmpipe an invocation
// stops looping after 65535 loop steps in all, silently; so a box whose sweep takes more than
// SWEEP_BUDGET steps (per column at most: 9 columns of a search and a scan stay far below) stops
// and is listed, and the host finishes it.
@compute @workgroup_size(WORKGROUP)
fn sweep(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let p = thread_index(wg, lid, WORKGROUP);
    if (p >= params.n) {
        return;
    }
    let own = elements[p];
    if (own.y == WIDE) {
        return;  // the wide pass tests it against every box
    }
    let a_lo = sorted_lo[p];
    let a_hi = sorted_hi[p];
    let end = a_hi[params.axis];
    let cell = vec2i(i32(own.y >> 16u), i32(own.y & 0xFFFFu));  // as the columns pass found it
    var steps = 0u;
    for (var d = 0u; d < 9u; d++) {
        let other = cell + vec2i(i32(d % 3u) - 1, i32(d / 3u) - 1);
        if (any(other < vec2i(0)) || any(other > vec2i(MAX_CELL))) {
            continue;
        }
        let column = column_key(other);
        // The boxes of that column (and this within key) after this one in (start, body) order:
        // of each overlapping pair, the one that starts first (or has the lower index) finds
        // the other, in the other's column.
        for (var q = first_after(vec4u(own.x, column, own.z, own.w)); q < params.n; q++) {
            let e = elements[q];
            if (e.x != own.x || e.y != column || sorted_lo[q][params.axis] > end) {
                break;
            }
            steps++;
            if (steps > SWEEP_BUDGET) {
                unfinished[atomicAdd(&counter[2], 1u)] = p;
                return;
            }
            test_pair(p, q, a_lo, a_hi);
        }
    }
}

// One thread per sorted box: tested against every wide box of its within key (wide pairs once,
// from the later of the two in sort order).
@compute @workgroup_size(WORKGROUP)
fn wide_sweep(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let q = thread_index(wg, lid, WORKGROUP);
    if (q >= params.n) {
        return;
    }
    let e = elements[q];
    let wide = min(atomicLoad(&grid[G_SETUP + 3u]), WIDE_BODIES);
    for (var k = 0u; k < wide; k++) {
        let p = atomicLoad(&grid[G_WIDE + k]);
        if (elements[p].x == e.x && (e.y != WIDE || q > p)) {
            test_pair(p, q, sorted_lo[p], sorted_hi[p]);
        }
    }
}

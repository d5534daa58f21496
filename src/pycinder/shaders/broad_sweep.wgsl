// Broad phase, passes B6-B8 (pycinder/focused/broad/b6_sweep.py): the boxes in sorted order, then
// the pairs of boxes that overlap, appended through an atomic count.
//!include broad_common

@group(0) @binding(1) var<storage, read_write> elements: array<vec4u>;
@group(0) @binding(2) var<storage, read_write> boxes_lo: array<vec4f>;
@group(0) @binding(3) var<storage, read_write> boxes_hi: array<vec4f>;
@group(0) @binding(4) var<storage, read_write> sorted_lo: array<vec4f>;
@group(0) @binding(5) var<storage, read_write> sorted_hi: array<vec4f>;
@group(0) @binding(6) var<storage, read_write> sorted_body: array<u32>;
// The Counts struct (broad_common.py) as atomic words, at the COUNT_* word indices.
@group(0) @binding(7) var<storage, read_write> counts: array<atomic<u32>, COUNT_WORDS>;
@group(0) @binding(8) var<storage, read_write> pairs: array<vec2u>;
// The Grid struct (broad_common.py) as atomic words, at the GRID_* word indices.
@group(0) @binding(9) var<storage, read_write> grid: array<atomic<u32>, GRID_WORDS>;
// Sorted positions of the boxes whose sweep ran out of its budget (counts[COUNT_UNFINISHED]).
@group(0) @binding(10) var<storage, read_write> unfinished: array<u32>;

const SWEEP_BUDGET: u32 = 4096u;    // loop steps of one box's sweep (see the sweep)

// B6: the boxes in sorted order, so that the sweep reads them in sequence; the list of wide
// boxes.
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
        let slot = atomicAdd(&counts[COUNT_WIDE_LISTED], 1u);
        if (slot < WIDE_BODIES) {
            atomicStore(&grid[GRID_WIDE_LIST + slot], p);
        } else {
            atomicAdd(&counts[COUNT_WIDE_OVERFLOW], 1u);  // never: B2 counted them
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
    let slot = atomicAdd(&counts[COUNT_PAIRS], 1u);
    if (slot < params.capacity) {
        pairs[slot] = vec2u(min(a, b), max(a, b));
    }
}

// B7: one thread per sorted box outside the wide column: in its own and the 8 neighbouring
// columns (found by binary search), the boxes after it in (start, body) order that start before
// it ends are tested on all three axes and their groups. On llvmpipe an invocation stops looping
// after 65535 loop steps in all, silently; so a box whose sweep takes more than SWEEP_BUDGET
// steps (per column at most: 9 columns of a search and a scan stay far below) stops and is
// listed, and the host finishes it.
@compute @workgroup_size(WORKGROUP)
fn sweep(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let p = thread_index(wg, lid, WORKGROUP);
    if (p >= params.n) {
        return;
    }
    let own = elements[p];
    if (own.y == WIDE) {
        return;  // B8 tests it against every box
    }
    let a_lo = sorted_lo[p];
    let a_hi = sorted_hi[p];
    let end = a_hi[params.axis];
    let cell = vec2i(i32(own.y >> 16u), i32(own.y & 0xFFFFu));  // as B3 found it
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
                unfinished[atomicAdd(&counts[COUNT_UNFINISHED], 1u)] = p;
                return;
            }
            test_pair(p, q, a_lo, a_hi);
        }
    }
}

// B8: one thread per sorted box: tested against every wide box of its within key (wide pairs
// once, from the later of the two in sort order).
@compute @workgroup_size(WORKGROUP)
fn wide_sweep(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let q = thread_index(wg, lid, WORKGROUP);
    if (q >= params.n) {
        return;
    }
    let e = elements[q];
    let wide = min(atomicLoad(&grid[GRID_WIDE_COUNT]), WIDE_BODIES);
    for (var k = 0u; k < wide; k++) {
        let p = atomicLoad(&grid[GRID_WIDE_LIST + k]);
        if (elements[p].x == e.x && (e.y != WIDE || q > p)) {
            test_pair(p, q, sorted_lo[p], sorted_hi[p]);
        }
    }
}

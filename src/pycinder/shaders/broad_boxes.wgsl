// Broad phase, passes B1-B3 (pycinder/focused/broad/b1_boxes.py): world boxes, the grid across the
// sweep axis, and each box's sort element.
//!include broad_common

@group(0) @binding(1) var<storage, read> bodies: array<Body>;
@group(0) @binding(2) var<storage, read_write> boxes_lo: array<vec4f>;  // w: within key bits
@group(0) @binding(3) var<storage, read_write> boxes_hi: array<vec4f>;  // w: group bits
@group(0) @binding(4) var<storage, read_write> elements: array<vec4u>;
// The Grid struct (broad_common.py) as atomic words, at the GRID_* word indices.
@group(0) @binding(5) var<storage, read_write> grid: array<atomic<u32>, GRID_WORDS>;

const HIST_SHIFT: u32 = 21u;        // float bits >> 21: quarter octaves
const HIST_OFFSET: u32 = 384u;      // the first bin's (2^-31)
const CENTRE_WORDS: u32 = GRID_LOW + 3u;  // the grid's first words: high and low centres
const COLUMN_CELLS: f32 = 65000.0;  // cells along an axis at most, before clamping
const COLUMN_MARGIN: f32 = 1.0625;  // cells wider than the widest box, by more than rounding

var<workgroup> local_grid: array<atomic<u32>, CENTRE_WORDS>;  // this workgroup's centre extremes
var<workgroup> local_hist: array<atomic<u32>, HIST_BINS>;     // and widths

// B1: one thread per body: its world box, grown outward so that it holds the exact box despite
// float32 rounding; the range of box centres along each axis and the histogram of widths across
// the sweep axis (by their float bits >> HIST_SHIFT, from 2^-31 to 2^33 in quarter octaves;
// narrower and wider ones in the first and last bins), reduced per workgroup first.
@compute @workgroup_size(WORKGROUP)
fn world_boxes(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    if (lid < CENTRE_WORDS) {
        atomicStore(&local_grid[lid], 0u);
    }
    for (var h = lid; h < HIST_BINS; h += WORKGROUP) {
        atomicStore(&local_hist[h], 0u);
    }
    workgroupBarrier();
    let i = thread_index(wg, lid, WORKGROUP);
    if (i < params.n) {
        let b = bodies[i];
        let lo = b.lo;
        let hi = b.hi;
        let radius = b.radius;
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
            // Grown by the rounding bound of this row's arithmetic (see pycinder.focused.broad).
            let pad = PAD_SCALE * (abs(row.w) + dot(abs(m), reach + vec3f(radius)))
                + params.base_pad;
            wlo[k] = max(box_lo, c - half) - pad;
            whi[k] = min(box_hi, c + half) + pad;
            let mid = ordered(0.5 * (wlo[k] + whi[k]));
            atomicMax(&local_grid[GRID_HIGH + k], mid);
            atomicMax(&local_grid[GRID_LOW + k], ~mid);
        }
        let bits = bitcast<u32>(width(wlo, whi)) >> HIST_SHIFT;
        atomicAdd(&local_hist[min(max(bits, HIST_OFFSET) - HIST_OFFSET, HIST_BINS - 1u)], 1u);
        boxes_lo[i] = vec4f(wlo, bitcast<f32>(b.within));
        boxes_hi[i] = vec4f(whi, bitcast<f32>(b.group));
    }
    workgroupBarrier();
    if (lid < CENTRE_WORDS) {
        atomicMax(&grid[lid], atomicLoad(&local_grid[lid]));
    }
    for (var h = lid; h < HIST_BINS; h += WORKGROUP) {
        let count = atomicLoad(&local_hist[h]);
        if (count != 0u) {
            atomicAdd(&grid[GRID_HISTOGRAM + h], count);
        }
    }
}

// B2, one thread: the widest boxes (at most WIDE_BODIES, whole histogram bins, unless more than
// that are wider than the last bin's start) are kept out of the grid, whose cells are then as
// wide as the widest of the others (the upper edge of its bin). B3 decides which boxes are wide
// by the same threshold, so the cells hold every other box whatever the histogram says.
@compute @workgroup_size(1)
fn grid_setup() {
    var wide = 0u;
    var threshold = 0.0;  // every box is wide when there are few
    for (var h = HIST_BINS; h > 0u; h--) {
        let count = atomicLoad(&grid[GRID_HISTOGRAM + h - 1u]);
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
        let low = unordered(~atomicLoad(&grid[GRID_LOW + k]));
        let high = unordered(atomicLoad(&grid[GRID_HIGH + k]));
        let size = max(max(threshold * COLUMN_MARGIN, (high - low) / COLUMN_CELLS), 1e-30);
        atomicStore(&grid[GRID_CELL_SIZE + e], bitcast<u32>(size));
    }
    atomicStore(&grid[GRID_WIDE_FROM], bitcast<u32>(threshold));
    atomicStore(&grid[GRID_WIDE_COUNT], wide);
}

// B3: one thread per body (and per padding slot of the sort): its sort element (within key,
// column, order-preserving bits of the box's start on the sweep axis, body). The column is the
// grid cell holding the box's centre (boxes that overlap are in the same or neighbouring
// columns), or WIDE.
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
    if (width(lo.xyz, hi.xyz) < bitcast<f32>(atomicLoad(&grid[GRID_WIDE_FROM]))) {
        let a = (params.axis + 1u) % 3u;
        let b = (params.axis + 2u) % 3u;
        let start = vec2f(unordered(~atomicLoad(&grid[GRID_LOW + a])),
                          unordered(~atomicLoad(&grid[GRID_LOW + b])));
        let size = vec2f(bitcast<f32>(atomicLoad(&grid[GRID_CELL_SIZE])),
                         bitcast<f32>(atomicLoad(&grid[GRID_CELL_SIZE + 1u])));
        let mid = 0.5 * (lo.xyz + hi.xyz);
        let cell = (vec2f(mid[a], mid[b]) - start) / size;
        column = column_key(clamp(vec2i(floor(cell)), vec2i(0), vec2i(MAX_CELL)));
    }
    elements[i] = vec4u(bitcast<u32>(lo.w), column, ordered(lo[params.axis]), i);
}

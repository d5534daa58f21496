// Pass P2 of the GPU tile planner, atlas (compute): the integer part of
// pycinder.focused.plan.plan_numpy.plan_tiles (lead=None): every kept window cut into tiles, in
// phases, the tiles packed into the atlas's bands and the bands into rounds, with the same tiles in
// the same order as _phases_of, _layout, _place and concat_plans make them (see
// focused/plan/p2_atlas.py for the whole argument).
//
// Four entry points, dispatched in order in one compute pass:
//   count  (one workgroup of GROUP): totals over the pairs, which windows are probed, and per
//          pair the tiles and class widths of the pairs before it (a blocked scan); the plan's
//          constants (atlas width, classes, bands, rounds) and the indirect arguments;
//   place  (a thread per tile): each tile's band, counted per band with its band cut;
//   bands  (one workgroup of GROUP): per band, the tiles and cuts up to it (a blocked scan), its
//          round and row; each round's rows;
//   write  (a thread per tile): each tile (and a cut tile's second part) at its place in the
//          plan's order.
//
// Sections of the tiles, in their phase's order (a window is in one of S, O, L; L's are in P too):
//   S: small windows whole (phase 0, probes on), O: pieces of windows not probed (phase 0; every
//   window when probes are off or none is large), L: probes of large windows (phase 0), P: pieces
//   of large windows (phase 1, FLAG_SKIP_IF_HIT).
// Lanes of the pair scan: section s, class c: count at 10 s + c, width at 10 s + 5 + c.
//!include layout

const SEC_S: u32 = 0u;
const SEC_O: u32 = 1u;
const SEC_L: u32 = 2u;
const SEC_P: u32 = 3u;
const SEC_NONE: u32 = 4u;
const LANES: u32 = 40u;
const CUT_BIT: u32 = 65536u;   // band count word: tiles starting in the band | cut << 16
// Cap of the rows per round: above the rows of every plan of MAX_TILES tiles (at most a band of
// 128 rows per tile, plus 10), so that capping a larger budget changes no round.
const ROWS_CAP: u32 = 1073741824u;

@group(0) @binding(0) var<storage, read> windows: array<AtlasWindow>;
@group(0) @binding(1) var<uniform> params: AtlasParams;
@group(0) @binding(2) var<storage, read_write> prefix: array<AtlasPairPrefix>;
@group(0) @binding(3) var<storage, read_write> state: AtlasState;
@group(0) @binding(4) var<storage, read_write> args: array<u32>;
@group(0) @binding(5) var<storage, read_write> band_counts: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> band_info: array<vec4u>;
@group(0) @binding(7) var<storage, read_write> summary: AtlasSummaryBuffer;
@group(0) @binding(8) var<storage, read_write> tiles: array<AtlasTile>;

struct AtlasSummaryBuffer {
    head: AtlasSummary,
    round_rows: array<u32>,  // rows of each round, in the plan's order of rounds
};

var<workgroup> scan: array<vec4u, GROUP>;
var<workgroup> totals: array<vec4u, 10>;
var<workgroup> wg_kept: atomic<u32>;
var<workgroup> wg_pix_lo: atomic<u32>;
var<workgroup> wg_pix_hi: atomic<u32>;
var<workgroup> wg_big: atomic<u32>;      // bit 0: a window larger than a probe; bit 1: a dense one
var<workgroup> wg_bound: atomic<u32>;    // tiles, at most (saturated at MAX_TILES + 1)
var<workgroup> wg_go: u32;               // uniform decisions of thread 0
var<workgroup> wg_mode: u32;             // bit 0: probes; bit 1: only dense windows are large
var<workgroup> wg_bands: u32;

// ---------------------------------------------------------------------------------------------
// Integers.

fn sat_add(a: u32, b: u32) -> u32 {
    let s = a + b;
    return select(s, 0xffffffffu, s < a);
}

// 64-bit (lo, hi) sum and product of 32-bit words.
fn add64(a: vec2u, b: vec2u) -> vec2u {
    let lo = a.x + b.x;
    return vec2u(lo, a.y + b.y + select(0u, 1u, lo < a.x));
}

fn mul64(a: u32, b: u32) -> vec2u {
    let a0 = a & 0xffffu;
    let a1 = a >> 16u;
    let b0 = b & 0xffffu;
    let b1 = b >> 16u;
    let mid = a1 * b0;
    let mid2 = a0 * b1;
    var r = vec2u(a0 * b0, a1 * b1);
    r = add64(r, vec2u(mid << 16u, mid >> 16u));
    r = add64(r, vec2u(mid2 << 16u, mid2 >> 16u));
    return r;
}

fn ceil_div(a: u32, b: u32) -> u32 {
    return a / b + select(0u, 1u, a % b != 0u);
}

// ---------------------------------------------------------------------------------------------
// Tiles of a window.

//!include plan_height_classes.wgsl

// Pieces of a window cut into a grid of tiles of at most MAX_TILE_W x MAX_TILE_H (saturated).
fn pieces(w: u32, h: u32) -> u32 {
    let nx = ceil_div(w, MAX_TILE_W);
    let ny = ceil_div(h, MAX_TILE_H);
    if (ny != 0u && nx > 0xffffffffu / ny) {
        return 0xffffffffu;
    }
    return nx * ny;
}

// The section of a pair's window (SEC_NONE: no window). mode: see wg_mode.
fn section_of(win: AtlasWindow, mode: u32) -> u32 {
    if (win.kept == 0u) {
        return SEC_NONE;
    }
    if ((mode & 1u) == 0u) {
        return SEC_O;  // one phase: every window's pieces
    }
    var big = win.w > PROBE_W || win.h > PROBE_H;
    if ((mode & 2u) != 0u) {
        big = big && win.dense != 0u;
    }
    if (big) {
        return SEC_L;
    }
    if (win.w <= MAX_TILE_W && win.h <= MAX_TILE_H) {
        return SEC_S;
    }
    return SEC_O;
}

// Add the tiles of a window cut in pieces to lanes of section s.
fn add_pieces(acc: ptr<function, array<u32, LANES>>, s: u32, w: u32, h: u32) {
    let nx = ceil_div(w, MAX_TILE_W);
    let ny = ceil_div(h, MAX_TILE_H);
    let last = class_of(h - MAX_TILE_H * (ny - 1u));
    let base = 10u * s;
    (*acc)[base + 4u] += (ny - 1u) * nx;           // full rows: the tallest class
    (*acc)[base + 9u] += (ny - 1u) * w;
    (*acc)[base + last] += nx;                      // the last row
    (*acc)[base + 5u + last] += w;
}

// Add a window's tiles to the lanes (its section's, and P's for a probed window).
fn add_window(acc: ptr<function, array<u32, LANES>>, win: AtlasWindow, s: u32) {
    switch s {
        case SEC_S: {
            let c = class_of(win.h);
            (*acc)[c] += 1u;
            (*acc)[5u + c] += win.w;
        }
        case SEC_O: {
            add_pieces(acc, SEC_O, win.w, win.h);
        }
        case SEC_L: {  // and the window's pieces in SEC_P
            let c = class_of(min(win.h, PROBE_H));
            (*acc)[20u + c] += 1u;
            (*acc)[25u + c] += min(win.w, PROBE_W);
            add_pieces(acc, SEC_P, win.w, win.h);
        }
        default: {}
    }
}

// ---------------------------------------------------------------------------------------------
// Workgroup scans (GROUP = 256 threads: 8 steps).

fn scan_step(lid: u32, k: u32) {
    var v = scan[lid];
    if (lid >= k) {
        v += scan[lid - k];
    }
    workgroupBarrier();
    scan[lid] = v;
    workgroupBarrier();
}

// The sum of `own` over the threads before this one; the sum over all is left in totals[slot].
fn exclusive_scan(lid: u32, own: vec4u, slot: u32) -> vec4u {
    scan[lid] = own;
    workgroupBarrier();
    scan_step(lid, 1u);
    scan_step(lid, 2u);
    scan_step(lid, 4u);
    scan_step(lid, 8u);
    scan_step(lid, 16u);
    scan_step(lid, 32u);
    scan_step(lid, 64u);
    scan_step(lid, 128u);
    let inclusive = scan[lid];
    if (lid == GROUP - 1u) {
        totals[slot] = inclusive;
    }
    workgroupBarrier();
    return inclusive - own;
}

fn lane(l: u32) -> u32 {
    return totals[l / 4u][l % 4u];
}

// ---------------------------------------------------------------------------------------------
// Rounds: band b of class c of a phase (index i = 5 phase + c), as _layout's runs place it.

fn band_round_row(i: u32, b: u32) -> vec2u {
    let f0 = state.first_run[i];
    if (b < f0) {
        return vec2u(state.round_start[i], state.row_start[i] + b * class_rows(i % 5u));
    }
    let b2 = b - f0;
    let q = state.per_round[i];
    return vec2u(state.round_start[i] + select(0u, 1u, f0 > 0u) + b2 / q,
                 (b2 % q) * class_rows(i % 5u));
}

// (phase, class, band in the class) of a band of the plan.
fn band_place(g: u32) -> vec3u {
    let phase = select(0u, 1u, g >= state.bands0);
    let i = 5u * phase;
    // A class without bands starts where the next one does: the count lands on the class
    // that holds the band (no loop: llvmpipe counts every loop step, see the host's notes).
    let c = select(0u, 1u, state.band_first[i + 1u] <= g)
        + select(0u, 1u, state.band_first[i + 2u] <= g)
        + select(0u, 1u, state.band_first[i + 3u] <= g)
        + select(0u, 1u, state.band_first[i + 4u] <= g);
    return vec3u(phase, c, g - state.band_first[i + c]);
}

// ---------------------------------------------------------------------------------------------
// count

// The plan's constants, by thread 0 from the pair totals (lanes in totals).
fn plan_constants(kept: u32, pixels: vec2u, mode: u32, bound: u32) {
    var h = AtlasSummary();
    h.windows = kept;
    h.separated = params.pairs - kept;
    h.pixels_lo = pixels.x;
    h.pixels_hi = pixels.y;
    var s = AtlasState();
    var sec = vec4u(0u);
    for (var x = 0u; x < 4u; x++) {
        for (var c = 0u; c < 5u; c++) {
            sec[x] += lane(10u * x + c);
        }
    }
    s.sections = sec;
    s.tiles0 = sec.x + sec.y + sec.z;
    s.tiles = s.tiles0 + sec.w;
    s.probes = mode & 1u;
    // Widths of the classes of the phases, and the atlas width (fitted_width over both phases).
    var widest = 1u;
    for (var c = 0u; c < 5u; c++) {
        let w0 = lane(5u + c) + lane(15u + c) + lane(25u + c);
        let w1 = lane(35u + c);
        widest = max(widest, min(w0 + w1, ATLAS_WIDTH));
        for (var x = 0u; x < 4u; x++) {
            var before = vec2u(0u);
            if (x == SEC_O || x == SEC_L) {
                before += vec2u(lane(c), lane(5u + c));
            }
            if (x == SEC_L) {
                before += vec2u(lane(10u + c), lane(15u + c));
            }
            s.before_count[5u * x + c] = before.x;
            s.before_width[5u * x + c] = before.y;
        }
    }
    var width = ATLAS_WIDTH;
    if (widest < ATLAS_WIDTH) {
        width = max(MIN_ATLAS_WIDTH, 1u << (32u - countLeadingZeros(widest - 1u)));
    }
    if (kept == 0u) {
        width = ATLAS_WIDTH;  // an empty plan's
    }
    s.width = width;
    s.shift = countTrailingZeros(width);
    // Rows per round: max(budget_pixels // width, 1), as 64 bits shifted, capped.
    var rows = (params.budget_lo >> s.shift) | (params.budget_hi << (32u - s.shift));
    if ((params.budget_hi >> s.shift) != 0u) {
        rows = ROWS_CAP;
    }
    let budget = clamp(rows, 1u, ROWS_CAP);
    s.rows_budget = budget;
    // Per phase: class order, bands, and the runs of bands into rounds (_layout's loop, a class
    // at a time).
    var band = 0u;
    var rounds = 0u;
    for (var p = 0u; p < 2u; p++) {
        var first = 0u;
        var r = 0u;
        var at = 0u;
        var any = false;
        for (var c = 0u; c < 5u; c++) {
            let i = 5u * p + c;
            var count = 0u;
            var width_c = 0u;
            if (p == 0u) {
                count = lane(c) + lane(10u + c) + lane(20u + c);
                width_c = lane(5u + c) + lane(15u + c) + lane(25u + c);
            } else {
                count = lane(30u + c);
                width_c = lane(35u + c);
            }
            let bands = (width_c + width - 1u) >> s.shift;
            s.class_first[i] = first;
            s.band_first[i] = band;
            s.class_bands[i] = bands;
            first += count;
            band += bands;
            let rows_c = class_rows(c);
            let q = max(budget / rows_c, 1u);
            s.per_round[i] = q;
            if (bands == 0u) {
                s.round_start[i] = rounds + r;
                s.row_start[i] = at;
                continue;
            }
            any = true;
            if (at > 0u && at + rows_c > budget) {
                r += 1u;
                at = 0u;
            }
            var f0 = 0u;
            if (at > 0u) {
                f0 = min(bands, (budget - at) / rows_c);
            }
            s.round_start[i] = rounds + r;
            s.row_start[i] = at;
            s.first_run[i] = f0;
            if (bands <= f0) {
                at += bands * rows_c;
            } else {
                let b2 = bands - 1u - f0;
                r += select(0u, 1u, f0 > 0u) + b2 / q;
                at = (b2 % q + 1u) * rows_c;
            }
        }
        if (p == 0u) {
            s.bands0 = band;
        }
        if (any) {
            rounds += r + 1u;
        }
        if (p == 0u) {
            s.rounds0 = rounds;
        }
    }
    s.bands = band;
    s.rounds = rounds;
    h.atlas_width = width;
    h.rounds = rounds;
    h.phases = select(0u, 1u, s.tiles0 > 0u) + select(0u, 1u, sec.w > 0u);
    h.phase_rounds = s.rounds0;
    h.pieces = s.tiles;
    h.bands = band;
    h.rows_budget = budget;
    // Capacity: the bands (and rounds, fewer) must fit their buffers; the tiles are checked
    // once the cuts are counted (stage bands). Until then, tiles + bands bounds the records.
    s.fits = 1u;
    if (bound > MAX_TILES) {
        s.fits = 0u;
        h.needed = 0xffffffffu;
    } else if (band > params.band_capacity) {
        s.fits = 0u;
        h.needed = s.tiles + band;
    }
    if (s.fits == 0u) {
        s.tiles = 0u;
        s.bands = 0u;
        s.bands0 = 0u;
    }
    h.fits = s.fits;
    summary.head = h;
    state = s;
    let groups = ceil_div(s.tiles, WORKGROUP);
    args[0] = min(groups, ROW);
    args[1] = ceil_div(groups, ROW);
    args[2] = 1u;
    wg_bands = s.bands;
}

@compute @workgroup_size(GROUP)
fn count(@builtin(local_invocation_index) lid: u32) {
    let k = params.pairs;
    let per = ceil_div(k, GROUP);
    let first = min(lid * per, k);
    let last = min(first + per, k);
    if (lid == 0u) {
        atomicStore(&wg_kept, 0u);
        atomicStore(&wg_pix_lo, 0u);
        atomicStore(&wg_pix_hi, 0u);
        atomicStore(&wg_big, 0u);
        atomicStore(&wg_bound, 0u);
    }
    workgroupBarrier();
    // 1. Totals: windows, their pixels, whether any is large, a bound on the tiles.
    var kept = 0u;
    var pixels = vec2u(0u);
    var big = 0u;
    var bound = 0u;
    for (var p = first; p < last; p++) {
        let win = windows[p];
        if (win.kept == 0u) {
            continue;
        }
        kept += 1u;
        pixels = add64(pixels, mul64(win.w, win.h));
        if (win.w > PROBE_W || win.h > PROBE_H) {
            big |= select(1u, 3u, win.dense != 0u);
        }
        bound = min(sat_add(bound, sat_add(pieces(win.w, win.h), 1u)), MAX_TILES + 1u);
    }
    atomicAdd(&wg_kept, kept);
    let old = atomicAdd(&wg_pix_lo, pixels.x);
    atomicAdd(&wg_pix_hi, pixels.y + select(0u, 1u, old + pixels.x < old));
    atomicOr(&wg_big, big);
    atomicAdd(&wg_bound, bound);
    workgroupBarrier();
    if (lid == 0u) {
        let pix = vec2u(atomicLoad(&wg_pix_lo), atomicLoad(&wg_pix_hi));
        // Only dense pairs' windows are probed in a plan of fewer than PROBE_PLAN pixels whose
        // faces are given.
        let dense_only = params.faces != 0u && pix.y == 0u && pix.x < PROBE_PLAN;
        let any_big = atomicLoad(&wg_big) & select(1u, 2u, dense_only);
        wg_mode = select(0u, 1u, params.probe != 0u && any_big != 0u)
            | select(0u, 2u, dense_only);
        wg_go = select(1u, 0u, atomicLoad(&wg_bound) > MAX_TILES);
        if (wg_go == 0u) {
            // Too many tiles to plan: say so, and leave every later stage without work.
            for (var g = 0u; g < LANES / 4u; g++) {
                totals[g] = vec4u(0u);
            }
            plan_constants(atomicLoad(&wg_kept), pix, 0u, MAX_TILES + 1u);
        }
    }
    if (workgroupUniformLoad(&wg_go) == 0u) {
        return;
    }
    let mode = wg_mode;
    // 2. Each thread's lanes over its block of pairs; 3. their exclusive scan.
    var acc: array<u32, LANES>;
    for (var p = first; p < last; p++) {
        let win = windows[p];
        add_window(&acc, win, section_of(win, mode));
    }
    for (var g = 0u; g < LANES / 4u; g++) {
        let before = exclusive_scan(lid, vec4u(acc[4u * g], acc[4u * g + 1u], acc[4u * g + 2u],
                                               acc[4u * g + 3u]), g);
        acc[4u * g] = before.x;
        acc[4u * g + 1u] = before.y;
        acc[4u * g + 2u] = before.z;
        acc[4u * g + 3u] = before.w;
    }
    // 4. Per pair, what the pairs before it hold.
    for (var p = first; p < last; p++) {
        let win = windows[p];
        let s = section_of(win, mode);
        var pre: AtlasPairPrefix;
        pre.tiles = vec4u(acc[0] + acc[1] + acc[2] + acc[3] + acc[4],
                          acc[10] + acc[11] + acc[12] + acc[13] + acc[14],
                          acc[20] + acc[21] + acc[22] + acc[23] + acc[24],
                          acc[30] + acc[31] + acc[32] + acc[33] + acc[34]);
        let b = 10u * min(s, SEC_L);
        pre.count0 = array<u32, 5>(acc[b], acc[b + 1u], acc[b + 2u], acc[b + 3u], acc[b + 4u]);
        pre.width0 = array<u32, 5>(acc[b + 5u], acc[b + 6u], acc[b + 7u], acc[b + 8u],
                                   acc[b + 9u]);
        pre.count1 = array<u32, 5>(acc[30], acc[31], acc[32], acc[33], acc[34]);
        pre.width1 = array<u32, 5>(acc[35], acc[36], acc[37], acc[38], acc[39]);
        prefix[p] = pre;
        add_window(&acc, win, s);
    }
    // 5. The plan's constants; the band counts cleared for stage place.
    workgroupBarrier();
    if (lid == 0u) {
        plan_constants(atomicLoad(&wg_kept), vec2u(atomicLoad(&wg_pix_lo),
                       atomicLoad(&wg_pix_hi)), mode, atomicLoad(&wg_bound));
    }
    let bands = workgroupUniformLoad(&wg_bands);
    for (var g = lid; g < bands; g += GROUP) {
        atomicStore(&band_counts[g], 0u);
    }
}

// ---------------------------------------------------------------------------------------------
// A tile of the plan, from its index in the phases' order (phase 0's tiles, then phase 1's).

struct Placed {
    pair: u32,
    u0: u32,
    v0: u32,
    w: u32,
    h: u32,
    moved: u32,
    phase: u32,
    order: u32,   // its index in the plan's class order (phase 0's, then phase 1's)
    band: u32,    // its band in the plan's bands
    col: u32,     // its column in the band
    first_w: u32, // the width before the band's end (w when it is not cut)
};

// The pair whose tiles of section x hold tile t of the section: the last pair whose prefix is
// at most t.
fn pair_of(x: u32, t: u32) -> u32 {
    var lo = 0u;
    var hi = params.pairs;
    while (hi - lo > 1u) {
        let mid = (lo + hi) / 2u;
        if (prefix[mid].tiles[x] <= t) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

fn placed(t: u32) -> Placed {
    var out: Placed;
    let sec = state.sections;
    var x = SEC_P;
    var k = t - state.tiles0;
    if (t < sec.x) {
        x = SEC_S;
        k = t;
    } else if (t < sec.x + sec.y) {
        x = SEC_O;
        k = t - sec.x;
    } else if (t < state.tiles0) {
        x = SEC_L;
        k = t - sec.x - sec.y;
    }
    let p = pair_of(x, k);
    k -= prefix[p].tiles[x];                     // the tile's index among its window's
    let win = windows[p];
    out.pair = p;
    out.phase = select(0u, 1u, x == SEC_P);
    out.moved = select(1u, 0u, x == SEC_S);
    var rank = 0u;                         // tiles of its class before it in the window
    var before = 0u;                       // and their widths
    if (x == SEC_S) {
        out.w = win.w;
        out.h = win.h;
    } else if (x == SEC_L) {
        out.w = min(win.w, PROBE_W);
        out.h = min(win.h, PROBE_H);
        out.u0 = (win.w - out.w) / 2u;
        out.v0 = (win.h - out.h) / 2u;
    } else {
        let nx = ceil_div(win.w, MAX_TILE_W);
        let ny = ceil_div(win.h, MAX_TILE_H);
        let col = k % nx;
        let row = k / nx;
        out.u0 = col * MAX_TILE_W;
        out.v0 = row * MAX_TILE_H;
        out.w = min(win.w - out.u0, MAX_TILE_W);
        out.h = min(win.h - out.v0, MAX_TILE_H);
        if (row + 1u < ny || class_of(out.h) == 4u) {
            rank = k;
            before = row * win.w + out.u0;
        } else {
            rank = col;
            before = out.u0;
        }
    }
    let c = class_of(out.h);
    let i = 5u * out.phase + c;
    var count = prefix[p].count0[c];
    var width = prefix[p].width0[c];
    if (x == SEC_P) {
        count = prefix[p].count1[c];
        width = prefix[p].width1[c];
    }
    out.order = select(0u, state.tiles0, x == SEC_P) + state.class_first[i]
        + state.before_count[5u * x + c] + count + rank;
    let start = state.before_width[5u * x + c] + width + before;
    let w_atlas = state.width;
    out.band = state.band_first[i] + (start >> state.shift);
    out.col = start & (w_atlas - 1u);
    out.first_w = min(out.w, w_atlas - out.col);
    return out;
}

fn tile_index(wg: vec3u, lid: u32) -> u32 {
    return (wg.y * ROW + wg.x) * WORKGROUP + lid;
}

// ---------------------------------------------------------------------------------------------
// place

@compute @workgroup_size(WORKGROUP)
fn place(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let t = tile_index(wg, lid);
    if (t >= state.tiles) {
        return;
    }
    let q = placed(t);
    atomicAdd(&band_counts[q.band], 1u + select(0u, CUT_BIT, q.first_w < q.w));
}

// ---------------------------------------------------------------------------------------------
// bands

@compute @workgroup_size(GROUP)
fn bands(@builtin(local_invocation_index) lid: u32) {
    if (lid == 0u) {
        wg_bands = state.bands;
    }
    let n = workgroupUniformLoad(&wg_bands);
    let per = ceil_div(n, GROUP);
    let first = min(lid * per, n);
    let last = min(first + per, n);
    var own = vec4u(0u);
    for (var g = first; g < last; g++) {
        let word = atomicLoad(&band_counts[g]);
        own += vec4u(word % CUT_BIT, word / CUT_BIT, 0u, 0u);
    }
    var upto = exclusive_scan(lid, own, 0u);
    for (var g = first; g < last; g++) {
        let word = atomicLoad(&band_counts[g]);
        upto += vec4u(word % CUT_BIT, word / CUT_BIT, 0u, 0u);
        let at = band_place(g);
        let i = 5u * at.x + at.y;
        let rr = band_round_row(i, at.z);
        band_info[g] = vec4u(upto.x, upto.y, rr.x, rr.y);
        // The last band of a round gives the round's rows.
        var next_round = 0xffffffffu;
        if (g + 1u < n) {
            let nat = band_place(g + 1u);
            next_round = band_round_row(5u * nat.x + nat.y, nat.z).x;
        }
        if (next_round != rr.x) {
            summary.round_rows[rr.x] = rr.y + class_rows(at.y);
        }
        if (g + 1u == state.bands0) {
            summary.head.phase_tiles = state.tiles0 + upto.y;
        }
    }
    if (lid == 0u && state.fits != 0u) {
        let cuts = totals[0].y;
        let records = state.tiles + cuts;
        summary.head.tiles = records;
        summary.head.cuts = cuts;
        summary.head.needed = records;
        let fits = select(0u, 1u, records <= params.capacity);
        summary.head.fits = fits;
        state.fits = fits;
        if (n == 0u) {
            summary.head.phase_tiles = 0u;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// write

@compute @workgroup_size(WORKGROUP)
fn write(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let t = tile_index(wg, lid);
    if (t >= state.tiles || state.fits == 0u) {
        return;
    }
    let q = placed(t);
    var cuts_before = 0u;                  // second parts in bands before this tile's band
    if (q.band >= 2u) {
        cuts_before = band_info[q.band - 2u].y;
    }
    let band = band_info[q.band];
    var out: AtlasTile;
    out.window = vec4u(q.col, band.w, q.first_w, q.h);
    out.pair = q.pair;
    out.u0 = q.u0;
    out.v0 = q.v0;
    out.moved = q.moved;
    out.flags = select(0u, FLAG_SKIP_IF_HIT, q.phase == 1u);
    out.round = band.z;
    out.phase = q.phase;
    tiles[q.order + cuts_before] = out;
    if (q.first_w < q.w) {
        // The second part: after the tiles that start in the next band (the tiles up to that
        // band, and the second parts before this one).
        let next = band_info[q.band + 1u];
        var before = 0u;
        if (q.band >= 1u) {
            before = band_info[q.band - 1u].y;
        }
        out.window = vec4u(0u, next.w, q.w - q.first_w, q.h);
        out.round = next.z;
        out.shift = q.first_w;
        tiles[next.x + before] = out;
    }
}

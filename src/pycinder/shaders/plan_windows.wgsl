// Tile planner, pass P1 (compute; pycinder/focused/plan/p1_windows.py): the window of each
// candidate pair, as pycinder.focused.plan.plan_numpy_windows._plan_chunk plans it, in single
// precision. One invocation per pair.
//
// Each body comes measured from its own anchor (a point at its oriented box's centre, given
// exactly as hi + lo in two f32 vectors). A pair is planned in the frame of its anchor body
// (the one with the smaller world box): the other body's quantities are moved by the offset d
// between the two anchors, taken as (hi_o - hi_p) + (lo_o - lo_p), exact for nearby bodies. So
// every rounding is relative to the pair's own extent and offset, not to the distance from the
// world's origin, and the window's origin is written relative to the anchor.
//
// The structs PlanBody, PlanWindow and PlanParams are generated from p1_windows.py, AtlasWindow
// (what pass P2 reads of each pair) from p2_atlas.py; so are the constants WORKGROUP, ROW,
// MARGIN_PX, FLAG_COUNT_BACK, COS_TILT, SIN_TILT and PROBE_FACES.

@group(0) @binding(0) var<storage, read> bodies: array<PlanBody>;
@group(0) @binding(1) var<storage, read> pairs: array<vec2u>;
@group(0) @binding(2) var<storage, read> pair_tolerances: array<f32>;
@group(0) @binding(3) var<storage, read_write> windows: array<PlanWindow>;
@group(0) @binding(4) var<uniform> params: PlanParams;
@group(0) @binding(5) var<storage, read> faces: array<u32>;
@group(0) @binding(6) var<storage, read_write> atlas: array<AtlasWindow>;

const WIDEST: f32 = 4294967040.0;  // the largest f32 below 2^32: wider windows saturate

// A body's bounds in the pair's frame (measured from the pair's anchor).
struct Bounds {
    centre: vec3f,     // the oriented box's centre
    half: mat3x3f,     // its half axes (columns)
    rows: mat3x3f,     // the body's frame: column j holds axis j (a row of BodyBounds.frames)
    aabb_c: vec3f,     // the world box's centre
    aabb_h: vec3f,     // and half extents
    world_lo: vec3f,   // where both boxes hold, along the world's axes
    world_hi: vec3f,
    own_lo: vec3f,     // and along the body's own axes
    own_hi: vec3f,
};

// An axis-aligned box of a frame: (lo, hi) along its three axes.
struct Box {
    lo: vec3f,
    hi: vec3f,
};

fn xyz(m: array<vec4f, 3>) -> mat3x3f {
    return mat3x3f(m[0].xyz, m[1].xyz, m[2].xyz);
}

// Body b's bounds moved by d (d = 0: the anchor body itself). Intervals along a frame axis r
// move by dot(r, d).
fn bounds_of(b: PlanBody, d: vec3f) -> Bounds {
    let rows = xyz(b.frame);
    let along = d * rows;  // dot(rows[j], d) for each axis j
    return Bounds(b.centre + d, xyz(b.half_axes), rows, b.aabb_centre + d, b.aabb_half,
                  b.world_lo + d, b.world_hi + d, b.own_lo + along, b.own_hi + along);
}

// Along each axis r of a frame (columns of `rows`), sum over the half axes c of |dot(r, c)|:
// the half width of an oriented box.
fn spread(rows: mat3x3f, half: mat3x3f) -> vec3f {
    var out: vec3f;
    for (var j = 0u; j < 3u; j++) {
        let p = abs(rows[j] * half);  // dot(rows[j], half[c]) per half axis c
        out[j] = (p.x + p.y) + p.z;
    }
    return out;
}

// Where all four bounds hold along the axes of a body's frame: that body's own interval, and
// the other body's oriented box and world box projected on its axes.
fn in_frame(me: Bounds, other: Bounds) -> Box {
    let r = me.rows;
    let c1 = other.centre * r;
    let h1 = spread(r, other.half);
    let c2 = other.aabb_c * r;
    let h2 = other.aabb_h * mat3x3f(abs(r[0]), abs(r[1]), abs(r[2]));
    return Box(max(me.own_lo, max(c1 - h1, c2 - h2)), min(me.own_hi, min(c1 + h1, c2 + h2)));
}

// The estimated window area of a box of extents e in its best view (plan_numpy_windows.py's win_x *
// win_y).
fn window_area(e: vec3f, tol: f32) -> f32 {
    let top = max(e.x, e.y);
    let bottom = min(e.x, e.y);
    let long = max(top, e.z);
    let mid = max(bottom, min(top, e.z));
    let thin = min(bottom, e.z);
    let margin = f32(2u * MARGIN_PX + 1u);
    let win_x = (long * SIN_TILT + mid * COS_TILT) / tol + margin;
    let win_y = thin / tol + margin;
    return win_x * win_y;
}

// Pixels across an extent: ceil(x) + 2 MARGIN_PX, saturated at 2^32 - 1 (or NaN).
fn pixels(x: f32) -> u32 {
    let n = ceil(x) + f32(2u * MARGIN_PX);
    if (!(n <= WIDEST)) {
        return 0xFFFFFFFFu;
    }
    return u32(max(n, 0.0));
}

@compute @workgroup_size(WORKGROUP)
fn plan_windows(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let k = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (k >= params.count) {
        return;
    }
    let ab = pairs[k];
    let tol = pair_tolerances[k];
    let pa = bodies[ab.x];
    let pb = bodies[ab.y];
    // The pair's anchor: the body with the smaller world box (ties: a).
    let b_anchors = pb.size < pa.size;
    var out: PlanWindow;
    out.anchor = select(ab.x, ab.y, b_anchors);
    out.pixel = tol;
    var a: Bounds;
    var b: Bounds;
    if (b_anchors) {
        let d = (pa.hi - pb.hi) + (pa.lo - pb.lo);
        a = bounds_of(pa, d);
        b = bounds_of(pb, vec3f(0.0));
    } else {
        let d = (pb.hi - pa.hi) + (pb.lo - pa.lo);
        a = bounds_of(pa, vec3f(0.0));
        b = bounds_of(pb, d);
    }
    // The box where all four bounds hold, in each frame: the world's, body a's, body b's.
    var boxes: array<Box, 3>;
    boxes[0] = Box(max(a.world_lo, b.world_lo), min(a.world_hi, b.world_hi));
    boxes[1] = in_frame(a, b);
    boxes[2] = in_frame(b, a);
    var apart = false;
    for (var f = 0u; f < 3u; f++) {
        apart = apart || any(boxes[f].hi < boxes[f].lo);
    }
    if (apart) {
        out.kept = 0u;
        windows[k] = out;
        atlas[k] = AtlasWindow(0u, 0u, 0u, 0u);
        return;
    }
    // The frame of the smallest window (the first of the smallest).
    let area0 = window_area(boxes[0].hi - boxes[0].lo, tol);
    let area1 = window_area(boxes[1].hi - boxes[1].lo, tol);
    let area2 = window_area(boxes[2].hi - boxes[2].lo, tol);
    var f = select(0u, 1u, area1 < area0);
    if (area2 < min(area0, area1)) {
        f = 2u;
    }
    var frame = mat3x3f(vec3f(1.0, 0.0, 0.0), vec3f(0.0, 1.0, 0.0), vec3f(0.0, 0.0, 1.0));
    if (f == 1u) {
        frame = a.rows;
    } else if (f == 2u) {
        frame = b.rows;
    }
    let box = boxes[f];
    let e = box.hi - box.lo;
    // The frame's axes by extent, long, mid, thin (ties by index): pos_i axes come before i.
    let pos0 = u32(e.y > e.x) + u32(e.z > e.x);
    let pos1 = u32(e.x >= e.y) + u32(e.z > e.y);
    let o0 = select(select(2u, 1u, pos1 == 0u), 0u, pos0 == 0u);
    let o1 = select(select(2u, 1u, pos1 == 1u), 0u, pos0 == 1u);
    let o2 = 3u - o0 - o1;
    let long = frame[o0];
    let mid = frame[o1];
    var x = -SIN_TILT * long + COS_TILT * mid;
    var y = frame[o2];
    let view = COS_TILT * long + SIN_TILT * mid;
    // (x, y, view) is right-handed for a proper frame taken in an even order.
    if ((o1 + 3u - o0) % 3u == 2u) {
        y = -y;
    }
    // The box in view coordinates: rows of (x, y, view) times the frame's axes.
    let centre = 0.5 * (box.lo + box.hi);
    let half = 0.5 * (box.hi - box.lo);
    // m[j][r] = dot(axis r, frame axis j)
    let m = transpose(mat3x3f(x * frame, y * frame, view * frame));
    let vc = m * centre;
    let vh = mat3x3f(abs(m[0]), abs(m[1]), abs(m[2])) * half;
    var vlo = vc - vh;
    var vhi = vc + vh;
    // The window's long side along screen x, as _plan_chunk does (its extent along screen x,
    // sin * long + cos * mid, is never the shorter while the tilt is under 45 degrees).
    if ((vhi.y - vlo.y) > (vhi.x - vlo.x)) {
        let x0 = x;
        x = y;
        y = -x0;
        let lo0 = vlo.x;
        let hi0 = vhi.x;
        vlo.x = vlo.y;
        vhi.x = vhi.y;
        vlo.y = -hi0;
        vhi.y = -lo0;
    }
    out.w = pixels((vhi.x - vlo.x) / tol);
    out.h = pixels((vhi.y - vlo.y) / tol);
    let zmid = 0.5 * (vlo.z + vhi.z);
    let margin = f32(MARGIN_PX) * tol;
    out.origin = (vlo.x - margin) * x + (vlo.y - margin) * y + zmid * view;
    out.slab = vec2f((vlo.z - zmid) / tol, (vhi.z - zmid) / tol);
    out.axes = array<vec4f, 3>(vec4f(x, 0.0), vec4f(y, 0.0), vec4f(view, 0.0));
    // Count towards the side of the slab with less of the pair's depth extent behind it.
    let ca = dot(view, a.centre);
    let ha = dot(abs(view * a.half), vec3f(1.0));
    let cb = dot(view, b.centre);
    let hb = dot(abs(view * b.half), vec3f(1.0));
    let front = vlo.z - min(ca - ha, cb - hb);
    let back = max(ca + ha, cb + hb) - vhi.z;
    out.flags = select(0u, FLAG_COUNT_BACK, back < front) | pa.flags_a | pb.flags_b;
    out.frame = f;
    out.kept = 1u;
    windows[k] = out;
    let dense = faces[ab.x] + faces[ab.y] >= PROBE_FACES;
    atlas[k] = AtlasWindow(1u, out.w, out.h, select(0u, 1u, dense));
}

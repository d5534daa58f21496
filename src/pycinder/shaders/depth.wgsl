// Hard clashes, pass H1 (compute): how far body a must move along each of LINES lines, either
// way, to leave body b behind on every ray parallel to it; reduced to two figures per line and
// candidate pair.
//
// Along a direction n, moving a by s n puts all of a beyond all of b on a ray parallel to n when
// s > (the farthest point of b on the ray) - (the nearest point of a on it), so
//     U(n) = max over rays of (max depth of b - min depth of a)
// is a translation that separates the pair (what pycinder.focused.modes.hardclash takes the least of). A ray's
// extremes lie on the surfaces, so U(n) is the largest of depth_b - depth_a over every face of a
// and face of b, over the region where their projections along n overlap. Both depths are affine
// there, so that largest value is found at the region's corners: a corner of one face inside the
// other's projection, or a crossing of an edge of each. The same corners give the smallest value,
// which is -U(-n), so each line serves both ways.
//
// One workgroup per item: the faces of a pair's two bodies whole (when b has at most WHOLE_FACES),
// or a cluster of each. b's faces are in workgroup memory; the threads share a's faces. An item
// that is its pair's whole work stops at the first line that clears the pair. Depths are computed as convex
// combinations of corner depths (barycentric weights clamped at 0), so a rounding error never
// takes a figure outside the faces' own depth range. Figures are kept as order-preserving bits:
// word 2 i holds max(depth_b - depth_a) along line i, word 2 i + 1 max(depth_a - depth_b); 0
// means no ray met both bodies.
//!include layout
//!include pairwork.wgsl

const NONE: f32 = -3.0e38;  // below every figure: no corner found yet

var<workgroup> tri_b: array<vec3f, 3u * WHOLE_FACES>;    // the corners of b's faces
var<workgroup> views: array<mat3x3f, LINES>;             // rows: screen x, screen y, n
var<workgroup> kept: array<atomic<u32>, 2u * LINES>;      // the workgroup's figures
var<workgroup> cleared: u32;                              // a line cleared the pair
var<workgroup> whole_item: u32;                           // the item is its pair's whole work

// The LINES directions: each body's own three axes (its transform's columns), which follow the
// body when it is turned and most often clear a touching pair at once, then the 13 lines through
// a cube's centre and its faces, edges and corners (every direction is within DIRECTION_COS of
// one of them, either way).
fn line(i: u32, frame: PairFrame) -> vec3f {
    switch i {
        case 0u, 1u, 2u: { return vec3f(frame.m0[0][i], frame.m0[1][i], frame.m0[2][i]); }
        case 3u, 4u, 5u: {
            let j = i - 3u;
            return vec3f(frame.m1[0][j], frame.m1[1][j], frame.m1[2][j]);
        }
        case 6u: { return vec3f(1.0, 0.0, 0.0); }
        case 7u: { return vec3f(0.0, 1.0, 0.0); }
        case 8u: { return vec3f(0.0, 0.0, 1.0); }
        case 9u: { return vec3f(1.0, 1.0, 0.0); }
        case 10u: { return vec3f(1.0, -1.0, 0.0); }
        case 11u: { return vec3f(1.0, 0.0, 1.0); }
        case 12u: { return vec3f(1.0, 0.0, -1.0); }
        case 13u: { return vec3f(0.0, 1.0, 1.0); }
        case 14u: { return vec3f(0.0, 1.0, -1.0); }
        case 15u: { return vec3f(1.0, 1.0, 1.0); }
        case 16u: { return vec3f(1.0, 1.0, -1.0); }
        case 17u: { return vec3f(1.0, -1.0, 1.0); }
        default: { return vec3f(-1.0, 1.0, 1.0); }
    }
}

// Rows: screen x and y, perpendicular to n, and n (unit).
fn view_of(d: vec3f) -> mat3x3f {
    var n = vec3f(0.0, 0.0, 1.0);  // for a degenerate transform's column
    let len = length(d);
    if (len > 0.0) {
        n = d / len;
    }
    var helper = vec3f(1.0, 0.0, 0.0);
    if (abs(n.x) > 0.75) {
        helper = vec3f(0.0, 1.0, 0.0);
    }
    let x = normalize(cross(helper, n));
    return mat3x3f(x, cross(n, x), n);
}

// (x, y) on screen and depth along n.
fn project(v: mat3x3f, p: vec3f) -> vec3f {
    return vec3f(dot(v[0], p), dot(v[1], p), dot(v[2], p));
}

fn orient(a: vec2f, b: vec2f, c: vec2f) -> f32 {
    let ab = b - a;
    let ac = c - a;
    return ab.x * ac.y - ab.y * ac.x;
}

fn length2(a: vec2f) -> f32 {
    return dot(a, a);
}

// The depth of face t0 t1 t2 (projected) on the ray through p: x = 1 where p is inside the face's
// projection (edges included, within rounding), y = the depth. A face seen edge-on covers no
// area; its depths are reached through its edges. The weights are clamped at 0, so a point just
// outside by rounding takes the depth of the nearest point of the face; a point the clamped
// weights place farther than the rounding allows (beyond the sharp corner of a sliver face, along
// an edge's line) is outside.
fn depth_in(t0: vec3f, t1: vec3f, t2: vec3f, p: vec2f) -> vec2f {
    var o = vec3f(orient(t1.xy, t2.xy, p), orient(t2.xy, t0.xy, p), orient(t0.xy, t1.xy, p));
    let area = o.x + o.y + o.z;
    let size2 = length2(t1.xy - t0.xy) + length2(t2.xy - t1.xy) + length2(t0.xy - t2.xy);
    let slack = SLACK * size2;
    if (abs(area) <= slack) {
        return vec2f(0.0, 0.0);
    }
    if (area < 0.0) {
        o = -o;
    }
    if (min(o.x, min(o.y, o.z)) < -slack) {
        return vec2f(0.0, 0.0);
    }
    let w = max(o, vec3f(0.0)) / (max(o.x, 0.0) + max(o.y, 0.0) + max(o.z, 0.0));
    let q = w.x * t0.xy + w.y * t1.xy + w.z * t2.xy;
    if (length2(q - p) > SLACK * SLACK * size2) {
        return vec2f(0.0, 0.0);
    }
    return vec2f(1.0, dot(w, vec3f(t0.z, t1.z, t2.z)));
}

// depth_b - depth_a where edge p0 p1 of a crosses edge q0 q1 of b on screen; x = 1 where they do.
// Both depths are taken at one screen point: the crossing found on edge a, and the point of edge
// b nearest it (when it lies within rounding of edge b), so that edges crossing at a shallow angle,
// whose crossing is ill-conditioned along them, still give the depths of one ray.
fn crossing(p0: vec3f, p1: vec3f, q0: vec3f, q1: vec3f) -> vec2f {
    let r = p1.xy - p0.xy;
    let s = q1.xy - q0.xy;
    let den = r.x * s.y - r.y * s.x;
    let rr = length2(r);
    let ss = length2(s);
    if (abs(den) <= SLACK * sqrt(rr * ss)) {
        return vec2f(0.0, 0.0);  // parallel: where they overlap, corners lie on the other edge
    }
    let w = q0.xy - p0.xy;
    let ta = (w.x * s.y - w.y * s.x) / den;
    if (ta < -SLACK || ta > 1.0 + SLACK) {
        return vec2f(0.0, 0.0);
    }
    let t = clamp(ta, 0.0, 1.0);
    let x = p0.xy + t * r;
    let tb = clamp(dot(x - q0.xy, s) / ss, 0.0, 1.0);
    if (length2(q0.xy + tb * s - x) > SLACK * SLACK * (rr + ss)) {
        return vec2f(0.0, 0.0);
    }
    return vec2f(1.0, mix(q0.z, q1.z, tb) - mix(p0.z, p1.z, t));
}

// Order-preserving bits of a float: larger floats give larger words.
fn key(f: f32) -> u32 {
    let b = bitcast<u32>(f);
    if ((b & 0x80000000u) != 0u) {
        return ~b;
    }
    return b | 0x80000000u;
}

// Whether the figures kept so far for line i say it clears the pair: no ray meets both bodies,
// or one way along it leaves them apart already.
fn clears(i: u32) -> bool {
    let ahead = atomicLoad(&kept[2u * i]);
    let behind = atomicLoad(&kept[2u * i + 1u]);
    return ahead == 0u || ahead <= key(0.0) || behind <= key(0.0);
}

@compute @workgroup_size(WORKGROUP)
fn depth(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let k = wg.y * ROW + wg.x;
    if (k >= params.items) {
        return;  // uniform across the workgroup
    }
    let item = items[k];
    let frame = frames[item.pair];
    // A whole item keeps the body with fewer faces in workgroup memory: flipped, that is body a,
    // and the figures of each line swap ways.
    let flipped = (item.whole & ITEM_FLIPPED) != 0u;
    var ma = frame.m0;
    var mb = frame.m1;
    if (flipped) {
        ma = frame.m1;
        mb = frame.m0;
    }
    for (var t = lid; t < item.b_count; t += WORKGROUP) {
        let f = item.b_start + t;
        for (var j = 0u; j < 3u; j++) {
            tri_b[3u * t + j] = to_pair(mb, vertex(faces[3u * f + j]));
        }
    }
    if (lid < LINES) {
        views[lid] = view_of(line(lid, frame));
    }
    if (lid < 2u * LINES) {
        atomicStore(&kept[lid], 0u);
    }
    if (lid == 0u) {
        whole_item = item.whole & ITEM_WHOLE;
    }
    let whole = workgroupUniformLoad(&whole_item);  // a barrier, and uniform
    for (var i = 0u; i < LINES; i++) {
        let v = views[i];
        var most = NONE;   // max(depth_b - depth_a)
        var least = NONE;  // max(depth_a - depth_b)
        // Each thread takes every WORKGROUP-th face of a.
        for (var fa = lid; fa < item.a_count; fa += WORKGROUP) {
            let f = item.a_start + fa;
            let pa = array<vec3f, 3>(project(v, to_pair(ma, vertex(faces[3u * f]))),
                                     project(v, to_pair(ma, vertex(faces[3u * f + 1u]))),
                                     project(v, to_pair(ma, vertex(faces[3u * f + 2u]))));
            let a_lo = min(pa[0].xy, min(pa[1].xy, pa[2].xy));
            let a_hi = max(pa[0].xy, max(pa[1].xy, pa[2].xy));
            for (var t = 0u; t < item.b_count; t++) {
                let pb = array<vec3f, 3>(project(v, tri_b[3u * t]), project(v, tri_b[3u * t + 1u]),
                                         project(v, tri_b[3u * t + 2u]));
                let b_lo = min(pb[0].xy, min(pb[1].xy, pb[2].xy));
                let b_hi = max(pb[0].xy, max(pb[1].xy, pb[2].xy));
                let gap = max(a_lo - b_hi, b_lo - a_hi);
                let size = max(max(a_hi.x - a_lo.x, a_hi.y - a_lo.y),
                               max(b_hi.x - b_lo.x, b_hi.y - b_lo.y));
                if (max(gap.x, gap.y) > SLACK * size) {
                    continue;  // their projections are apart
                }
                for (var c = 0u; c < 3u; c++) {
                    let in_b = depth_in(pb[0], pb[1], pb[2], pa[c].xy);
                    if (in_b.x > 0.0) {
                        most = max(most, in_b.y - pa[c].z);
                        least = max(least, pa[c].z - in_b.y);
                    }
                    let in_a = depth_in(pa[0], pa[1], pa[2], pb[c].xy);
                    if (in_a.x > 0.0) {
                        most = max(most, pb[c].z - in_a.y);
                        least = max(least, in_a.y - pb[c].z);
                    }
                    for (var e = 0u; e < 3u; e++) {
                        let x = crossing(pa[c], pa[(c + 1u) % 3u], pb[e], pb[(e + 1u) % 3u]);
                        if (x.x > 0.0) {
                            most = max(most, x.y);
                            least = max(least, -x.y);
                        }
                    }
                }
            }
        }
        if (most > NONE) {
            atomicMax(&kept[2u * i], key(most));
            atomicMax(&kept[2u * i + 1u], key(least));
        }
        // An item that is its pair's whole work stops at the first line that clears the pair
        // (its depth is then 0 whatever the other lines say).
        if (whole != 0u) {
            workgroupBarrier();
            if (lid == 0u) {
                cleared = u32(clears(i));
            }
            if (workgroupUniformLoad(&cleared) != 0u) {
                break;
            }
        }
    }
    workgroupBarrier();
    if (lid < 2u * LINES) {
        let word = atomicLoad(&kept[lid]);
        if (word != 0u) {
            atomicMax(&best[item.pair * 2u * LINES + (lid ^ u32(flipped))], word);
        }
    }
}

// Clearance, pass C1 (compute): the distance between two bodies' surfaces, cluster pair by
// cluster pair, reduced to one figure per candidate pair.
//
// One workgroup per item (a cluster of body a and a cluster of body b whose boxes are within the
// clearance): the b cluster's faces are loaded into workgroup memory, and each thread takes one
// face of the a cluster and measures its distance to every one of them, exactly (in the pair's
// own frame, in single precision). Two triangles that do not intersect are closest at a pair of
// features: an edge and an edge, or a vertex and a face; when an edge of one passes through the
// other, their distance is 0. The smallest distance of each pair is kept with atomicMin on its
// bits (non-negative floats order as their bits do). A face of b whose box lies farther from
// the thread's face's box than the least distance found so far (by a margin of 2^-10 over the
// rounding of both figures) cannot be nearer, and is skipped: the figure is the same, and the
// exact test runs only for the faces near the thread's face.
//!include layout
//!include measure_pair_work.wgsl

var<workgroup> tri_b: array<vec3f, 3u * CLUSTER_FACES>;  // the corners of a cluster's faces
var<workgroup> lo_b: array<vec3f, CLUSTER_FACES>;        // and their boxes
var<workgroup> hi_b: array<vec3f, CLUSTER_FACES>;

const SKIP_MARGIN: f32 = 1.0009765625;  // 1 + 2^-10: a box gap this far over the least skips

// The squared gap between boxes lo_a-hi_a and lo_b-hi_b (0 where they meet).
fn box_gap2(lo_a: vec3f, hi_a: vec3f, lo_b: vec3f, hi_b: vec3f) -> f32 {
    let gap = max(max(lo_b - hi_a, lo_a - hi_b), vec3f(0.0));
    return dot(gap, gap);
}

// Squared distance between segments p1-q1 and p2-q2 (Ericson, Real-Time Collision Detection 5.1.9).
fn segment_segment(p1: vec3f, q1: vec3f, p2: vec3f, q2: vec3f) -> f32 {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = dot(d1, d1);
    let e = dot(d2, d2);
    let f = dot(d2, r);
    var s = 0.0;
    var t = 0.0;
    if (a <= 1e-30 && e <= 1e-30) {
        return dot(r, r);
    }
    if (a <= 1e-30) {
        t = clamp(f / e, 0.0, 1.0);
    } else {
        let c = dot(d1, r);
        if (e <= 1e-30) {
            s = clamp(-c / a, 0.0, 1.0);
        } else {
            let b = dot(d1, d2);
            let denom = a * e - b * b;
            if (denom > 0.0) {
                s = clamp((b * f - c * e) / denom, 0.0, 1.0);
            }
            t = (b * s + f) / e;
            if (t < 0.0) {
                t = 0.0;
                s = clamp(-c / a, 0.0, 1.0);
            } else if (t > 1.0) {
                t = 1.0;
                s = clamp((b - c) / a, 0.0, 1.0);
            }
        }
    }
    let d = (p1 + d1 * s) - (p2 + d2 * t);
    return dot(d, d);
}

// Squared distance from p to triangle abc (Ericson 5.1.5, by Voronoi regions).
fn point_triangle(p: vec3f, a: vec3f, b: vec3f, c: vec3f) -> f32 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) {
        return dot(ap, ap);
    }
    let bp = p - b;
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
        return dot(bp, bp);
    }
    let vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        let x = ap - ab * (d1 / (d1 - d3));
        return dot(x, x);
    }
    let cp = p - c;
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
        return dot(cp, cp);
    }
    let vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        let x = ap - ac * (d2 / (d2 - d6));
        return dot(x, x);
    }
    let va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        let x = bp - (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
        return dot(x, x);
    }
    let denom = va + vb + vc;
    if (abs(denom) <= 1e-30) {
        // A degenerate (needle) triangle: the distance to its edges.
        return min(min(segment_segment(p, p, a, b), segment_segment(p, p, b, c)),
                   segment_segment(p, p, c, a));
    }
    let v = vb / denom;
    let w = vc / denom;
    let x = ap - ab * v - ac * w;
    return dot(x, x);
}

// Whether segment p-q passes through triangle abc: its ends strictly on either side of the
// triangle's plane, and the point where it crosses the plane inside the triangle (edges count).
// An end lying on the plane is left to the vertex-face distance, which is then 0 or tiny: a test
// of the line alone is ill-conditioned when the segment is nearly parallel to the plane.
fn segment_crosses(p: vec3f, q: vec3f, a: vec3f, b: vec3f, c: vec3f) -> bool {
    let n = cross(b - a, c - a);
    let sp = dot(n, p - a);
    let sq = dot(n, q - a);
    if (!((sp > 0.0 && sq < 0.0) || (sp < 0.0 && sq > 0.0))) {
        return false;
    }
    let x = p + (q - p) * (sp / (sp - sq));
    return dot(cross(b - a, x - a), n) >= 0.0 && dot(cross(c - b, x - b), n) >= 0.0
        && dot(cross(a - c, x - c), n) >= 0.0;
}

fn triangle_distance2(a0: vec3f, a1: vec3f, a2: vec3f, b0: vec3f, b1: vec3f, b2: vec3f) -> f32 {
    if (segment_crosses(a0, a1, b0, b1, b2) || segment_crosses(a1, a2, b0, b1, b2)
            || segment_crosses(a2, a0, b0, b1, b2) || segment_crosses(b0, b1, a0, a1, a2)
            || segment_crosses(b1, b2, a0, a1, a2) || segment_crosses(b2, b0, a0, a1, a2)) {
        return 0.0;
    }
    var d = point_triangle(a0, b0, b1, b2);
    d = min(d, point_triangle(a1, b0, b1, b2));
    d = min(d, point_triangle(a2, b0, b1, b2));
    d = min(d, point_triangle(b0, a0, a1, a2));
    d = min(d, point_triangle(b1, a0, a1, a2));
    d = min(d, point_triangle(b2, a0, a1, a2));
    let ea = array<vec3f, 4>(a0, a1, a2, a0);
    let eb = array<vec3f, 4>(b0, b1, b2, b0);
    for (var i = 0u; i < 3u; i++) {
        for (var j = 0u; j < 3u; j++) {
            d = min(d, segment_segment(ea[i], ea[i + 1u], eb[j], eb[j + 1u]));
        }
    }
    return d;
}

@compute @workgroup_size(WORKGROUP)
fn distance(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let k = wg.y * ROW + wg.x;
    if (k >= params.items) {
        return;  // uniform across the workgroup
    }
    let item = items[k];
    let frame = frames[item.pair];
    if (lid < item.b_count) {
        let f = item.b_start + lid;
        for (var j = 0u; j < 3u; j++) {
            tri_b[3u * lid + j] = to_pair(frame.m1, vertex(faces[3u * f + j]));
        }
        let b0 = tri_b[3u * lid];
        let b1 = tri_b[3u * lid + 1u];
        let b2 = tri_b[3u * lid + 2u];
        lo_b[lid] = min(min(b0, b1), b2);
        hi_b[lid] = max(max(b0, b1), b2);
    }
    workgroupBarrier();
    if (lid >= item.a_count) {
        return;
    }
    let f = item.a_start + lid;
    let a0 = to_pair(frame.m0, vertex(faces[3u * f]));
    let a1 = to_pair(frame.m0, vertex(faces[3u * f + 1u]));
    let a2 = to_pair(frame.m0, vertex(faces[3u * f + 2u]));
    let lo_a = min(min(a0, a1), a2);
    let hi_a = max(max(a0, a1), a2);
    var d = 3.4e38;
    for (var i = 0u; i < item.b_count; i++) {
        if (box_gap2(lo_a, hi_a, lo_b[i], hi_b[i]) <= d * SKIP_MARGIN) {
            d = min(d, triangle_distance2(a0, a1, a2, tri_b[3u * i], tri_b[3u * i + 1u],
                                          tri_b[3u * i + 2u]));
            if (d == 0.0) {
                break;
            }
        }
    }
    atomicMin(&best[item.pair], bitcast<u32>(sqrt(d)));
}

// Hard clashes, pass H1 (compute): how far body a must move along each of LINES lines, either
// way, to leave body b behind on every ray parallel to it; reduced to two figures per line and
// candidate pair.
//
// Along a direction n, moving a by s n puts all of a beyond all of b on a ray parallel to n when
// s > (the farthest point of b on the ray) - (the nearest point of a on it), so
//     U(n) = max over rays of (max depth of b - min depth of a)
// is a translation that separates the pair (what pycinder.focused.modes.hardclash takes the least
// of). A ray's extremes lie on the surfaces, so U(n) is the largest of depth_b - depth_a over
// every face of a and face of b, over the region where their projections along n overlap. Both
// depths are affine there, so that largest value is found at the region's corners: a corner of
// one face inside the other's projection, or a crossing of an edge of each. The same corners give
// the smallest value, which is -U(-n), so each line serves both ways.
//
// One workgroup per item: the faces of a pair's two bodies whole (when b has at most WHOLE_FACES:
// entry point depth, in rounds of WORKGROUP faces of a against blocks of WORKGROUP faces of b),
// or a cluster of each (depth_clusters). For each line, each thread projects a face of each
// body, and face_pairs finds the face pairs whose screen boxes meet, first dropping the faces of
// each side that are apart from the box of the other side's faces (a gap to that box is never
// more than the gap to any face in it, rounding included, so no face pair the per-face test would
// keep is left out), then shares them among the threads, so that the exact test of the corners
// (face_pair, the costly part) runs once per face pair that can add to the figures, with every
// thread busy. An item skips the lines its skip bits name (the host found its faces'
// projections apart along them: they would add nothing) and a line whose view equals an earlier
// one's (it takes that line's figures). An item that is its pair's whole work stops at the first
// line that clears the pair. A pair whose frame has a cap (one whose figure matters only up to
// the cap: above it, the pair is measured again, locally; or, for the greatest float, any
// pair whose figure is only its least line's) stops measuring a line once both its figures
// reach the cap: a whole item after any block of face pairs, a cap lowered to the least figure
// of the lines it has measured whole, a cluster item before a line its pair's figures already
// hold at the cap. A line's figures only grow as face pairs add to them, so a line stopped
// holds figures at least the cap, and the pair's least figure is exact where it is below the
// cap and at least the cap otherwise. Depths are computed as convex combinations of corner
// depths (barycentric weights clamped at 0), so a rounding error never takes a figure outside
// the faces' own depth range. Figures are kept as order-preserving bits: of a pair's WORDS
// words, word 2 i holds max(depth_b - depth_a) along line i, word 2 i + 1 max(depth_a -
// depth_b) (0: no ray met both bodies), and word DONE counts the threads that finished its
// items.
//
// Touching adds nothing between solids. For a pair of solids (a frame whose touch width is not
// 0) the figures are the largest over the rays that meet both bodies in an area, not along a
// line or at a point: a face pair adds to them only where its projections overlap over more than
// a strip of the touch width (what rounding can make of faces that share an edge or meet face
// on face), and a face seen edge-on adds nothing. Otherwise a ray grazing a door along its
// opening's reveal, where the wall's face and the door's meet, would count the wall's far side
// behind the door, and a door merely standing in its opening would be as deep as its leaf is
// thick. Such a ray is a line where the solids only touch: moving one by the figures of the other
// rays leaves no volume in common. A pair with an open body (touch width 0) keeps every ray: a
// surface has no volume, and a ray along it is where it is met.
//!include layout
//!include measure_pair_work.wgsl

const NONE: f32 = -3.0e38;  // below every figure: no corner found yet
const NO_BOX = vec4f(3.0e38, 3.0e38, -3.0e38, -3.0e38);  // the box of no face

var<workgroup> flat_a: array<vec2f, 3u * WORKGROUP>;  // the kept faces of a: corners on screen
var<workgroup> deep_a: array<f32, 3u * WORKGROUP>;    // and their depths
var<workgroup> box_a: array<vec4f, WORKGROUP>;        // and screen boxes: lo, hi
var<workgroup> flat_b: array<vec2f, 3u * WORKGROUP>;  // the same of the kept faces of b
var<workgroup> deep_b: array<f32, 3u * WORKGROUP>;
var<workgroup> box_b: array<vec4f, WORKGROUP>;
// The boxes of a face_pairs call's faces of a and of b, and their largest faces, reduced: keys of
// -lo.x, -lo.y, hi.x, hi.y and size for a (0 to 4), then for b (5 to 9); 0 where none.
var<workgroup> reduced: array<atomic<u32>, 10>;
var<workgroup> kept_a: atomic<u32>;                   // faces of a and of b kept
var<workgroup> kept_b: atomic<u32>;
var<workgroup> hits: array<vec2u, WORKGROUP>;         // per face of a: bits of the b faces it meets
var<workgroup> first_hit: array<u32, WORKGROUP>;      // where each face's face pairs start
var<workgroup> hit_count: u32;                        // face pairs found
var<workgroup> views: array<mat3x3f, LINES>;          // rows: screen x, screen y, n
var<workgroup> source: array<u32, LINES>;             // the line whose figures a line takes
var<workgroup> kept: array<atomic<u32>, 2u * LINES>;  // the workgroup's figures
var<workgroup> cleared: u32;                          // a line cleared the pair
var<workgroup> todo_lines: u32;                       // bits: the lines measured
var<workgroup> item_shape: vec3u;                     // rounds of a, blocks of b, whole item
var<workgroup> item_cap: u32;                         // key of the frame's cap; 0: none
var<workgroup> capped: u32;                           // a line reached the cap; its figure

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

// The float of a key (0, no key, gives -inf).
fn unkey(k: u32) -> f32 {
    if (k == 0u) {
        return NONE;
    }
    if ((k & 0x80000000u) != 0u) {
        return bitcast<f32>(k & 0x7fffffffu);
    }
    return bitcast<f32>(~k);
}

// Adds a face's screen box and size to the reduced box at word o.
fn reduce_box(o: u32, lo: vec2f, hi: vec2f, size: f32) {
    atomicMax(&reduced[o], key(-lo.x));
    atomicMax(&reduced[o + 1u], key(-lo.y));
    atomicMax(&reduced[o + 2u], key(hi.x));
    atomicMax(&reduced[o + 3u], key(hi.y));
    atomicMax(&reduced[o + 4u], key(size));
}

// The reduced box at word o (NO_BOX where no face added to it).
fn reduced_box(o: u32) -> vec4f {
    if (atomicLoad(&reduced[o + 2u]) == 0u) {
        return NO_BOX;
    }
    return vec4f(-unkey(atomicLoad(&reduced[o])), -unkey(atomicLoad(&reduced[o + 1u])),
                 unkey(atomicLoad(&reduced[o + 2u])), unkey(atomicLoad(&reduced[o + 3u])));
}

fn clear_reduced() {
    for (var i = 0u; i < 10u; i++) {
        atomicStore(&reduced[i], 0u);
    }
}

fn same_view(a: mat3x3f, b: mat3x3f) -> bool {
    return all(a[0] == b[0]) && all(a[1] == b[1]) && all(a[2] == b[2]);
}

// The k-th (from 0) set bit of the 64 bits lo | hi << 32.
fn nth_bit(bits: vec2u, k: u32) -> u32 {
    let low = countOneBits(bits.x);
    let in_hi = k >= low;
    var w = select(bits.x, bits.y, in_hi);
    var rest = select(k, k - low, in_hi);
    var at = select(0u, 32u, in_hi);
    for (var step = 16u; step > 0u; step >>= 1u) {
        let below = countOneBits(w & ((1u << step) - 1u));
        let up = rest >= below;
        rest = select(rest, rest - below, up);
        at += select(0u, step, up);
        w = select(w, w >> step, up);
    }
    return at;
}

// Whether the figures kept so far for line i say it clears the pair: no ray meets both bodies,
// or one way along it leaves them apart already.
fn clears(i: u32) -> bool {
    let ahead = atomicLoad(&kept[2u * i]);
    let behind = atomicLoad(&kept[2u * i + 1u]);
    return ahead == 0u || ahead <= key(0.0) || behind <= key(0.0);
}

// Whether both figures of line i, in words ahead and behind, reach the cap (key) cap.
fn at_cap(ahead: u32, behind: u32, cap: u32) -> bool {
    return cap != 0u && ahead >= cap && behind >= cap;
}

// Corners of kept face j of a and of kept face u of b.
fn corners_a(j: u32) -> array<vec3f, 3> {
    return array<vec3f, 3>(vec3f(flat_a[3u * j], deep_a[3u * j]),
                           vec3f(flat_a[3u * j + 1u], deep_a[3u * j + 1u]),
                           vec3f(flat_a[3u * j + 2u], deep_a[3u * j + 2u]));
}

fn corners_b(u: u32) -> array<vec3f, 3> {
    return array<vec3f, 3>(vec3f(flat_b[3u * u], deep_b[3u * u]),
                           vec3f(flat_b[3u * u + 1u], deep_b[3u * u + 1u]),
                           vec3f(flat_b[3u * u + 2u], deep_b[3u * u + 2u]));
}

// The inward unit normal of edge p q of a face turning the way of s (the sign of its orient);
// zero for an edge of no length.
fn inward(p: vec2f, q: vec2f, s: f32) -> vec2f {
    let e = q - p;
    let len = length(e);
    if (len == 0.0) {
        return vec2f(0.0);
    }
    return (s / len) * vec2f(-e.y, e.x);
}

// How far a corner moves when the edges beside it, of inward normals a and b, move inward by
// w: along their bisector, by 2 w (a + b) / |a + b|^2 (|a + b|^2 = 2 + 2 a.b, taken from the sum
// itself, so that a sharp corner does not cancel it away).
fn corner_shift(a: vec2f, b: vec2f, w: f32) -> vec2f {
    let bisector = a + b;
    return (2.0 * w / max(dot(bisector, bisector), 1e-30)) * bisector;
}

// A face's projection moved inward by w on every side: its corners ([0] to [2]) and, in [3].x,
// 1 where it has such an inset (w under its inradius, the face not seen edge-on), else 0.
fn inset(t: array<vec3f, 3>, w: f32) -> array<vec2f, 4> {
    let a = t[0].xy;
    let b = t[1].xy;
    let c = t[2].xy;
    let turn = orient(a, b, c);
    let s = sign(turn);
    let n0 = inward(a, b, s);
    let n1 = inward(b, c, s);
    let n2 = inward(c, a, s);
    let ia = a + corner_shift(n2, n0, w);
    let ib = b + corner_shift(n0, n1, w);
    let ic = c + corner_shift(n1, n2, w);
    let kept = turn != 0.0 && dot(n0, n0) > 0.0 && dot(n1, n1) > 0.0 && dot(n2, n2) > 0.0
        && orient(ia, ib, ic) * turn > 0.0;
    return array<vec2f, 4>(ia, ib, ic, vec2f(select(0.0, 1.0, kept), 0.0));
}

// Whether edge p q of a convex polygon turning the way of s has every one of o0, o1, o2 outside
// it (a separating axis).
fn separates(p: vec2f, q: vec2f, s: f32, o0: vec2f, o1: vec2f, o2: vec2f) -> bool {
    let e = q - p;
    let n = s * vec2f(-e.y, e.x);
    return max(dot(n, o0 - p), max(dot(n, o1 - p), dot(n, o2 - p))) < 0.0;
}

// Whether the projections of faces pa and pb overlap over more than a strip w wide: their insets
// by w meet (two convex polygons meet unless an edge of one separates them).
fn overlap_area(pa: array<vec3f, 3>, pb: array<vec3f, 3>, w: f32) -> bool {
    let ia = inset(pa, w);
    let ib = inset(pb, w);
    if (ia[3].x == 0.0 || ib[3].x == 0.0) {
        return false;
    }
    let sa = sign(orient(ia[0], ia[1], ia[2]));
    let sb = sign(orient(ib[0], ib[1], ib[2]));
    return !(separates(ia[0], ia[1], sa, ib[0], ib[1], ib[2])
             || separates(ia[1], ia[2], sa, ib[0], ib[1], ib[2])
             || separates(ia[2], ia[0], sa, ib[0], ib[1], ib[2])
             || separates(ib[0], ib[1], sb, ia[0], ia[1], ia[2])
             || separates(ib[1], ib[2], sb, ia[0], ia[1], ia[2])
             || separates(ib[2], ib[0], sb, ia[0], ia[1], ia[2]));
}

// The largest depth_b - depth_a (x) and depth_a - depth_b (y) over the rays through faces pa of
// a and pb of b (NONE where none meets both, or where they only touch: overlap_area): at a
// corner of one inside the other, or where their edges cross.
fn face_pair(pa: array<vec3f, 3>, pb: array<vec3f, 3>, touch: f32) -> vec2f {
    var most = NONE;
    var least = NONE;
    if (touch > 0.0 && !overlap_area(pa, pb, touch)) {
        return vec2f(most, least);
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
    return vec2f(most, least);
}

// Whether a face's screen box (lo, hi, its size) is apart from a box of faces (span, their
// largest size): then it is apart from each of them by the per-face test in face_pairs (a gap to
// the box is never more than the gap to any face in it, rounding included).
fn apart(lo: vec2f, hi: vec2f, size: f32, span: vec4f, span_size: f32) -> bool {
    let gap = max(lo - span.zw, span.xy - hi);
    return max(gap.x, gap.y) > SLACK * max(size, span_size);
}

fn project_face(v: mat3x3f, t: array<vec3f, 3>) -> array<vec3f, 3> {
    return array<vec3f, 3>(project(v, t[0]), project(v, t[1]), project(v, t[2]));
}

// Face f of a body in the pair's frame (m: pair-from-body rows).
fn face_in_pair(m: array<vec4f, 3>, f: u32) -> array<vec3f, 3> {
    return array<vec3f, 3>(to_pair(m, vertex(faces[3u * f])),
                           to_pair(m, vertex(faces[3u * f + 1u])),
                           to_pair(m, vertex(faces[3u * f + 2u])));
}

// The loops below test their exit at their end: a CPU adapter runs a loop's body once more, with
// every lane masked off, when the test comes first (and runs both ways of every branch).
//
// Over the workgroup's faces of a and of b on one line's screen (each thread's own: pa where
// has_a, pb where has_b), max(depth_b - depth_a) (x) and max(depth_a - depth_b) (y) of the face
// pairs this thread is given (NONE where none). Every thread calls it (it holds barriers). The
// boxes of each side's faces are reduced over the threads; the faces of each side whose boxes
// are apart from the other side's box are dropped (the per-face test would skip them with every
// face of the other side); each thread then tests a kept face of a against every kept face of b
// by their screen boxes, and the face pairs found are shared among the threads for the exact
// test.
fn face_pairs(pa: array<vec3f, 3>, has_a: bool, pb: array<vec3f, 3>, has_b: bool, touch: f32,
              lid: u32) -> vec2f {
    let a_lo = min(pa[0].xy, min(pa[1].xy, pa[2].xy));
    let a_hi = max(pa[0].xy, max(pa[1].xy, pa[2].xy));
    let a_size = max(a_hi.x - a_lo.x, a_hi.y - a_lo.y);
    let b_lo = min(pb[0].xy, min(pb[1].xy, pb[2].xy));
    let b_hi = max(pb[0].xy, max(pb[1].xy, pb[2].xy));
    let b_size = max(b_hi.x - b_lo.x, b_hi.y - b_lo.y);
    // One barrier, not one per halving: a CPU adapter pays for every barrier in every thread.
    if (has_a) {
        reduce_box(0u, a_lo, a_hi, a_size);
    }
    if (has_b) {
        reduce_box(5u, b_lo, b_hi, b_size);
    }
    workgroupBarrier();
    // The kept faces go to the front of the arrays, in any order (the figures are maxima).
    let all_a = reduced_box(0u);
    let all_b = reduced_box(5u);
    let all_size = vec2f(max(unkey(atomicLoad(&reduced[4u])), 0.0),
                         max(unkey(atomicLoad(&reduced[9u])), 0.0));
    if (has_a && !apart(a_lo, a_hi, a_size, all_b, all_size.y)) {
        let slot = atomicAdd(&kept_a, 1u);
        for (var c = 0u; c < 3u; c++) {
            flat_a[3u * slot + c] = pa[c].xy;
            deep_a[3u * slot + c] = pa[c].z;
        }
        box_a[slot] = vec4f(a_lo, a_hi);
    }
    if (has_b && !apart(b_lo, b_hi, b_size, all_a, all_size.x)) {
        let slot = atomicAdd(&kept_b, 1u);
        for (var c = 0u; c < 3u; c++) {
            flat_b[3u * slot + c] = pb[c].xy;
            deep_b[3u * slot + c] = pb[c].z;
        }
        box_b[slot] = vec4f(b_lo, b_hi);
    }
    workgroupBarrier();
    // Thread j: kept face j of a against every kept face of b, by their screen boxes (the face
    // pairs more than SLACK times their size apart add nothing).
    let n_a = atomicLoad(&kept_a);
    let n = select(0u, atomicLoad(&kept_b), lid < n_a);
    let mine = box_a[lid];
    let size_a = max(mine.z - mine.x, mine.w - mine.y);
    var hit = vec2u(0u);
    var u = 0u;
    loop {
        let box = box_b[u];
        let gap = max(mine.xy - box.zw, box.xy - mine.zw);
        let size = max(size_a, max(box.z - box.x, box.w - box.y));
        if (u < n && !(max(gap.x, gap.y) > SLACK * size)) {
            if (u < 32u) {
                hit.x |= 1u << u;
            } else {
                hit.y |= 1u << (u - 32u);
            }
        }
        u++;
        if (u >= n) {
            break;
        }
    }
    hits[lid] = hit;
    first_hit[lid] = countOneBits(hit.x) + countOneBits(hit.y);
    workgroupBarrier();
    if (lid == 0u) {
        var sum = 0u;
        for (var j = 0u; j < WORKGROUP; j++) {
            let count = first_hit[j];
            first_hit[j] = sum;
            sum += count;
        }
        hit_count = sum;
        atomicStore(&kept_a, 0u);
        atomicStore(&kept_b, 0u);
        clear_reduced();  // every thread read them before the last barrier
    }
    workgroupBarrier();
    let total = hit_count;  // the loop below holds no barrier: it need not be uniform
    // The face pairs found, shared among the threads: entry e is bit e - first_hit[j] of face
    // j's hits.
    var most = NONE;
    var least = NONE;
    var e = lid;
    loop {
        if (e < total) {
            var j = 0u;
            for (var step = WORKGROUP / 2u; step > 0u; step >>= 1u) {
                j = select(j, j + step, first_hit[j + step] <= e);
            }
            let figure = face_pair(corners_a(j), corners_b(nth_bit(hits[j], e - first_hit[j])),
                                   touch);
            most = max(most, figure.x);
            least = max(least, figure.y);
        }
        e += WORKGROUP;
        if (e >= total) {
            break;
        }
    }
    // No barrier here: the next call writes these faces only after its first barrier, which
    // every thread reaches once done with them.
    return vec2f(most, least);
}

// The views of the LINES lines (all threads), and the lines an item measures (thread 0): those
// its skip bits leave whose view no earlier such line has; the others take that line's figures.
fn start_item(frame: PairFrame, skip: u32, lid: u32) {
    if (lid < LINES) {
        views[lid] = view_of(line(lid, frame));
    }
    if (lid < 2u * LINES) {
        atomicStore(&kept[lid], 0u);
    }
    if (lid == 0u) {
        atomicStore(&kept_a, 0u);
        atomicStore(&kept_b, 0u);
        clear_reduced();
        item_cap = select(0u, key(frame.cap), frame.cap > 0.0);
    }
    workgroupBarrier();
    if (lid < LINES) {
        var earlier = lid;
        if (((skip >> lid) & 1u) == 0u) {
            var j = 0u;
            loop {
                if (j < lid && ((skip >> j) & 1u) == 0u && earlier == lid
                        && same_view(views[j], views[lid])) {
                    earlier = j;
                }
                j++;
                if (j >= lid) {
                    break;
                }
            }
        }
        source[lid] = earlier;
    }
    workgroupBarrier();
    if (lid == 0u) {
        var todo = 0u;
        for (var i = 0u; i < LINES; i++) {
            if (((skip >> i) & 1u) == 0u && source[i] == i) {
                todo |= 1u << i;
            }
        }
        todo_lines = todo;
    }
}

// The item's figures (lines up to last, those not skipped), added to its pair's; then every
// thread counts itself in the pair's word DONE, so that the host knows every thread of the
// item got here (a CPU adapter has been seen to end a workgroup of many rounds before its
// later threads did).
fn end_item(pair: u32, skip: u32, last: u32, flipped: bool, lid: u32) {
    workgroupBarrier();
    if (lid < 2u * LINES) {
        let i = lid >> 1u;
        if (i <= last && ((skip >> i) & 1u) == 0u) {
            let word = atomicLoad(&kept[2u * source[i] + (lid & 1u)]);
            if (word != 0u) {
                atomicMax(&best[pair * WORDS + (lid ^ u32(flipped))], word);
            }
        }
    }
    atomicAdd(&best[pair * WORDS + DONE], 1u);
}

// Items of a pair's two bodies whole (the first entry point: items before params.split): rounds
// of a's faces against blocks of b's, line by line, stopping at the first line that clears the
// pair.
@compute @workgroup_size(WORKGROUP)
fn depth(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let k = wg.y * ROW + wg.x;
    if (k >= params.split) {
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
    let skip = (item.whole >> ITEM_SKIP_SHIFT) & ((1u << LINES) - 1u);
    start_item(frame, skip, lid);
    if (lid == 0u) {
        item_shape = vec3u((item.a_count + WORKGROUP - 1u) / WORKGROUP,
                           (item.b_count + WORKGROUP - 1u) / WORKGROUP, item.whole & ITEM_WHOLE);
    }
    var todo = workgroupUniformLoad(&todo_lines);  // a barrier, and uniform
    let shape = workgroupUniformLoad(&item_shape);
    // The cap a line stops at: the frame's, lowered (in a pair's whole item) to the least figure
    // of a line measured whole, which a line stopped there cannot go below.
    var cap = workgroupUniformLoad(&item_cap);
    var last = LINES - 1u;  // the last line whose figures are written (the early stop)
    if (todo != 0u && shape.x != 0u && shape.y != 0u) {
        loop {
            let i = firstTrailingBit(todo);
            todo &= todo - 1u;
            let v = views[i];
            var most = NONE;   // max(depth_b - depth_a)
            var least = NONE;  // max(depth_a - depth_b)
            var round = 0u;
            var full = false;  // both figures of the line reached the cap
            loop {
                let fa = round * WORKGROUP + lid;
                let pa = project_face(v, face_in_pair(ma, item.a_start
                                                      + min(fa, item.a_count - 1u)));
                var block = 0u;
                loop {
                    let fb = block * WORKGROUP + lid;
                    let pb = project_face(v, face_in_pair(mb, item.b_start
                                                          + min(fb, item.b_count - 1u)));
                    let figure = face_pairs(pa, fa < item.a_count, pb, fb < item.b_count,
                                            frame.touch, lid);
                    most = max(most, figure.x);
                    least = max(least, figure.y);
                    if (cap != 0u) {
                        if (most > NONE) {
                            atomicMax(&kept[2u * i], key(most));
                            atomicMax(&kept[2u * i + 1u], key(least));
                        }
                        workgroupBarrier();
                        if (lid == 0u) {
                            capped = u32(at_cap(atomicLoad(&kept[2u * i]),
                                                atomicLoad(&kept[2u * i + 1u]), cap));
                        }
                        full = workgroupUniformLoad(&capped) != 0u;
                    }
                    block++;
                    if (full || block >= shape.y) {
                        break;
                    }
                }
                round++;
                if (full || round >= shape.x) {
                    break;
                }
            }
            if (most > NONE) {
                atomicMax(&kept[2u * i], key(most));
                atomicMax(&kept[2u * i + 1u], key(least));
            }
            workgroupBarrier();
            // An item that is its pair's whole work stops at the first line that clears the
            // pair (its depth is then 0 whatever the other lines say).
            if (shape.z != 0u) {
                if (lid == 0u) {
                    cleared = u32(clears(i));
                }
                if (workgroupUniformLoad(&cleared) != 0u) {
                    last = i;
                    break;
                }
                if (cap != 0u && !full) {
                    if (lid == 0u) {
                        capped = min(atomicLoad(&kept[2u * i]), atomicLoad(&kept[2u * i + 1u]));
                    }
                    cap = min(cap, workgroupUniformLoad(&capped));
                }
            }
            if (todo == 0u) {
                break;
            }
        }
    }
    end_item(item.pair, skip, last, flipped, lid);
}

// Items of a cluster of each body (the second entry point: items params.split and on): each
// thread holds a face of each, moved to the pair's frame once for every line.
@compute @workgroup_size(WORKGROUP)
fn depth_clusters(@builtin(workgroup_id) wg: vec3u,
                  @builtin(local_invocation_index) lid: u32) {
    let k = params.split + wg.y * ROW + wg.x;
    if (k >= params.items) {
        return;  // uniform across the workgroup
    }
    let item = items[k];
    let frame = frames[item.pair];
    let skip = (item.whole >> ITEM_SKIP_SHIFT) & ((1u << LINES) - 1u);
    start_item(frame, skip, lid);
    let ta = face_in_pair(frame.m0, item.a_start + min(lid, item.a_count - 1u));
    let tb = face_in_pair(frame.m1, item.b_start + min(lid, item.b_count - 1u));
    var todo = workgroupUniformLoad(&todo_lines);  // a barrier, and uniform
    let cap = workgroupUniformLoad(&item_cap);
    if (todo != 0u) {
        loop {
            let i = firstTrailingBit(todo);
            todo &= todo - 1u;
            workgroupBarrier();  // every thread has read the last line's flag
            if (lid == 0u) {
                // The pair's figures so far (other items'): they only grow.
                let row = item.pair * WORDS + 2u * i;
                capped = u32(at_cap(atomicLoad(&best[row]), atomicLoad(&best[row + 1u]), cap));
            }
            let full = workgroupUniformLoad(&capped) != 0u;
            let v = views[i];
            if (!full) {
                let figure = face_pairs(project_face(v, ta), lid < item.a_count,
                                        project_face(v, tb), lid < item.b_count, frame.touch,
                                        lid);
                if (figure.x > NONE) {
                    atomicMax(&kept[2u * i], key(figure.x));
                    atomicMax(&kept[2u * i + 1u], key(figure.y));
                }
            }
            if (todo == 0u) {
                break;
            }
        }
    }
    end_item(item.pair, skip, LINES - 1u, false, lid);
}

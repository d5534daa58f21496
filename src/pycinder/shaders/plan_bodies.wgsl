// Tile planner, pass P0 (compute; pycinder/focused/plan/p0_bodies.py): every body's bounds as pass
// P1 reads them (PlanBody), from its pose and boxes, as pycinder.focused.plan.p0_bodies.plan_bodies
// finds them in float64. One invocation per body.
//
// Everything is measured from the body's anchor (its oriented box's centre, exactly hi + lo):
// the host uploads the centres less the anchor, computed in float64, so nothing here rounds at
// the body's distance from the world's origin.
//
// The structs BodyPose, BodyExtent, PlanBody and PlanParams are generated from p0_bodies.py; so
// are the constants WORKGROUP, ROW, FLAG_MIRROR_A, FLAG_MIRROR_B, FLAG_OPEN_A, FLAG_OPEN_B,
// EXTENT_OPEN, EXTENT_MIRRORED and MIN_NORMAL.

@group(0) @binding(0) var<storage, read> poses: array<BodyPose>;
@group(0) @binding(1) var<storage, read> extents: array<BodyExtent>;
@group(0) @binding(2) var<storage, read_write> bodies: array<PlanBody>;
@group(0) @binding(3) var<uniform> params: PlanParams;

// -sign(x) as LAPACK's dlarfg takes it (BETA = -SIGN(norm, ALPHA)), a zero of either sign
// counting as positive: the host's reference decomposes its matrices with every -0.0 made +0.0
// (plan_numpy_windows._qr_frames), where LAPACK never meets a -0.0 diagonal element. A GPU's
// compiler need not keep the sign of a zero, so none is relied on here.
fn negated_sign(x: f32) -> f32 {
    return select(1.0, -1.0, x >= 0.0);
}

// |v|, scaled by its largest element first (as LAPACK's dnrm2 and dlapy2 are), so that elements
// far below 1 (a quarter turn's 6e-17, squared) neither underflow nor vanish.
fn norm(v: vec3f) -> f32 {
    let s = max(max(abs(v.x), abs(v.y)), abs(v.z));
    if (s == 0.0) {
        return 0.0;
    }
    return s * length(v / s);
}

// A Householder reflector H = I - tau v v^T (tau = 0: none).
struct Reflector {
    v: vec3f,
    tau: f32,
};

// LAPACK's dlarfg for a column whose diagonal element is alpha, with the elements below it in
// `below` (zeros above the diagonal): no reflection where they are all exactly zero.
fn reflector(alpha: f32, below: vec3f, unit: vec3f) -> Reflector {
    if (all(below == vec3f(0.0))) {
        return Reflector(vec3f(0.0), 0.0);
    }
    let beta = negated_sign(alpha) * norm(vec3f(alpha, norm(below), 0.0));
    return Reflector(unit + below * (1.0 / (alpha - beta)), (beta - alpha) / beta);
}

// H x; x itself where there is no reflector (LAPACK applies none).
fn reflect(h: Reflector, x: vec3f) -> vec3f {
    if (h.tau == 0.0) {
        return x;
    }
    return x - (h.tau * dot(h.v, x)) * h.v;
}

// The Q of the QR decomposition of m (columns), as NumPy's qr makes it (LAPACK's dgeqr2 and
// dorg2r: Q = H0 H1, the third reflector being none), made proper by negating its last column
// (plan_numpy_windows._qr_frames).
fn frame_of(given: mat3x3f) -> mat3x3f {
    // Elements below float32's smallest normal number are zeros, as the host's reference makes
    // them (a GPU may flush them to zero in arithmetic, or not).
    var m: mat3x3f;
    for (var c = 0u; c < 3u; c++) {
        m[c] = select(given[c], vec3f(0.0), abs(given[c]) < vec3f(MIN_NORMAL));
    }
    let h0 = reflector(m[0].x, vec3f(0.0, m[0].y, m[0].z), vec3f(1.0, 0.0, 0.0));
    let c1 = reflect(h0, m[1]);
    let h1 = reflector(c1.y, vec3f(0.0, 0.0, c1.z), vec3f(0.0, 1.0, 0.0));
    var q = mat3x3f(reflect(h0, reflect(h1, vec3f(1.0, 0.0, 0.0))),
                    reflect(h0, reflect(h1, vec3f(0.0, 1.0, 0.0))),
                    reflect(h0, reflect(h1, vec3f(0.0, 0.0, 1.0))));
    if (determinant(q) < 0.0) {
        q[2] = -q[2];
    }
    return q;
}

@compute @workgroup_size(WORKGROUP)
fn plan_bodies(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (i >= params.bodies) {
        return;
    }
    let pose = poses[i];
    let ext = extents[i];
    // r: the linear part, columns as R's columns.
    let r = transpose(mat3x3f(pose.rows[0].xyz, pose.rows[1].xyz, pose.rows[2].xyz));
    let half = mat3x3f(r[0] * ext.half.x, r[1] * ext.half.y, r[2] * ext.half.z);
    let q = frame_of(r);  // columns: the frame's axes
    var out: PlanBody;
    out.hi = pose.hi;
    out.lo = pose.lo;
    out.size = (ext.aabb_half.x + ext.aabb_half.y) + ext.aabb_half.z;
    let mirrored = (ext.flags & EXTENT_MIRRORED) != 0u;  // the host's float64 determinant
    let open = (ext.flags & EXTENT_OPEN) != 0u;
    out.flags_a = select(0u, FLAG_MIRROR_A, mirrored) | select(0u, FLAG_OPEN_A, open);
    out.flags_b = select(0u, FLAG_MIRROR_B, mirrored) | select(0u, FLAG_OPEN_B, open);
    out.centre = ext.centre;
    out.half_axes = array<vec4f, 3>(vec4f(half[0], 0.0), vec4f(half[1], 0.0),
                                    vec4f(half[2], 0.0));
    out.frame = array<vec4f, 3>(vec4f(q[0], 0.0), vec4f(q[1], 0.0), vec4f(q[2], 0.0));
    out.aabb_centre = ext.aabb_centre;
    out.aabb_half = ext.aabb_half;
    // Where both boxes hold along the world's axes: the oriented box's spread along axis k is
    // the sum over its half axes of |their k-th coordinate|.
    let spread = (abs(half[0]) + abs(half[1])) + abs(half[2]);
    out.world_lo = max(ext.centre - spread, ext.aabb_centre - ext.aabb_half);
    out.world_hi = min(ext.centre + spread, ext.aabb_centre + ext.aabb_half);
    // And along the frame's axes.
    var lo: vec3f;
    var hi: vec3f;
    for (var j = 0u; j < 3u; j++) {
        let axis = q[j];
        let p = abs(axis * half);  // |dot(axis, half axis c)| per c
        let h1 = (p.x + p.y) + p.z;
        let c1 = dot(axis, ext.centre);
        let c2 = dot(axis, ext.aabb_centre);
        let h2 = dot(abs(axis), ext.aabb_half);
        lo[j] = max(c1 - h1, c2 - h2);
        hi[j] = min(c1 + h1, c2 + h2);
    }
    out.own_lo = lo;
    out.own_hi = hi;
    bodies[i] = out;
}

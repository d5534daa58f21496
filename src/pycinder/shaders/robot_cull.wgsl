// A robot check's pair list culled by world boxes (compute; pycinder/robot/cull.py): for each
// configuration, a bit per checked pair, set where the two bodies' world boxes overlap. One
// invocation per configuration and word of 32 pairs (no atomics: the bits are the same on
// every run).
//
// A body's pose is K1's (pycinder/robot/kinematics.py) when it moves with the robot, else its
// own fixed pose (an environment body). Boxes are conservative: grown by the body's `pad` (the
// kinematics' error estimate, where the pose is K1's), by the rounding of their own arithmetic,
// and by `grow` (a padded check's clearance), so that a pair whose bodies overlap (or lie within
// `grow`) in float64 is never culled.
//
// The structs CullBody and CullParams are generated from cull.py; so are the constants
// WORKGROUP, FIXED and ROUNDING.

@group(0) @binding(0) var<storage, read> poses: array<vec4f>;
@group(0) @binding(1) var<storage, read> bodies: array<CullBody>;
@group(0) @binding(2) var<storage, read> pairs: array<vec2u>;
@group(0) @binding(3) var<storage, read_write> words: array<u32>;
@group(0) @binding(4) var<uniform> params: CullParams;

struct Box {
    lo: vec3f,
    hi: vec3f,
};

fn world_box(c: u32, u: u32) -> Box {
    let body = bodies[u];
    var r0 = body.pose[0];
    var r1 = body.pose[1];
    var r2 = body.pose[2];
    if (body.source != FIXED) {
        let base = 3u * (c * params.moving + body.source);
        r0 = poses[base];
        r1 = poses[base + 1u];
        r2 = poses[base + 2u];
    }
    let centre = vec3f(dot(r0.xyz, body.centre), dot(r1.xyz, body.centre),
                       dot(r2.xyz, body.centre)) + vec3f(r0.w, r1.w, r2.w);
    let half = vec3f(dot(abs(r0.xyz), body.half), dot(abs(r1.xyz), body.half),
                     dot(abs(r2.xyz), body.half));
    // Each coordinate is a few products and sums: its rounding is within ROUNDING of the sum of
    // its terms' magnitudes.
    let size = vec3f(dot(abs(r0.xyz), abs(body.centre)), dot(abs(r1.xyz), abs(body.centre)),
                     dot(abs(r2.xyz), abs(body.centre))) + abs(vec3f(r0.w, r1.w, r2.w)) + half;
    let grown = half + body.pad + params.grow + ROUNDING * size;
    return Box(centre - grown, centre + grown);
}

@compute @workgroup_size(WORKGROUP)
fn cull_pairs(@builtin(global_invocation_id) gid: vec3u) {
    let i = gid.x;
    if (i >= params.configurations * params.words) {
        return;
    }
    let c = i / params.words;
    let first = 32u * (i % params.words);
    let last = min(first + 32u, params.pairs);
    var bits = 0u;
    for (var p = first; p < last; p++) {
        let pair = pairs[p];
        let a = world_box(c, pair.x);
        let b = world_box(c, pair.y);
        if (all(a.lo <= b.hi) && all(b.lo <= a.hi)) {
            bits |= 1u << (p - first);
        }
    }
    words[i] = bits;
}

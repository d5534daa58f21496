// A robot check's pair list culled by world boxes (compute; pycinder/robot/k2_pair_cull.py): for
// each configuration, a bit per checked pair, set where the two bodies' world boxes overlap. One
// invocation per configuration and word of 32 pairs (no atomics: the bits are the same on
// every run).
//
// A body that moves with the robot takes its world box from pass K1
// (pycinder/robot/k1_kinematics.py), grown by its `pad` (twice K1's error estimate: the box then
// holds the body placed by float64 kinematics too); a fixed body (an environment's) has its own
// box, rounded outwards on the host. Every box is grown by `grow` (a padded check's clearance),
// so that a pair whose bodies overlap (or lie within `grow`) in float64 is never culled.
//
// The structs CullBody and CullParams are generated from k2_pair_cull.py; so are the constants
// WORKGROUP, ROW and FIXED.

@group(0) @binding(0) var<storage, read> boxes: array<vec4f>;
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
    var lo = body.lo;
    var hi = body.hi;
    if (body.source != FIXED) {
        let at = 2u * (c * params.moving + body.source);
        lo = boxes[at].xyz;
        hi = boxes[at + 1u].xyz;
    }
    let grown = body.pad + params.grow;
    return Box(lo - grown, hi + grown);
}

@compute @workgroup_size(WORKGROUP)
fn cull_pairs(@builtin(workgroup_id) wg: vec3u,
           @builtin(local_invocation_index) lid: u32) {
    // A large dispatch is a grid of rows of ROW workgroups (pycinder.gpu.bindings.workgroup_grid).
    let i = (wg.y * ROW + wg.x) * WORKGROUP + lid;
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

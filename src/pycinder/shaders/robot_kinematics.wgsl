// A robot's forward kinematics (compute; pycinder/robot/k1_kinematics.py): every collision body's
// world-from-body pose in every configuration, from each moving joint's motion. One invocation
// per configuration walks the joints in tree order (a parent's link before its children's), as
// pycinder.robot.model.RobotModel.link_transforms does in float64.
//
// A pose is three rows of an affine matrix: row i holds R's row i (xyz) and t_i (w).
// A motion is (sin, versine) of a revolute joint's angle or (offset, 0) of a prismatic joint's,
// computed on the host in float64 and rounded once: WGSL promises sin and cos only to 2^-11
// absolute.
//
// Each body's world box follows from its pose and its body-space box, grown by the rounding of
// its own arithmetic (ROUNDING of the sum of its terms' magnitudes): it holds the body's
// vertices (as stored in float32) placed by the pose as written.
//
// The structs KinJoint, KinBody and KinParams are generated from k1_kinematics.py; so are the
// constants WORKGROUP, ROW, JOINT_REVOLUTE, JOINT_PRISMATIC and ROUNDING.

@group(0) @binding(0) var<storage, read> joints: array<KinJoint>;
@group(0) @binding(1) var<storage, read> bodies: array<KinBody>;
@group(0) @binding(2) var<storage, read> motions: array<vec2f>;
@group(0) @binding(3) var<storage, read_write> links: array<vec4f>;
@group(0) @binding(4) var<storage, read_write> poses: array<vec4f>;
@group(0) @binding(5) var<uniform> params: KinParams;
@group(0) @binding(6) var<storage, read_write> boxes: array<vec4f>;

struct Affine {
    r0: vec4f,
    r1: vec4f,
    r2: vec4f,
};

// One row of a * b: the row's linear part times b's rows, its translation added.
fn row_times(r: vec4f, b: Affine) -> vec4f {
    return r.x * b.r0 + r.y * b.r1 + r.z * b.r2 + vec4f(0.0, 0.0, 0.0, r.w);
}

fn times(a: Affine, b: Affine) -> Affine {
    return Affine(row_times(a.r0, b), row_times(a.r1, b), row_times(a.r2, b));
}

// Rotation by an angle about the unit axis k (Rodrigues, as the host's _axis_rotations):
// R = I + s K + v K^2 with K^2 = k k^T - I, s = sin, v = 1 - cos (its versine).
fn rotation(k: vec3f, s: f32, v: f32) -> Affine {
    let kk = v * k;
    return Affine(
        vec4f(1.0 + kk.x * k.x - v, kk.x * k.y - s * k.z, kk.x * k.z + s * k.y, 0.0),
        vec4f(kk.y * k.x + s * k.z, 1.0 + kk.y * k.y - v, kk.y * k.z - s * k.x, 0.0),
        vec4f(kk.z * k.x - s * k.y, kk.z * k.y + s * k.x, 1.0 + kk.z * k.z - v, 0.0));
}

struct Box {
    lo: vec3f,
    hi: vec3f,
};

// The world box of a body-space box (centre, half extents) placed by pose t, conservatively.
fn world_box(t: Affine, centre: vec3f, half: vec3f) -> Box {
    let mid = vec3f(dot(t.r0.xyz, centre), dot(t.r1.xyz, centre), dot(t.r2.xyz, centre))
        + vec3f(t.r0.w, t.r1.w, t.r2.w);
    let reach = vec3f(dot(abs(t.r0.xyz), half), dot(abs(t.r1.xyz), half),
                      dot(abs(t.r2.xyz), half));
    let size = vec3f(dot(abs(t.r0.xyz), abs(centre)), dot(abs(t.r1.xyz), abs(centre)),
                     dot(abs(t.r2.xyz), abs(centre))) + abs(vec3f(t.r0.w, t.r1.w, t.r2.w))
        + reach;
    let grown = reach + ROUNDING * size;
    return Box(mid - grown, mid + grown);
}

fn link_at(c: u32, link: u32) -> Affine {
    let base = 3u * (c * params.links + link);
    return Affine(links[base], links[base + 1u], links[base + 2u]);
}

fn set_link(c: u32, link: u32, t: Affine) {
    let base = 3u * (c * params.links + link);
    links[base] = t.r0;
    links[base + 1u] = t.r1;
    links[base + 2u] = t.r2;
}

@compute @workgroup_size(WORKGROUP)
fn forward_kinematics(@builtin(workgroup_id) wg: vec3u,
           @builtin(local_invocation_index) lid: u32) {
    // A large dispatch is a grid of rows of ROW workgroups (pycinder.gpu.bindings.workgroup_grid).
    let c = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (c >= params.configurations) {
        return;
    }
    // The root link (index 0) is the world.
    set_link(c, 0u, Affine(vec4f(1.0, 0.0, 0.0, 0.0), vec4f(0.0, 1.0, 0.0, 0.0),
                           vec4f(0.0, 0.0, 1.0, 0.0)));
    for (var j = 0u; j < params.joints; j++) {
        let joint = joints[j];
        var t = times(link_at(c, joint.parent),
                      Affine(joint.origin[0], joint.origin[1], joint.origin[2]));
        if (joint.kind == JOINT_REVOLUTE) {
            let m = motions[c * params.motions + joint.motion];
            t = times(t, rotation(joint.axis, m.x, m.y));
        } else if (joint.kind == JOINT_PRISMATIC) {
            let d = motions[c * params.motions + joint.motion].x;
            t.r0.w += dot(t.r0.xyz, joint.axis) * d;
            t.r1.w += dot(t.r1.xyz, joint.axis) * d;
            t.r2.w += dot(t.r2.xyz, joint.axis) * d;
        }
        set_link(c, joint.child, t);
    }
    for (var b = 0u; b < params.bodies; b++) {
        let body = bodies[b];
        let pose = times(link_at(c, body.link),
                         Affine(body.origin[0], body.origin[1], body.origin[2]));
        let base = 3u * (c * params.bodies + b);
        poses[base] = pose.r0;
        poses[base + 1u] = pose.r1;
        poses[base + 2u] = pose.r2;
        let box = world_box(pose, body.centre, body.half);
        boxes[2u * (c * params.bodies + b)] = vec4f(box.lo, 0.0);
        boxes[2u * (c * params.bodies + b) + 1u] = vec4f(box.hi, 0.0);
    }
}

// Shared by passes C1 (measure_distance.wgsl) and H1 (measure_depth.wgsl), included after the
// layout: the bindings of a pass over items of a candidate pair's faces (see
// focused/measure/pair_work.py), and the packed shapes' vertices in the pair's own frame.

@group(0) @binding(0) var<storage, read> positions: array<f32>;
@group(0) @binding(1) var<storage, read> faces: array<u32>;
@group(0) @binding(2) var<storage, read> items: array<PairItem>;
@group(0) @binding(3) var<storage, read> frames: array<PairFrame>;
@group(0) @binding(4) var<storage, read_write> best: array<atomic<u32>>;
@group(0) @binding(5) var<uniform> params: PairParams;

fn vertex(i: u32) -> vec3f {
    return vec3f(positions[3u * i], positions[3u * i + 1u], positions[3u * i + 2u]);
}

// A body's vertex in the pair's frame (m: pair-from-body rows).
fn to_pair(m: array<vec4f, 3>, p: vec3f) -> vec3f {
    let q = vec4f(p, 1.0);
    return vec3f(dot(m[0], q), dot(m[1], q), dot(m[2], q));
}

// Focused strategy: body-space bounds of clusters whose vertices changed (deforming bodies).
//!include frame_tiles.wgsl


@group(0) @binding(0) var<storage, read> positions: array<f32>;
@group(0) @binding(1) var<storage, read> faces: array<u32>;
@group(0) @binding(2) var<storage, read> clusters: array<Cluster>;
@group(0) @binding(3) var<storage, read> which: array<u32>;          // cluster indices to update
@group(0) @binding(4) var<storage, read_write> bounds: array<vec4f>;  // lo, hi per cluster
@group(0) @binding(5) var<uniform> params: BoundsParams;

fn position(v: u32) -> vec3f {
    return vec3f(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
}

@compute @workgroup_size(WORKGROUP)
fn cluster_bounds(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (i >= params.count) {
        return;
    }
    let c = which[i];
    let info = clusters[c];
    var lo = vec3f(3.0e38);
    var hi = vec3f(-3.0e38);
    for (var f = info.face_start; f < info.face_start + info.face_count; f++) {
        for (var k = 0u; k < 3u; k++) {
            let p = position(faces[3u * f + k]);
            lo = min(lo, p);
            hi = max(hi, p);
        }
    }
    bounds[2u * c] = vec4f(lo, 0.0);
    bounds[2u * c + 1u] = vec4f(hi, 0.0);
}

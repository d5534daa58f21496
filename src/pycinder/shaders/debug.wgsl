// debug-buffers: copy the depth and stencil aspects into a buffer that can be read back
// (a depth24plus texture cannot be copied to a buffer directly).

struct Params {
    width: u32,
    height: u32,
    _pad0: u32,
    _pad1: u32,
};

@group(0) @binding(0) var depth_tex: texture_depth_2d;
@group(0) @binding(1) var stencil_tex: texture_2d<u32>;
@group(0) @binding(2) var<storage, read_write> out_depth: array<f32>;
@group(0) @binding(3) var<storage, read_write> out_stencil: array<u32>;
@group(0) @binding(4) var<uniform> params: Params;

@compute @workgroup_size(8, 8)
fn dump(@builtin(global_invocation_id) gid: vec3u) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let i = gid.y * params.width + gid.x;
    out_depth[i] = textureLoad(depth_tex, vec2i(gid.xy), 0);
    out_stencil[i] = textureLoad(stencil_tex, vec2i(gid.xy), 0).r;
}

// Focused strategy, start of every round (compute): clear the round's atlas pixels (what pass F3
// counts and lists per pixel), one thread per 32-bit word. The round's size is read from its
// parameters, and the dispatch from them too (an indirect dispatch the host writes), so a round's
// commands do not depend on its size.
//!include tiles.wgsl


@group(0) @binding(0) var<storage, read_write> pixels: array<u32>;
@group(0) @binding(1) var<uniform> params: CullParams;

@compute @workgroup_size(WORKGROUP)
fn clear_pixels(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (i < params.pixel_words) {
        pixels[i] = 0u;
    }
}

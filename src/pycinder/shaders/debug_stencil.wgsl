// debug-buffers: read the stencil buffer portably. A full-screen triangle is drawn once per
// stencil value v with the stencil test "equal v" (the reference is set per draw), writing v into
// an r8uint target: afterwards every pixel holds its stencil value. (Depth-stencil textures cannot
// be read by shaders or copied by aspect on every backend.)

struct VertexOut {
    @builtin(position) position: vec4f,
    @location(0) @interpolate(flat) value: u32,
};

@vertex
fn vs(@builtin(vertex_index) vi: u32, @builtin(instance_index) value: u32) -> VertexOut {
    let corner = vec2f(f32((vi << 1u) & 2u), f32(vi & 2u));
    var out: VertexOut;
    out.position = vec4f(corner * 2.0 - 1.0, 0.5, 1.0);
    out.value = value;
    return out;
}

@fragment
fn fs(in: VertexOut) -> @location(0) vec4u {
    return vec4u(in.value, 0u, 0u, 0u);
}

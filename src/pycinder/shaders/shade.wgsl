// Demo display: the detector's packed scene drawn lit from a display camera, one colour per body.
// Reads the same storage buffers the CInDeR passes read (positions, body of each vertex, vertex
// normals), so nothing is uploaded twice.

struct Body {
    clip_from_body: mat4x4f,
    world_from_body: mat4x4f,
    colour: vec4f,
};

@group(0) @binding(0) var<storage, read> positions: array<f32>;
@group(0) @binding(1) var<storage, read> vertex_body: array<u32>;
@group(0) @binding(2) var<storage, read> vertex_normals: array<f32>;
@group(0) @binding(3) var<storage, read> bodies: array<Body>;

struct Out {
    @builtin(position) position: vec4f,
    @location(0) normal: vec3f,
    @location(1) colour: vec4f,
};

@vertex
fn vs_main(@builtin(vertex_index) v: u32) -> Out {
    let b = bodies[vertex_body[v]];
    let p = vec3f(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
    let n = vec3f(vertex_normals[3u * v], vertex_normals[3u * v + 1u], vertex_normals[3u * v + 2u]);
    var out: Out;
    out.position = b.clip_from_body * vec4f(p, 1.0);
    out.normal = (b.world_from_body * vec4f(n, 0.0)).xyz;
    out.colour = b.colour;
    return out;
}

@fragment
fn fs_main(in: Out) -> @location(0) vec4f {
    let light = normalize(vec3f(0.4, 0.8, 0.5));
    let n = normalize(in.normal);
    let diffuse = max(dot(n, light), 0.0);
    let rim = 0.25 * max(dot(n, normalize(vec3f(-0.5, 0.2, -0.6))), 0.0);
    return vec4f(in.colour.rgb * (0.3 + 0.7 * diffuse + rim), 1.0);
}

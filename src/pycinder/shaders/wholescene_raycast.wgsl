// CInDeR passes 1-7 (paper Appendix A and section 4.2).
//
// Every pass draws the packed scene: all bodies' vertices live in one storage buffer, and the
// vertex shaders pull them ("vertex pulling"), so that a pass over all bodies is a single draw and
// a per-body pass (5-7) is a draw over that body's index range. Which fragments survive, and what
// the stencil and depth buffers do with them, is set by the pipeline state in gpu/states.py;
// these shaders only place geometry and say what colour a fragment would write.
//
// Record layout of the rgba32uint target (documented in result.py):
//   r = penetrating body id (1..65535)   written by pass 4 (edges)
//   g = penetrated body id  (1..65535)   written by pass 7 (faces)
//   b = bit pattern of the edge fragment's depth (f32)   written by pass 4
//   a = payload of the edge: global edge index + 1, or a packed normal   written by pass 4

// The Frame struct (edge offset, payload mode) and the PAYLOAD_* constants are declared in Python
// (wholescene/raycast.py) and generated in front of this source.
@group(0) @binding(0) var<uniform> frame: Frame;
// Body-space vertex positions, 3 floats per vertex, all bodies packed one after another.
@group(0) @binding(1) var<storage, read> positions: array<f32>;
// Index of the body each vertex belongs to (0-based; the id is index + 1).
@group(0) @binding(2) var<storage, read> vertex_body: array<u32>;
// Per body: clip-from-body matrix for the current view (projection * view * world-from-body).
@group(0) @binding(3) var<storage, read> clip_from_body: array<mat4x4f>;
// Unique edges as pairs of global vertex indices.
@group(0) @binding(4) var<storage, read> edges: array<u32>;
// Per vertex: body-space normal (3 floats), used by the offset mode.
@group(0) @binding(5) var<storage, read> vertex_normals: array<f32>;
// Per edge: body-space normal (3 floats), used when the payload is the normal.
@group(0) @binding(6) var<storage, read> edge_normals: array<f32>;
// Per body: world-from-body rotation part (for normals), as a mat4x4 with zero translation.
@group(0) @binding(7) var<storage, read> world_from_body: array<mat4x4f>;
// Copy of the colour target after pass 1 in the "prevent" mode: its r channel is the id of the
// body that owns the edge at each pixel (paper 4.3.1.3's intermediate texture). Pass 4 draws the
// same last edge, so this is also the penetrating id.
@group(0) @binding(8) var edge_owner_tex: texture_2d<u32>;

fn load_position(v: u32) -> vec3f {
    return vec3f(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
}

fn load_vertex_normal(v: u32) -> vec3f {
    return vec3f(vertex_normals[3u * v], vertex_normals[3u * v + 1u], vertex_normals[3u * v + 2u]);
}

struct EdgeOut {
    @builtin(position) position: vec4f,
    @location(0) @interpolate(flat) body_id: u32,
    @location(1) @interpolate(flat) payload: u32,
};

struct FaceOut {
    @builtin(position) position: vec4f,
    @location(0) @interpolate(flat) body_id: u32,
};

// Pack a unit normal into 10:10:10 signed fixed point; bits 30-31 are set to 0b01 so the payload
// is never zero.
fn pack_normal(n: vec3f) -> u32 {
    let q = vec3u(clamp(round((n * 0.5 + 0.5) * 1023.0), vec3f(0.0), vec3f(1023.0)));
    return q.x | (q.y << 10u) | (q.z << 20u) | (1u << 30u);
}

// Passes 1 and 4: edges as a line list. Vertex 2e and 2e+1 are the ends of edge e.
@vertex
fn vs_edge(@builtin(vertex_index) vi: u32) -> EdgeOut {
    let e = vi / 2u;
    let v = edges[vi];
    let body = vertex_body[v];
    var p = load_position(v);
    if (frame.edge_offset != 0.0) {
        // Move the vertex edge_offset world units: along the normal, divided by how much the
        // body's transform stretches that direction.
        let n = load_vertex_normal(v);
        let stretch = length((world_from_body[body] * vec4f(n, 0.0)).xyz);
        p = p + (frame.edge_offset / max(stretch, 1e-30)) * n;
    }
    var out: EdgeOut;
    out.position = clip_from_body[body] * vec4f(p, 1.0);
    out.body_id = body + 1u;
    if (frame.payload_mode == PAYLOAD_NORMAL) {
        let n_body = vec3f(edge_normals[3u * e], edge_normals[3u * e + 1u], edge_normals[3u * e + 2u]);
        let n = (world_from_body[body] * vec4f(n_body, 0.0)).xyz;
        out.payload = pack_normal(normalize(n));
    } else {
        out.payload = e + 1u;
    }
    return out;
}

// Passes 2, 3, 5, 6, 7: filled triangles, drawn through the index buffer.
@vertex
fn vs_face(@builtin(vertex_index) v: u32) -> FaceOut {
    let body = vertex_body[v];
    var out: FaceOut;
    out.position = clip_from_body[body] * vec4f(load_position(v), 1.0);
    out.body_id = body + 1u;
    return out;
}

// Pass 1 (colour writes masked off, or r, b, a when preventing) and pass 4 (writes r, b, a).
@fragment
fn fs_edge(in: EdgeOut) -> @location(0) vec4u {
    return vec4u(in.body_id, 0u, bitcast<u32>(in.position.z), in.payload);
}

// Passes 2, 3, 5, 6 (colour writes masked off) and pass 7 (writes g).
@fragment
fn fs_face(in: FaceOut) -> @location(0) vec4u {
    return vec4u(0u, in.body_id, 0u, 0u);
}

// Passes 2, 3, 5 and 6 with self_interference="prevent": a body does not count its own faces in
// front of its own edge, so a self-interference is never registered and never overwrites a real
// collision. (A closed body cannot contain its own edge, so nothing real is lost.)
@fragment
fn fs_face_prevent(in: FaceOut) -> @location(0) vec4u {
    let owner = textureLoad(edge_owner_tex, vec2i(in.position.xy), 0).r;
    if (owner == in.body_id) {
        discard;
    }
    return vec4u(0u, in.body_id, 0u, 0u);
}

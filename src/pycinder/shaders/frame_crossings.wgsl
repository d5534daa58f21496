// Focused strategy, pass F3 (render): the virtual ray casting of CInDeR, per pixel and per body.
//
// Each clipped face of both bodies is rasterised once (fragments outside the face's tile are
// dropped: faces near a window are passed on uncut) (no culling, no depth or stencil test; see
// gpu/states.py). At every pixel centre it covers, the face crosses the pixel's ray. Crossings
// on the counting side of the box only change how many times the ray has entered each body
// before it reaches the box: they are summed per body (front faces +1, back faces -1, as passes 2
// and 3 of the paper do in the stencil buffer). Crossings within the box's depth range are kept
// in a short list per pixel, so that pass F5 can count, for an edge sample at any depth in the
// box, the crossings between it and the counting side: there is no one-edge-per-pixel limit.
//!include frame_tiles.wgsl


@group(0) @binding(0) var<storage, read> tris: array<vec4u>;
@group(0) @binding(1) var<storage, read> tiles: array<Tile>;
// Per pixel: [3p] crossings listed at the pixel (may exceed `capacity`: then the pixel is
// undecided), [3p + 1] the outside-the-box winding of body a (low 16 bits) and b (high 16 bits),
// [3p + 2] the pixel's tile + 1.
@group(0) @binding(2) var<storage, read_write> pixels: array<atomic<u32>>;
// Per pixel, `capacity` crossings: bits of the f32 depth relative to the box's near side with the
// two low bits replaced by front << 1 | side, and the packed face.
@group(0) @binding(3) var<storage, read_write> crossings: array<vec2u>;
@group(0) @binding(4) var<uniform> atlas: Atlas;
@group(0) @binding(5) var<storage, read> tri_face: array<u32>;
// The pixels with a listed crossing, for pass F4 (counter C_ACTIVE).
@group(0) @binding(6) var<storage, read_write> active_pixels: array<u32>;
@group(0) @binding(7) var<storage, read_write> counters: array<atomic<u32>>;

struct VertexOut {
    @builtin(position) position: vec4f,
    @location(0) z: f32,
    @location(1) @interpolate(flat) flags: u32,
    @location(2) @interpolate(flat) depth: f32,   // the box's depth range, pixels
    @location(3) @interpolate(flat) window: vec4f,  // the tile's window: x0, y0, x1, y1 (atlas)
    @location(4) @interpolate(flat) face: u32,
};

@vertex
fn vs(@builtin(vertex_index) vi: u32) -> VertexOut {
    let v = tris[vi];
    let p = bitcast<vec3f>(v.xyz);
    let t = tiles[v.w >> 3u];
    var out: VertexOut;
    out.position = vec4f(p.x / f32(atlas.target_width) * 2.0 - 1.0,
                         1.0 - p.y / f32(atlas.height) * 2.0, 0.5, 1.0);
    out.z = p.z;
    out.flags = v.w;
    out.depth = t.slab.y - t.slab.x;
    let corner = vec2f(f32(t.window.x), f32(t.window.y));
    out.window = vec4f(corner, corner + vec2f(f32(t.window.z), f32(t.window.w)));
    out.face = tri_face[vi / 3u];
    return out;
}

@fragment
fn fs(in: VertexOut) {
    let at = in.position.xy;
    if (at.x < in.window.x || at.y < in.window.y || at.x > in.window.z || at.y > in.window.w) {
        return;  // the uncut part of a face near the window, over another tile
    }
    let pixel = u32(in.position.y) * atlas.width + u32(in.position.x);
    let side = in.flags & 1u;
    let front = (in.flags >> 1u) & 1u;
    let back = (in.flags >> 2u) & 1u;
    var outside: bool;
    var within: bool;
    if (back == 0u) {
        outside = in.z < 0.0;
        within = !outside && in.z <= in.depth;
    } else {
        outside = in.z > in.depth;
        within = !outside && in.z >= 0.0;
    }
    if (outside) {
        // Seen from inside the box, a ray towards the counting side enters a body through a
        // face turned towards that side: +1; leaves it through one turned away: -1.
        let towards = (front == 1u) != (back == 1u);
        let one = select(0xFFFFFFFFu, 1u, towards);
        atomicAdd(&pixels[3u * pixel + 1u], select(one, one << 16u, side == 1u));
    } else if (within) {
        let slot = atomicAdd(&pixels[3u * pixel], 1u);
        if (slot == 0u) {
            atomicStore(&pixels[3u * pixel + 2u], (in.flags >> 3u) + 1u);
            active_pixels[atomicAdd(&counters[C_ACTIVE], 1u)] = pixel;
        }
        if (slot < atlas.capacity) {
            crossings[pixel * atlas.capacity + slot] =
                vec2u((bitcast<u32>(in.z) & 0xFFFFFFFCu) | (front << 1u) | side, in.face);
        }
    }
}

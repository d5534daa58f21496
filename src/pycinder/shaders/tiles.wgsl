// Shared by the focused passes (included with //!include tiles.wgsl).
//
// A tile is an orthographic view of one candidate pair (a, b) over the box where they can touch.
// Tile coordinates: u, v in pixels across the window from its corner, z in pixels along the view
// direction from the middle of the box. Side 0 is body a, side 1 is body b.

struct Tile {
    m0: array<vec4f, 3>,   // tile-from-body rows (u, v, z) for body a
    m1: array<vec4f, 3>,   // tile-from-body rows for body b
    window: vec4u,         // atlas column, atlas row (in this round), width, height
    slab: vec4f,           // z0, z1: depth range of the box, in pixels; zw unused
    info: vec4u,           // body a, body b, flags (FLAG_*), pair index
};

// Count the crossings behind the box instead of in front of it (whichever side holds less).
const FLAG_COUNT_BACK: u32 = 1u;
// A body's transform reverses orientation: its faces' facing flips.
const FLAG_MIRROR0: u32 = 2u;
const FLAG_MIRROR1: u32 = 4u;
// Skip the tile once another tile of its pair found a hit (the pieces after a pair's probe).
const FLAG_SKIP_IF_HIT: u32 = 8u;

// A cluster: up to 64 faces and the edges they own, contiguous in the packed arrays.
struct Cluster {
    face_start: u32,
    face_count: u32,
    edge_start: u32,
    edge_count: u32,
};

// Counters of a frame. Items and triangles are reset every round; the rest every frame.
const C_FACE_ITEMS: u32 = 0u;
const C_EDGE_ITEMS: u32 = 1u;
const C_TRIS: u32 = 2u;
const C_ACTIVE: u32 = 3u;        // pixels with at least one listed crossing
const C_RECORDS: u32 = 4u;       // edge samples found inside the other body
const C_UNDECIDED: u32 = 5u;     // samples at pixels whose crossing list overflowed
const C_SAMPLES: u32 = 6u;       // edge samples tested
const C_MAX_FACE_ITEMS: u32 = 8u;
const C_MAX_EDGE_ITEMS: u32 = 9u;
const C_MAX_TRIS: u32 = 10u;
const C_TOTAL_TRIS: u32 = 11u;
const C_TOTAL_FACE_ITEMS: u32 = 12u;
const C_TOTAL_EDGE_ITEMS: u32 = 13u;

// Indirect dispatches are laid out in rows of this many workgroups (under the 65535 limit).
const ROW: u32 = 32768u;

fn tile_point(t: Tile, side: u32, p: vec3f) -> vec3f {
    let q = vec4f(p, 1.0);
    if (side == 0u) {
        return vec3f(dot(t.m0[0], q), dot(t.m0[1], q), dot(t.m0[2], q));
    }
    return vec3f(dot(t.m1[0], q), dot(t.m1[1], q), dot(t.m1[2], q));
}

fn tile_row(t: Tile, side: u32, k: u32) -> vec4f {
    if (side == 0u) {
        return t.m0[k];
    }
    return t.m1[k];
}

fn mirrored(t: Tile, side: u32) -> bool {
    return (t.info.z & select(FLAG_MIRROR0, FLAG_MIRROR1, side == 1u)) != 0u;
}

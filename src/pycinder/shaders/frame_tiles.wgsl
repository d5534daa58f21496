// Shared by the focused passes (included with //!include frame_tiles.wgsl).
//
// A tile is an orthographic view of one candidate pair (a, b) over the box where they can touch.
// Tile coordinates: u, v in pixels across the window from its corner, z in pixels along the view
// direction from the middle of the box. Side 0 is body a, side 1 is body b.
//!include layout

// Tile and Cluster are declared in pycinder/layout.py (generated into the layout prelude).

fn tile_point(t: Tile, side: u32, p: vec3f) -> vec3f {
    let q = vec4f(p, 1.0);
    if (side == 0u) {
        return vec3f(dot(t.m0[0], q), dot(t.m0[1], q), dot(t.m0[2], q));
    }
    return vec3f(dot(t.m1[0], q), dot(t.m1[1], q), dot(t.m1[2], q));
}

// The tile-space centre and half extent of the body-space box (lo, hi) of side `side`, grown by
// `pad` pixels (a conservative box: every point of the body box maps inside it).
fn tile_box(t: Tile, side: u32, lo: vec3f, hi: vec3f, pad: f32) -> array<vec3f, 2> {
    let centre = 0.5 * (lo + hi);
    let half = 0.5 * (hi - lo);
    var mid: vec3f;
    var ext: vec3f;
    for (var k = 0u; k < 3u; k++) {
        let row = tile_row(t, side, k);
        mid[k] = dot(row.xyz, centre) + row.w;
        ext[k] = dot(abs(row.xyz), half) + pad;
    }
    return array<vec3f, 2>(mid, ext);
}

fn tile_row(t: Tile, side: u32, k: u32) -> vec4f {
    if (side == 0u) {
        return t.m0[k];
    }
    return t.m1[k];
}

fn mirrored(t: Tile, side: u32) -> bool {
    return (t.flags & select(FLAG_MIRROR0, FLAG_MIRROR1, side == 1u)) != 0u;
}

fn is_open(t: Tile, side: u32) -> bool {
    return (t.flags & select(FLAG_OPEN0, FLAG_OPEN1, side == 1u)) != 0u;
}

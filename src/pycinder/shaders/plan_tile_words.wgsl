// Tile planner, pass P3 (compute; pycinder/focused/plan/p3_tile_words.py): each tile of the plan as
// the frame's passes read it (Tile), from pass P2's tile record, pass P1's window of its pair and
// the pair's bodies. One invocation per tile record of P2's capacity; those past the plan's tiles
// (AtlasSummary.tiles) return at once.
//
// Nothing is measured from the world's origin: a body's translation comes as its offset from its
// anchor (pass P1's, exactly hi + lo), the window's origin is relative to the pair's anchor, and a
// side's translation less the pair's anchor is the offset between the two anchors, taken as P1
// takes it, (hi_side - hi_pair) + (lo_side - lo_pair), plus the side's own offset. The tile's
// place in its window (u, v pixels from the window's corner) is subtracted in pixels.
//
// The structs BodyPose, PlanWindow, AtlasTile, AtlasSummary and Tile are generated from
// p3_tile_words.py, p1_windows.py, p2_atlas.py and layout.py; so are the constants WORKGROUP and
// ROW.

@group(0) @binding(0) var<storage, read> bodies: array<BodyPose>;
@group(0) @binding(1) var<storage, read> windows: array<PlanWindow>;
@group(0) @binding(2) var<storage, read> pairs: array<vec2u>;
@group(0) @binding(3) var<storage, read> atlas: array<AtlasTile>;
@group(0) @binding(4) var<storage, read> summary: AtlasSummary;
@group(0) @binding(5) var<storage, read_write> tiles: array<Tile>;

// One side's tile-from-body rows: (axis_i . R) / pixel, and in w the tile coordinate of the
// body's origin, axis_i . (t - origin) / pixel, where t - origin is measured from the pair's
// anchor body `p` (corner: the window's corner relative to it), less the tile's place in pixels
// (`place`: u axis_i . axis_0 + v axis_i . axis_1).
fn side_rows(b: BodyPose, p: BodyPose, view: mat3x3f, corner: vec3f, pixel: f32,
             place: vec3f) -> array<vec4f, 3> {
    let offset = vec3f(b.rows[0].w, b.rows[1].w, b.rows[2].w);  // t - the body's anchor
    // The body's origin from the window's corner: (anchor_b - anchor_p) + (t - anchor_b) - corner.
    let from_corner = (((b.hi - p.hi) + (b.lo - p.lo)) + offset) - corner;
    let at = (from_corner * view) / pixel - place;  // axis_i . from_corner / pixel - place_i
    // axis_i . R: sum_k axis_i[k] R[k][j], R's rows weighted by the axis's components.
    let r0 = b.rows[0].xyz;
    let r1 = b.rows[1].xyz;
    let r2 = b.rows[2].xyz;
    let x = view[0];
    let y = view[1];
    let z = view[2];
    return array<vec4f, 3>(
        vec4f((x.x * r0 + x.y * r1 + x.z * r2) / pixel, at.x),
        vec4f((y.x * r0 + y.y * r1 + y.z * r2) / pixel, at.y),
        vec4f((z.x * r0 + z.y * r1 + z.z * r2) / pixel, at.z));
}

@compute @workgroup_size(WORKGROUP)
fn tile_words(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let t = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (summary.fits == 0u || t >= summary.tiles || t >= arrayLength(&tiles)) {
        return;
    }
    let tile = atlas[t];
    let k = tile.pair;
    let w = windows[k];
    let ab = pairs[k];
    let p = bodies[w.anchor];
    // Pixels from the window's corner to the tile's: the part's offset (when it is moved), then a
    // band cut's second part's column.
    let moved = tile.moved != 0u;
    let u = f32(select(0u, tile.u0, moved) + tile.shift);
    let v = f32(select(0u, tile.v0, moved));
    // The view's axes as columns: d * view = (axis_0 . d, axis_1 . d, axis_2 . d).
    let view = mat3x3f(w.axes[0].xyz, w.axes[1].xyz, w.axes[2].xyz);
    let place = u * (view[0] * view) + v * (view[1] * view);
    var out: Tile;
    out.m0 = side_rows(bodies[ab.x], p, view, w.origin, w.pixel, place);
    out.m1 = side_rows(bodies[ab.y], p, view, w.origin, w.pixel, place);
    out.window = tile.window;
    out.slab = vec4f(w.slab, 0.0, 0.0);
    out.bodies = ab;
    out.flags = w.flags | tile.flags;
    out.pair = k;
    tiles[t] = out;
}

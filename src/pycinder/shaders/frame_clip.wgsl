// Focused strategy, pass F2 (compute): the faces of each kept cluster, projected into their tile
// and clipped to its window, as triangles for pass F3 to rasterise.
//
// Two entry points: `clip` (one workgroup per kept cluster, one thread per face) passes on the
// faces within the window and lists those reaching beyond it; `cut` (one thread per listed face)
// cuts them. Cutting is long and branchy: in threads of its own it runs side by side with other
// cuts, not masked beside faces that needed none.
//
// A face within the window is passed on as it is. A face reaching beyond it is cut to the window:
// the polygon of
// its vertices inside that rectangle, the points where its edges cross the rectangle's sides, and
// the rectangle's corners inside it, fanned into triangles. The crossing points are computed from
// each edge's lower-indexed vertex, and an edge that crosses the rectangle's side belongs to two
// faces that both reach past it, so both cut it at the same point bit for bit: the surface stays
// watertight, and every ray through a pixel centre of the window still crosses a closed body's
// surface an even number of times.
// Facing comes from the projected winding (flipped for mirroring transforms); pass F3 draws both
// sides.
//!include frame_tiles.wgsl

// Pixels by which a face's box is grown before it is tested for pixel centres: more than the
// rasterizer's vertex snapping can move an edge (half a step of a 4-bit sub-pixel grid).
const SNAP_MARGIN: f32 = 0.125;


@group(0) @binding(0) var<storage, read> tiles: array<Tile>;
@group(0) @binding(1) var<storage, read> clusters: array<Cluster>;
@group(0) @binding(2) var<storage, read> positions: array<f32>;
@group(0) @binding(3) var<storage, read> faces: array<u32>;
@group(0) @binding(4) var<storage, read> face_items: array<vec2u>;
// Three vertices per triangle: atlas x, atlas y, z relative to the box's near depth (f32 bits),
// and flags: tile << 3 | count_back << 2 | front << 1 | side.
@group(0) @binding(5) var<storage, read_write> tris: array<vec4u>;
@group(0) @binding(6) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(7) var<uniform> params: ClipParams;
// The packed face (cluster order) each triangle comes from.
@group(0) @binding(8) var<storage, read_write> tri_face: array<u32>;
// Faces to cut: face item, face within its cluster (counter C_CUTS).
@group(0) @binding(9) var<storage, read_write> cuts: array<vec2u>;

fn position(v: u32) -> vec3f {
    return vec3f(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
}

fn cross2(a: vec2f, b: vec2f) -> f32 {
    return a.x * b.y - a.y * b.x;
}

// Where the edge between vertices ia and ib crosses the line where coordinate `axis` equals
// `at`, computed from the lower-indexed vertex so both faces of the edge agree exactly.
fn cross_line(pa: vec3f, ia: u32, pb: vec3f, ib: u32, axis: u32, at: f32) -> vec3f {
    var p = pa;
    var q = pb;
    if (ib < ia) {
        p = pb;
        q = pa;
    }
    let t = (at - p[axis]) / (q[axis] - p[axis]);
    var r = p + t * (q - p);
    r[axis] = at;
    return r;
}

// The edge function of the edge (ia, ib) at point c, as seen walking from ia to ib, evaluated
// from the lower-indexed vertex so both faces of the edge agree exactly (with opposite signs).
fn edge_side(pa: vec2f, ia: u32, pb: vec2f, ib: u32, c: vec2f) -> f32 {
    if (ia < ib) {
        return cross2(pb - pa, c - pa);
    }
    return -cross2(pa - pb, c - pb);
}

fn emit(slot: u32, a: vec3f, b: vec3f, c: vec3f, origin: vec2f, z0: f32, flags: u32, face: u32) {
    if (slot >= params.tri_cap) {
        return;
    }
    tri_face[slot] = face;
    let base = 3u * slot;
    tris[base] = vec4u(bitcast<vec3u>(vec3f(a.xy + origin, a.z - z0)), flags);
    tris[base + 1u] = vec4u(bitcast<vec3u>(vec3f(b.xy + origin, b.z - z0)), flags);
    tris[base + 2u] = vec4u(bitcast<vec3u>(vec3f(c.xy + origin, c.z - z0)), flags);
}

// Face `lid` of face item `item_index` in its tile.
struct TileFace {
    p: array<vec3f, 3>,  // its corners in tile coordinates
    ids: vec3u,          // their vertices
    face: u32,           // the packed face
    flags: u32,          // what its triangles carry (see `tris`)
    area: f32,           // twice its signed projected area
};

fn tile_face(item_index: u32, lid: u32) -> TileFace {
    let item = face_items[item_index];
    let c = item.y & 0x7FFFFFFFu;
    let side = item.y >> 31u;
    let t = tiles[item.x];
    var out: TileFace;
    out.face = clusters[c].face_start + lid;
    let f = out.face;
    out.ids = vec3u(faces[3u * f], faces[3u * f + 1u], faces[3u * f + 2u]);
    out.p[0] = tile_point(t, side, position(out.ids.x));
    out.p[1] = tile_point(t, side, position(out.ids.y));
    out.p[2] = tile_point(t, side, position(out.ids.z));
    out.area = cross2(out.p[1].xy - out.p[0].xy, out.p[2].xy - out.p[0].xy);
    // Tile coordinates are right-handed with z pointing away from the viewer, so the outward
    // normal of a counter-clockwise face has z component `area`: negative when it faces the viewer.
    let front = (out.area < 0.0) != mirrored(t, side);
    let back = (t.flags & FLAG_COUNT_BACK) != 0u;
    out.flags = (item.x << 3u) | (select(0u, 4u, back)) | (select(0u, 2u, front)) | side;
    return out;
}

@compute @workgroup_size(WORKGROUP)
fn clip(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let item_index = wg.y * ROW + wg.x;
    if (item_index >= min(atomicLoad(&counters[C_FACE_ITEMS]), params.item_cap)) {
        return;
    }
    let item = face_items[item_index];
    if (lid >= clusters[item.y & 0x7FFFFFFFu].face_count) {
        return;
    }
    let t = tiles[item.x];
    let face = tile_face(item_index, lid);
    var p = face.p;
    let w = f32(t.window.z);
    let h = f32(t.window.w);
    let lo = min(min(p[0], p[1]), p[2]);
    let hi = max(max(p[0], p[1]), p[2]);
    if (hi.x <= 0.0 || lo.x >= w || hi.y <= 0.0 || lo.y >= h) {
        return;
    }
    let back = (t.flags & FLAG_COUNT_BACK) != 0u;
    if ((!back && lo.z > t.slab.y) || (back && hi.z < t.slab.x)) {
        return;  // wholly on the far side of the box: crosses no ray the count looks along
    }
    // A face covers no pixel centre (x + 0.5, y + 0.5) outside its box: a face smaller than a
    // pixel usually holds none, and then crosses no ray at all. The rasterizer snaps vertices to
    // its sub-pixel grid (at least 4 bits) and decides centres on an edge by the top-left rule,
    // so a centre just outside the face's box can still be covered by the snapped face (and then
    // by neither neighbour): the box is grown by SNAP_MARGIN before it is tested.
    let first_centre = ceil(lo.xy - 0.5 - SNAP_MARGIN);
    if (any(first_centre > floor(hi.xy - 0.5 + SNAP_MARGIN))) {
        return;
    }
    if (face.area == 0.0) {
        return;  // seen edge-on: covers no pixel centre
    }
    if (lo.x >= 0.0 && hi.x <= w && lo.y >= 0.0 && hi.y <= h) {
        let origin = vec2f(f32(t.window.x), f32(t.window.y));
        emit(atomicAdd(&counters[C_TRIS], 1u), p[0], p[1], p[2], origin, t.slab.x, face.flags,
             face.face);
        return;
    }
    let slot = atomicAdd(&counters[C_CUTS], 1u);
    if (slot < params.tri_cap) {
        cuts[slot] = vec2u(item_index, lid);
    }
}

// The listed faces cut to the window: one thread each.
@compute @workgroup_size(WORKGROUP)
fn cut(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (i >= min(atomicLoad(&counters[C_CUTS]), params.tri_cap)) {
        return;
    }
    let listed = cuts[i];
    let face = tile_face(listed.x, listed.y);
    let t = tiles[face_items[listed.x].x];
    var p = face.p;
    let area = face.area;
    let origin = vec2f(f32(t.window.x), f32(t.window.y));
    let z0 = t.slab.x;
    let r0 = 0.0;
    let rw = f32(t.window.z);
    let rh = f32(t.window.w);
    // The face cut to the rectangle: a convex polygon of at most 7 corners (13 candidates).
    let id = array<u32, 3>(face.ids.x, face.ids.y, face.ids.z);
    var pts: array<vec3f, 13>;
    var n = 0u;
    for (var k = 0u; k < 3u; k++) {
        let q = p[k];
        if (q.x >= r0 && q.x <= rw && q.y >= r0 && q.y <= rh) {
            pts[n] = q;
            n++;
        }
    }
    let limits = array<vec2f, 2>(vec2f(r0, rw), vec2f(r0, rh));
    for (var k = 0u; k < 3u; k++) {
        let k1 = (k + 1u) % 3u;
        for (var axis = 0u; axis < 2u; axis++) {
            let other = 1u - axis;
            for (var s = 0u; s < 2u; s++) {
                let at = limits[axis][s];
                if ((p[k][axis] - at) * (p[k1][axis] - at) < 0.0) {
                    let r = cross_line(p[k], id[k], p[k1], id[k1], axis, at);
                    if (r[other] >= limits[other].x && r[other] <= limits[other].y) {
                        pts[n] = r;
                        n++;
                    }
                }
            }
        }
    }
    // Rectangle corners inside the face, on the face's plane.
    let corners = array<vec2f, 4>(vec2f(r0, r0), vec2f(rw, r0), vec2f(rw, rh), vec2f(r0, rh));
    for (var k = 0u; k < 4u; k++) {
        let q = corners[k];
        let e0 = edge_side(p[0].xy, id[0], p[1].xy, id[1], q);
        let e1 = edge_side(p[1].xy, id[1], p[2].xy, id[2], q);
        let e2 = edge_side(p[2].xy, id[2], p[0].xy, id[0], q);
        let inside = select(e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0,
                            e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0, area > 0.0);
        if (inside) {
            // Barycentric weights of the corner give its depth on the face's plane.
            let z = (e1 * p[0].z + e2 * p[1].z + e0 * p[2].z) / area;
            pts[n] = vec3f(q, z);
            n++;
        }
    }
    if (n < 3u) {
        return;
    }
    // Order the corners around their centroid and fan them.
    var centre = vec2f(0.0);
    for (var k = 0u; k < n; k++) {
        centre += pts[k].xy;
    }
    centre /= f32(n);
    var angle: array<f32, 13>;
    for (var k = 0u; k < n; k++) {
        let d = pts[k].xy - centre;
        angle[k] = atan2(d.y, d.x);
    }
    for (var k = 1u; k < n; k++) {
        let a = angle[k];
        let q = pts[k];
        var j = k;
        loop {
            if (j == 0u || angle[j - 1u] <= a) {
                break;
            }
            angle[j] = angle[j - 1u];
            pts[j] = pts[j - 1u];
            j--;
        }
        angle[j] = a;
        pts[j] = q;
    }
    let slot = atomicAdd(&counters[C_TRIS], n - 2u);
    for (var k = 1u; k + 1u < n; k++) {
        emit(slot + k - 1u, pts[0], pts[k], pts[k + 1u], origin, z0, face.flags, face.face);
    }
}

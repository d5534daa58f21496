// Focused strategy, pass F6 (compute, indirect): surfaces that cross, for tiles with an open body.
//
// An open body has no inside, so nothing is tested against its winding (passes F4 and F5 skip it).
// Its surface is tested here instead: two triangulated surfaces cross exactly when an edge of one
// passes through a face of the other (the ends of every segment where two faces meet lie on an
// edge of one of them). One workgroup per kept edge cluster of the tile: the other body's clusters
// whose bounds meet the edge cluster's bounds within the tile's box are found a chunk at a time,
// their faces are loaded into workgroup memory, and every edge of the cluster is tested against
// them exactly (in tile coordinates, no sampling).
//
// The test is watertight: whether the edge's line passes through a face is decided by the signs
// of three signed volumes, one per face edge, each computed from the face edge's lower-indexed
// vertex, so the two faces sharing an edge see the same value with opposite signs and a line
// through their shared edge passes through exactly one of them (a zero counts for the face that
// walks the edge from its lower index).
//
// llvmpipe (the CPU driver of lavapipe and of OpenGL without a GPU) silently ends a thread's loops
// after 65,535 steps in all. A workgroup counts the steps its threads take (the most any thread
// takes, the same for all of them) and, before a cluster whose faces would take it past
// `params.budget`, stops: the tile is counted undecided, marked with UNDECIDED_BUDGET_BIT, so that
// the host runs it again with its box cut thinner (fewer clusters meet a thinner box; longer lists
// would not help), and warns when even that is not enough.
//!include frame_tiles.wgsl
//!include frame_records.wgsl


@group(0) @binding(0) var<storage, read> tiles: array<Tile>;
@group(0) @binding(1) var<storage, read> clusters: array<Cluster>;
@group(0) @binding(2) var<storage, read> bounds: array<vec4f>;       // lo, hi per cluster
@group(0) @binding(3) var<storage, read> positions: array<f32>;
@group(0) @binding(4) var<storage, read> faces: array<u32>;
@group(0) @binding(5) var<storage, read> edges: array<u32>;
@group(0) @binding(6) var<storage, read> edge_items: array<vec2u>;
// Per (tile, side) entry e = 2 * tile + side: x = its first cull thread (a prefix over the frame,
// so entries[e + 1].x - entries[e].x is the entry's cluster count), y = its first cluster.
@group(0) @binding(7) var<storage, read> entries: array<vec2u>;
@group(0) @binding(8) var<storage, read_write> tile_counts: array<atomic<u32>>;
// Per record: tile, pixel u | v << 16, f32 bits of the crossing's z, edge | kind | side.
@group(0) @binding(9) var<storage, read_write> records: array<Record>;
@group(0) @binding(10) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(11) var<uniform> params: CrossingTestParams;

var<workgroup> wanted: array<u32, WORKGROUP>;        // clusters of this chunk to test
var<workgroup> n_wanted: atomic<u32>;                 // how many
var<workgroup> wanted_count: u32;                     // the same, read uniformly
var<workgroup> face_pos: array<vec3f, 192>;          // 3 vertices per face, tile coordinates
var<workgroup> face_ids: array<vec3u, WORKGROUP>;    // their vertex indices
var<workgroup> stop: u32;

fn position(v: u32) -> vec3f {
    return vec3f(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]);
}

// The tile-space box (lo, hi) of cluster c of side `side`, grown by a pixel for rounding.
fn cluster_box(t: Tile, side: u32, c: u32) -> array<vec3f, 2> {
    let box = tile_box(t, side, bounds[2u * c].xyz, bounds[2u * c + 1u].xyz, 1.0);
    return array<vec3f, 2>(box[0] - box[1], box[0] + box[1]);
}

// Signed volume of the line p0 -> p1 with the face edge a -> b, from the lower-indexed vertex.
fn edge_volume(p0: vec3f, d: vec3f, a: vec3f, ia: u32, b: vec3f, ib: u32) -> f32 {
    if (ia < ib) {
        return dot(d, cross(a - p0, b - p0));
    }
    return -dot(d, cross(b - p0, a - p0));
}

fn positive(w: f32, ia: u32, ib: u32) -> bool {
    return w > 0.0 || (w == 0.0 && ia < ib);
}

// Where segment p0 -> p1 crosses the face (a, b, c) with vertex ids `ids`, as the segment's
// parameter in [0, 1]; -1 when it does not. A segment whose ends both lie within rounding of the
// face's plane lies in that plane: where it meets the face the surfaces touch, and where it does
// not, the signs of the line test are rounding's (a wall's edge in the plane of a ceiling's face
// 150 mm beyond it would pass). Neither is a crossing. An end's height above the plane,
// h = n.(p - a), is rounded by COPLANAR of the points' reach times |n| (the points' own
// rounding) and |p - a| (|b - a| + |c - a|) (the plane's turn, which a small face far from p
// turns into height).
fn within_plane(h: f32, p: vec3f, a: vec3f, n: vec3f, span: f32, reach: f32) -> bool {
    return abs(h) <= COPLANAR * reach * (length(n) + length(p - a) * span);
}

fn crossing(p0: vec3f, p1: vec3f, a: vec3f, b: vec3f, c: vec3f, ids: vec3u) -> f32 {
    let n = cross(b - a, c - a);
    let h0 = dot(n, p0 - a);
    let h1 = dot(n, p1 - a);
    let reach = max(max(max(abs(p0.x), abs(p0.y)), max(abs(p0.z), abs(p1.x))),
                    max(max(abs(p1.y), abs(p1.z)),
                        max(max(max(abs(a.x), abs(a.y)), abs(a.z)),
                            max(max(max(abs(b.x), abs(b.y)), abs(b.z)),
                                max(max(abs(c.x), abs(c.y)), abs(c.z))))));
    let span = length(b - a) + length(c - a);
    if (within_plane(h0, p0, a, n, span, reach) && within_plane(h1, p1, a, n, span, reach)) {
        return -1.0;
    }
    let d = p1 - p0;
    let s0 = positive(edge_volume(p0, d, a, ids.x, b, ids.y), ids.x, ids.y);
    let s1 = positive(edge_volume(p0, d, b, ids.y, c, ids.z), ids.y, ids.z);
    let s2 = positive(edge_volume(p0, d, c, ids.z, a, ids.x), ids.z, ids.x);
    if (s0 != s1 || s1 != s2) {
        return -1.0;  // the line misses the face
    }
    if ((h0 > 0.0 && h1 > 0.0) || (h0 < 0.0 && h1 < 0.0) || h0 == h1) {
        return -1.0;  // both ends on one side of the face's plane (or the edge lies in it)
    }
    return h0 / (h0 - h1);
}

@compute @workgroup_size(WORKGROUP)
fn crossing_test(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let item_index = wg.y * ROW + wg.x;
    let item = edge_items[min(item_index, arrayLength(&edge_items) - 1u)];
    let t = tiles[item.x];
    if (lid == 0u) {
        let items = min(atomicLoad(&counters[C_EDGE_ITEMS]), params.item_cap);
        let found = atomicLoad(&tile_counts[params.pair_offset + t.pair]) != 0u;
        let neither_open = !is_open(t, 0u) && !is_open(t, 1u);
        stop = select(0u, 1u, item_index >= items || neither_open
                                  || (params.early_out != 0u && found) || frame_decided(t));
    }
    if (workgroupUniformLoad(&stop) != 0u) {
        return;
    }
    let tile_index = item.x;
    let c = item.y & 0x7FFFFFFFu;
    let side = item.y >> 31u;
    let other = 1u - side;
    let info = clusters[c];
    // Crossings lie within the tile's box and within both clusters' boxes.
    let own = cluster_box(t, side, c);
    let lo = max(own[0], vec3f(0.0, 0.0, t.slab.x));
    let hi = min(own[1], vec3f(f32(t.window.z), f32(t.window.w), t.slab.y));
    let e_other = 2u * tile_index + other;
    let first = entries[e_other].y;
    let count = entries[e_other + 1u].x - entries[e_other].x;
    var found = 0u;
    // Loop steps taken so far: the chunk loop and cluster_box's, then per wanted cluster the
    // cluster loop's, the edge loop's and the face loop's of the thread with the most edges.
    var spent = 3u;
    var unfinished = false;
    let edge_rounds = (info.edge_count + WORKGROUP - 1u) / WORKGROUP;
    for (var chunk = 0u; chunk < count; chunk += WORKGROUP) {
        if (spent + 4u > params.budget) {
            unfinished = true;
            break;
        }
        spent += 4u;
        if (lid == 0u) {
            atomicStore(&n_wanted, 0u);
        }
        workgroupBarrier();
        let k = chunk + lid;
        if (k < count && all(lo <= hi)) {
            let box = cluster_box(t, other, first + k);
            if (all(box[0] <= hi) && all(lo <= box[1])) {
                wanted[atomicAdd(&n_wanted, 1u)] = first + k;
            }
        }
        workgroupBarrier();
        if (lid == 0u) {
            wanted_count = atomicLoad(&n_wanted);
        }
        let n = workgroupUniformLoad(&wanted_count);
        for (var j = 0u; j < n; j++) {
            let other_info = clusters[workgroupUniformLoad(&wanted[j])];
            let cost = 1u + edge_rounds * (1u + other_info.face_count);
            if (spent + cost > params.budget) {
                unfinished = true;
                break;
            }
            spent += cost;
            if (lid < other_info.face_count) {
                let f = other_info.face_start + lid;
                let ids = vec3u(faces[3u * f], faces[3u * f + 1u], faces[3u * f + 2u]);
                face_ids[lid] = ids;
                face_pos[3u * lid] = tile_point(t, other, position(ids.x));
                face_pos[3u * lid + 1u] = tile_point(t, other, position(ids.y));
                face_pos[3u * lid + 2u] = tile_point(t, other, position(ids.z));
            }
            workgroupBarrier();
            for (var ei = lid; ei < info.edge_count; ei += WORKGROUP) {
                let e = info.edge_start + ei;
                let p0 = tile_point(t, side, position(edges[2u * e]));
                let p1 = tile_point(t, side, position(edges[2u * e + 1u]));
                for (var f = 0u; f < other_info.face_count; f++) {
                    let s = crossing(p0, p1, face_pos[3u * f], face_pos[3u * f + 1u],
                                     face_pos[3u * f + 2u], face_ids[f]);
                    if (s < 0.0) {
                        continue;
                    }
                    let x = p0 + s * (p1 - p0);
                    // Count each crossing in the one tile piece whose box holds it.
                    if (x.x < 0.0 || x.y < 0.0 || x.x >= f32(t.window.z) || x.y >= f32(t.window.w)
                            || x.z < t.slab.x || x.z > t.slab.y) {
                        continue;
                    }
                    found++;
                    append_record(t, Record(tile_index, u32(x.x) | (u32(x.y) << 16u),
                                           bitcast<u32>(x.z),
                                           e | (RECORD_CROSSING << RECORD_KIND_SHIFT)
                                             | (side << RECORD_SIDE_BIT)));
                }
            }
            workgroupBarrier();
        }
        if (unfinished) {
            break;
        }
    }
    if (unfinished && lid == 0u) {
        atomicAdd(&tile_counts[2u * tile_index + 1u], 1u);
        atomicOr(&tile_counts[2u * tile_index + 1u], UNDECIDED_BUDGET_BIT);
        atomicAdd(&counters[C_UNDECIDED], 1u);
    }
    if (found > 0u) {
        atomicAdd(&tile_counts[2u * tile_index], found);
        mark_found(t);
    }
}

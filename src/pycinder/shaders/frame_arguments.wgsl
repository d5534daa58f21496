// Focused strategy: turn the counters of the last pass into indirect dispatch and draw arguments,
// clamped to what the buffers hold, and keep the largest counts for the host to size buffers.
//!include frame_tiles.wgsl


@group(0) @binding(0) var<storage, read_write> counters: array<u32>;
// The indirect arguments (IndirectArgs in pycinder/layout.py); the retry rounds' cull dispatch is
// written by frame_retry.wgsl.
@group(0) @binding(1) var<storage, read_write> args: IndirectArgs;
@group(0) @binding(2) var<uniform> params: FinalizeParams;

// A dispatch of n workgroups in rows of ROW.
fn rows(n: u32) -> array<u32, 3> {
    return array<u32, 3>(min(n, ROW), (n + ROW - 1u) / ROW, 1u);
}

// After the cull: one workgroup per kept cluster.
@compute @workgroup_size(1)
fn after_cull() {
    let faces = counters[C_FACE_ITEMS];
    let edges = counters[C_EDGE_ITEMS];
    counters[C_MAX_FACE_ITEMS] = max(counters[C_MAX_FACE_ITEMS], faces);
    counters[C_MAX_EDGE_ITEMS] = max(counters[C_MAX_EDGE_ITEMS], edges);
    counters[C_TOTAL_FACE_ITEMS] += faces;
    counters[C_TOTAL_EDGE_ITEMS] += edges;
    args.clip = rows(min(faces, params.face_cap));
    args.edges = rows(min(edges, params.edge_cap));
}

// After the face clip: cut the faces it listed (one thread each). The cut list is as long as the
// triangle buffer, and the largest count of either sizes both: growing one grows the other. (A
// cut face nearly always yields a triangle, so this seldom grows the buffers more than needed.)
@compute @workgroup_size(1)
fn after_clip_faces() {
    let cuts = counters[C_CUTS];
    counters[C_MAX_TRIS] = max(counters[C_MAX_TRIS], cuts);
    args.cut = rows((min(cuts, params.tri_cap) + WORKGROUP - 1u) / WORKGROUP);
}

// After the cuts: draw every emitted triangle.
@compute @workgroup_size(1)
fn after_clip() {
    let tris = counters[C_TRIS];
    counters[C_MAX_TRIS] = max(counters[C_MAX_TRIS], tris);
    counters[C_TOTAL_TRIS] += tris;
    args.draw = array<u32, 4>(3u * min(tris, params.tri_cap), 1u, 0u, 0u);
}

// After the crossings: one thread per pixel with a listed crossing.
@compute @workgroup_size(1)
fn after_crossings() {
    _ = params.face_cap;  // the three entry points share one bind group layout
    args.surface = rows((counters[C_ACTIVE] + WORKGROUP - 1u) / WORKGROUP);
}

// After the edges are listed: test them (one thread each).
@compute @workgroup_size(1)
fn after_edge_list() {
    let listed = counters[C_EDGES];
    counters[C_MAX_EDGES] = max(counters[C_MAX_EDGES], listed);
    args.edge_test = rows((min(listed, params.list_cap) + WORKGROUP - 1u) / WORKGROUP);
}

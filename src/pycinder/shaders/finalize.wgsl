// Focused strategy: turn the counters of the last pass into indirect dispatch and draw arguments,
// clamped to what the buffers hold, and keep the largest counts for the host to size buffers.
//!include tiles.wgsl

struct Params {
    face_cap: u32,
    edge_cap: u32,
    tri_cap: u32,
    list_cap: u32,  // edges the edge list holds
};

@group(0) @binding(0) var<storage, read_write> counters: array<u32>;
// [0..3) face-clip dispatch, [3..6) edge-test dispatch, [6..10) draw (vertices, 1, 0, 0),
// [10..13) surface-test dispatch (WORKGROUP pixels per workgroup); [13..16) is the retry rounds'
// cull dispatch (retry.wgsl); [16..19) the cut dispatch; [19..22) the edge-test dispatch
@group(0) @binding(1) var<storage, read_write> args: array<u32>;
@group(0) @binding(2) var<uniform> params: Params;

fn rows(n: u32, at: u32) {
    args[at] = min(n, ROW);
    args[at + 1u] = (n + ROW - 1u) / ROW;
    args[at + 2u] = 1u;
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
    rows(min(faces, params.face_cap), 0u);
    rows(min(edges, params.edge_cap), 3u);
}

// After the face clip: cut the faces it listed (one thread each). The cut list is as long as the
// triangle buffer, and the largest count of either sizes both: growing one grows the other. (A
// cut face nearly always yields a triangle, so this seldom grows the buffers more than needed.)
@compute @workgroup_size(1)
fn after_clip_faces() {
    let cuts = counters[C_CUTS];
    counters[C_MAX_TRIS] = max(counters[C_MAX_TRIS], cuts);
    rows((min(cuts, params.tri_cap) + WORKGROUP - 1u) / WORKGROUP, 16u);
}

// After the cuts: draw every emitted triangle.
@compute @workgroup_size(1)
fn after_clip() {
    let tris = counters[C_TRIS];
    counters[C_MAX_TRIS] = max(counters[C_MAX_TRIS], tris);
    counters[C_TOTAL_TRIS] += tris;
    args[6] = 3u * min(tris, params.tri_cap);
    args[7] = 1u;
    args[8] = 0u;
    args[9] = 0u;
}

// After the crossings: one thread per pixel with a listed crossing.
@compute @workgroup_size(1)
fn after_crossings() {
    _ = params.face_cap;  // the three entry points share one bind group layout
    rows((counters[C_ACTIVE] + WORKGROUP - 1u) / WORKGROUP, 10u);
}

// After the edges are listed: test them (one thread each).
@compute @workgroup_size(1)
fn after_edge_list() {
    let listed = counters[C_EDGES];
    counters[C_MAX_EDGES] = max(counters[C_MAX_EDGES], listed);
    rows((min(listed, params.list_cap) + WORKGROUP - 1u) / WORKGROUP, 19u);
}

// Self-interference filter (paper 4.3.1.2), run on the GPU before anything is read back.
//
// A pixel survives when both ids are set and differ. Everything else is blanked:
//   r == 0           no edge inside a solid here
//   r != 0, g == 0   the count was non-zero but no single body claimed it (unidentified)
//   r == g           the body's edge was counted inside itself: self-interference
//
// counters: the FilterCounters of wholescene/filter.py (survivors, self-interference pixels
// blanked, unidentified pixels blanked, survivors that did not fit the compact buffer), indexed by
// the COUNT_* constants generated from that declaration, as is the FilterParams struct.
//
// Three outputs, one per entry point:
//   filter_full     writes the filtered image, one vec4u per pixel (readback "full")
//   filter_compact  appends each survivor as (pixel index, r << 16 | g, depth bits, payload)
//                   through an atomic counter (readback "compact", paper 4.3.2.4 made real)
//   filter_packed   writes the image with each pixel in the compact layout, zero where blanked,
//                   as level 0 of the mip-map reduction (readback "mipmap" and "adaptive")

@group(0) @binding(0) var records: texture_2d<u32>;
@group(0) @binding(1) var<storage, read_write> counters: array<atomic<u32>, COUNTER_WORDS>;
@group(0) @binding(2) var<storage, read_write> out_records: array<vec4u>;
@group(0) @binding(3) var<uniform> params: FilterParams;

// Returns the record if it survives, else zero, and counts what was blanked.
fn filtered(p: vec2u) -> vec4u {
    let rec = textureLoad(records, vec2i(p), 0);
    if (rec.r == 0u) {
        return vec4u(0u);
    }
    if (rec.g == 0u) {
        atomicAdd(&counters[COUNT_UNIDENTIFIED], 1u);
        return vec4u(0u);
    }
    if (rec.r == rec.g) {
        atomicAdd(&counters[COUNT_SELF_INTERFERENCE], 1u);
        return vec4u(0u);
    }
    return rec;
}

@compute @workgroup_size(WORKGROUP_SIDE, WORKGROUP_SIDE)
fn filter_full(@builtin(global_invocation_id) gid: vec3u) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let rec = filtered(gid.xy);
    if (rec.r != 0u) {
        atomicAdd(&counters[COUNT_SURVIVORS], 1u);
    }
    out_records[gid.y * params.width + gid.x] = rec;
}

@compute @workgroup_size(WORKGROUP_SIDE, WORKGROUP_SIDE)
fn filter_compact(@builtin(global_invocation_id) gid: vec3u) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let rec = filtered(gid.xy);
    if (rec.r == 0u) {
        return;
    }
    let slot = atomicAdd(&counters[COUNT_SURVIVORS], 1u);
    if (slot >= params.capacity) {
        atomicAdd(&counters[COUNT_OVERFLOW], 1u);
        return;
    }
    out_records[slot] = vec4u(gid.y * params.width + gid.x, (rec.r << 16u) | rec.g, rec.b, rec.a);
}

@compute @workgroup_size(WORKGROUP_SIDE, WORKGROUP_SIDE)
fn filter_packed(@builtin(global_invocation_id) gid: vec3u) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let rec = filtered(gid.xy);
    let i = gid.y * params.width + gid.x;
    if (rec.r == 0u) {
        out_records[i] = vec4u(0u);
        return;
    }
    atomicAdd(&counters[COUNT_SURVIVORS], 1u);
    out_records[i] = vec4u(i, (rec.r << 16u) | rec.g, rec.b, rec.a);
}

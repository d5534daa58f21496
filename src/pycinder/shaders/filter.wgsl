// Self-interference filter (paper 4.3.1.2), run on the GPU before anything is read back.
//
// A pixel survives when both ids are set and differ. Everything else is blanked:
//   r == 0           no edge inside a solid here
//   r != 0, g == 0   the count was non-zero but no single body claimed it (unidentified)
//   r == g           the body's edge was counted inside itself: self-interference
//
// counters[0] survivors, [1] self-interference pixels blanked, [2] unidentified pixels blanked,
// [3] survivors that did not fit the compact buffer (never non-zero: it holds every pixel).
//
// Three outputs, one per entry point:
//   filter_full     writes the filtered image, one vec4u per pixel (readback "full")
//   filter_compact  appends each survivor as (pixel index, r << 16 | g, depth bits, payload)
//                   through an atomic counter (readback "compact", paper 4.3.2.4 made real)
//   filter_packed   writes the image with each pixel in the compact layout, zero where blanked,
//                   as level 0 of the mip-map reduction (readback "mipmap" and "adaptive")

struct Params {
    width: u32,
    height: u32,
    capacity: u32,
    _pad: u32,
};

@group(0) @binding(0) var records: texture_2d<u32>;
@group(0) @binding(1) var<storage, read_write> counters: array<atomic<u32>, 4>;
@group(0) @binding(2) var<storage, read_write> out_records: array<vec4u>;
@group(0) @binding(3) var<uniform> params: Params;

// Returns the record if it survives, else zero, and counts what was blanked.
fn filtered(p: vec2u) -> vec4u {
    let rec = textureLoad(records, vec2i(p), 0);
    if (rec.r == 0u) {
        return vec4u(0u);
    }
    if (rec.g == 0u) {
        atomicAdd(&counters[2], 1u);
        return vec4u(0u);
    }
    if (rec.r == rec.g) {
        atomicAdd(&counters[1], 1u);
        return vec4u(0u);
    }
    return rec;
}

@compute @workgroup_size(8, 8)
fn filter_full(@builtin(global_invocation_id) gid: vec3u) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let rec = filtered(gid.xy);
    if (rec.r != 0u) {
        atomicAdd(&counters[0], 1u);
    }
    out_records[gid.y * params.width + gid.x] = rec;
}

@compute @workgroup_size(8, 8)
fn filter_compact(@builtin(global_invocation_id) gid: vec3u) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let rec = filtered(gid.xy);
    if (rec.r == 0u) {
        return;
    }
    let slot = atomicAdd(&counters[0], 1u);
    if (slot >= params.capacity) {
        atomicAdd(&counters[3], 1u);
        return;
    }
    out_records[slot] = vec4u(gid.y * params.width + gid.x, (rec.r << 16u) | rec.g, rec.b, rec.a);
}

@compute @workgroup_size(8, 8)
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
    atomicAdd(&counters[0], 1u);
    out_records[i] = vec4u(i, (rec.r << 16u) | rec.g, rec.b, rec.a);
}

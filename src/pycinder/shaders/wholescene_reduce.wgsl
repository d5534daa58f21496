// Mip-map reduction of the collision records (paper 4.3.2.2), with loss detection on the GPU.
//
// Each destination pixel keeps the "highest" of the (up to) four records of its 2x2 source block,
// ordered by the unordered pair they name, so blank pixels (key 0) always lose, as in the paper.
// Where two records naming different pairs meet in one block, one pair may be dropped: such
// blocks are counted in lost[level]. A level whose count is 0 kept every pair of the level
// before it; the adaptive mode reads back the deepest level with no loss at or above it (the
// paper's "colour to identify information loss", checked with a counter instead of a query).
//
// Records are in the compact layout (pixel index, r << 16 | g, depth bits, payload), so a record
// that survives keeps the pixel it came from.

// ReduceParams (one level: source and destination sizes, the level) is declared in Python
// (wholescene/reduce.py) and generated in front of this source.
@group(0) @binding(0) var<storage, read> src: array<vec4u>;
@group(0) @binding(1) var<storage, read_write> dst: array<vec4u>;
@group(0) @binding(2) var<storage, read_write> lost: array<atomic<u32>>;
@group(0) @binding(3) var<uniform> params: ReduceParams;

fn pair_key(rec: vec4u) -> u32 {
    let a = rec.y >> 16u;
    let b = rec.y & 0xFFFFu;
    return (min(a, b) << 16u) | max(a, b);
}

@compute @workgroup_size(WORKGROUP_SIDE, WORKGROUP_SIDE)
fn reduce(@builtin(global_invocation_id) gid: vec3u) {
    if (gid.x >= params.dst_width || gid.y >= params.dst_height) {
        return;
    }
    var best = vec4u(0u);
    var best_key = 0u;
    var mixed = false;
    for (var dy = 0u; dy < 2u; dy++) {
        for (var dx = 0u; dx < 2u; dx++) {
            let sx = 2u * gid.x + dx;
            let sy = 2u * gid.y + dy;
            if (sx < params.src_width && sy < params.src_height) {
                let rec = src[sy * params.src_width + sx];
                let key = pair_key(rec);
                if (key != 0u) {
                    if (best_key != 0u && key != best_key) {
                        mixed = true;
                    }
                    if (key > best_key) {
                        best = rec;
                        best_key = key;
                    }
                }
            }
        }
    }
    if (mixed) {
        atomicAdd(&lost[params.level], 1u);
    }
    dst[gid.y * params.dst_width + gid.x] = best;
}

// Broad phase, passes B4 and B5 (pycinder/focused/broad/b4_sort.py): the bitonic sort of the sort
// elements, in (within key, column, start, body) order.
//!include broad_common

@group(0) @binding(1) var<uniform> step: SortStep;
@group(0) @binding(2) var<storage, read_write> elements: array<vec4u>;

var<workgroup> block: array<vec4u, SORT_BLOCK>;

// B4: one workgroup per block of SORT_BLOCK elements: merges step.k to step.j (every step of
// each below SORT_BLOCK), in workgroup memory.
@compute @workgroup_size(SORT_THREADS)
fn sort_local(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let base = (wg.y * ROW + wg.x) * SORT_BLOCK;
    if (base >= params.count) {
        return;  // past the last block, in the last row of workgroups (uniform per workgroup)
    }
    block[lid] = elements[base + lid];
    block[lid + SORT_THREADS] = elements[base + lid + SORT_THREADS];
    workgroupBarrier();
    for (var k = step.k; k <= step.j; k <<= 1u) {
        for (var j = min(k >> 1u, SORT_THREADS); j > 0u; j >>= 1u) {
            let i = 2u * lid - (lid & (j - 1u));
            let ascending = ((base + i) & k) == 0u;
            let a = block[i];
            let b = block[i + j];
            if (before(b, a) == ascending) {
                block[i] = b;
                block[i + j] = a;
            }
            workgroupBarrier();
        }
    }
    elements[base + lid] = block[lid];
    elements[base + lid + SORT_THREADS] = block[lid + SORT_THREADS];
}

// B5: one compare-exchange per thread: step j of merge k, for j >= SORT_BLOCK.
@compute @workgroup_size(SORT_THREADS)
fn sort_step(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let t = thread_index(wg, lid, SORT_THREADS);
    if (t >= params.count / 2u) {
        return;
    }
    let j = step.j;
    let i = 2u * t - (t & (j - 1u));
    let ascending = (i & step.k) == 0u;
    let a = elements[i];
    let b = elements[i + j];
    if (before(b, a) == ascending) {
        elements[i] = b;
        elements[i + j] = a;
    }
}

// Focused strategy, decisions after the rounds: choose the tiles of the frame's retry rounds (run
// after the last round, in the same submission: one retry round per round of the frame, over the
// same atlas rows), and at the end of the frame count the tiles the host must still run again.
//
// A tile is run again, with lists four times longer, when some of its samples were undecided (a
// pixel listed more crossings than its list holds) and no tile of its pair found the pair: only
// then can its answer change. Its undecided count is cleared (the retry counts its own; counter
// C_UNDECIDED keeps every round's); its flag after the per-pair flags tells pass F1 to cull it
// again. A tile that pass F6 left unfinished at its loop budget is not run again here (longer
// lists cannot help it): it stays undecided for the host, which cuts its box. Tiles of pairs already
// found are never retried, so no record comes twice.
//!include tiles.wgsl
//!include stop.wgsl


@group(0) @binding(0) var<storage, read> tiles: array<Tile>;
// Per tile (found, undecided), per pair a hit flag, per tile a retry flag.
@group(0) @binding(1) var<storage, read_write> tile_counts: array<u32>;
@group(0) @binding(2) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(3) var<uniform> params: RetryParams;


@group(0) @binding(4) var<uniform> round: CullParams;  // the retry round's cull parameters
@group(0) @binding(5) var<storage, read_write> args: IndirectArgs;

@compute @workgroup_size(WORKGROUP)
fn select_retry(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (i >= params.tiles) {
        return;
    }
    let undecided = tile_counts[2u * i + 1u];
    let again = undecided > 0u && (undecided & UNDECIDED_BUDGET_BIT) == 0u
        && tile_counts[params.pair_offset + tiles[i].pair] == 0u && !frame_decided(tiles[i]);
    tile_counts[params.retry_offset + i] = select(0u, 1u, again);
    if (again) {
        tile_counts[2u * i + 1u] = 0u;
        atomicAdd(&counters[C_RETRY_TILES], 1u);
    }
}

// Before each retry round: its cull's indirect dispatch (args.retry_cull), or nothing when no tile
// is retried.
@compute @workgroup_size(1)
fn retry_args() {
    let groups = select(0u, (round.total + WORKGROUP - 1u) / WORKGROUP,
                        atomicLoad(&counters[C_RETRY_TILES]) > 0u);
    args.retry_cull = array<u32, 3>(min(groups, ROW), (groups + ROW - 1u) / ROW, 1u);
}

// At the end of the frame: count the tiles still undecided whose answer could change (their pair
// not found, or every tile wanted). None: the per-pair flags are the whole answer, and the host
// reads nothing per tile.
@compute @workgroup_size(WORKGROUP)
fn count_again(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = (wg.y * ROW + wg.x) * WORKGROUP + lid;
    if (i >= params.tiles) {
        return;
    }
    if (tile_counts[2u * i + 1u] > 0u && !frame_decided(tiles[i]) && (params.every_tile != 0u
            || tile_counts[params.pair_offset + tiles[i].pair] == 0u)) {
        atomicAdd(&counters[C_AGAIN], 1u);
    }
}

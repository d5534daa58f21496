// Focused strategy, decisions after the rounds: choose the tiles of the frame's retry rounds and
// lay them out in them (run after the last round, in the same submission), and at the end of the
// frame count the tiles the host must still run again.
//
// A tile is run again, with lists four times longer, when some of its samples were undecided (a
// pixel listed more crossings than its list holds) and no tile of its pair found the pair: only
// then can its answer change. A tile that pass F6 left unfinished at its loop budget is not run
// again here (longer lists cannot help it): it stays undecided for the host, which cuts its box.
// Tiles of pairs already found are never retried, so no record comes twice.
//
// The chosen tiles, from every round, are laid out anew in rows of their own, cut into the frame's
// `retry_rounds` retry rounds of `retry_rows` rows each. Each height class
// (plan_height_classes.wgsl's class_of) has its own shelves, the tallest class first (so each
// class's shelves start at a multiple of its height, and none crosses into the next retry round
// where `retry_rows` is a multiple of the tallest class, or a power of two at least as tall); a
// class's shelves are cut into slots as wide as its widest chosen tile, filled in tile order. Three
// dispatches, so that the layout is the same on every run (no atomic decides a place):
//   select_retry:  per tile, whether it is chosen; per workgroup, its chosen tiles of each class
//                  and the widest; per chosen tile, its rank among them;
//   retry_layout:  one thread: each workgroup's first rank in each class, each class's shelves,
//                  and the rows they need (counter C_RETRY_ROWS: the next frame's retry rounds
//                  are sized by it);
//   place_retry:   per chosen tile, its slot; a tile whose slot lies past the last retry round
//                  (or across two) is not chosen after all: it stays undecided, for the host.
// A placed tile's window moves to its slot in its retry round (the retry rounds read their tiles'
// windows; nothing after the frame's rounds reads the old ones), its undecided count is cleared
// (the retry counts its own; counter C_UNDECIDED keeps every round's), and its retry flag, the
// number of its retry round, tells pass F1 which round culls it; the tiles laid out are listed
// (in no set order) for pass F1's dispatch of each retry round.
//!include frame_tiles.wgsl
//!include frame_stop.wgsl
//!include plan_height_classes.wgsl


@group(0) @binding(0) var<storage, read_write> tiles: array<Tile>;
// Per tile (found, undecided), per pair a hit flag, per tile a retry flag, then the layout's words
// (per workgroup of select_retry GROUP_WORDS, then per class CLASS_WORDS), then the list of the
// tiles laid out.
@group(0) @binding(1) var<storage, read_write> tile_counts: array<u32>;
@group(0) @binding(2) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(3) var<uniform> params: RetryParams;


@group(0) @binding(4) var<uniform> round: CullParams;  // the retry round's cull parameters
@group(0) @binding(5) var<storage, read_write> args: IndirectArgs;

// CLASSES (5), GROUP_WORDS (per workgroup: [c] chosen | widest << 16, [8 + c] first rank) and
// CLASS_WORDS (per class: first row, slots per shelf, slot width) come from f7_f8_retry.py.

var<workgroup> chosen_class: array<u32, WORKGROUP>;  // 0: not chosen; else class + 1
var<workgroup> class_count: array<atomic<u32>, CLASSES>;
var<workgroup> class_widest: array<atomic<u32>, CLASSES>;

fn group_of(wg: vec3u) -> u32 {
    return wg.y * ROW + wg.x;
}

@compute @workgroup_size(WORKGROUP)
fn select_retry(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = group_of(wg) * WORKGROUP + lid;
    if (lid < CLASSES) {
        atomicStore(&class_count[lid], 0u);
        atomicStore(&class_widest[lid], 0u);
    }
    var chosen = 0u;
    var width = 0u;
    if (i < params.tiles) {
        let t = tiles[i];
        let undecided = tile_counts[2u * i + 1u];
        let again = undecided > 0u && (undecided & UNDECIDED_BUDGET_BIT) == 0u
            && tile_counts[params.pair_offset + t.pair] == 0u && !frame_decided(t);
        tile_counts[params.retry_offset + i] = 0u;
        if (again) {
            chosen = class_of(t.window.w) + 1u;
            width = t.window.z;
        }
    }
    chosen_class[lid] = chosen;
    workgroupBarrier();
    if (chosen != 0u) {
        atomicAdd(&counters[C_RETRY_CHOSEN], 1u);
        atomicAdd(&class_count[chosen - 1u], 1u);
        atomicMax(&class_widest[chosen - 1u], width);
        var rank = 0u;  // among the workgroup's chosen tiles of its class
        for (var k = 0u; k < lid; k++) {
            rank += select(0u, 1u, chosen_class[k] == chosen);
        }
        tile_counts[params.retry_offset + i] = chosen | (rank << 8u);
    }
    workgroupBarrier();
    if (lid < CLASSES && group_of(wg) < params.groups) {
        tile_counts[params.group_offset + GROUP_WORDS * group_of(wg) + lid] =
            atomicLoad(&class_count[lid]) | (atomicLoad(&class_widest[lid]) << 16u);
    }
}

@compute @workgroup_size(1)
fn retry_layout() {
    var row = 0u;
    for (var k = 0u; k < CLASSES; k++) {
        let c = CLASSES - 1u - k;  // the tallest class first
        var chosen = 0u;
        var widest = 1u;
        for (var g = 0u; g < params.groups; g++) {
            let at = params.group_offset + GROUP_WORDS * g;
            let word = tile_counts[at + c];
            tile_counts[at + 8u + c] = chosen;
            chosen += word & 0xFFFFu;
            widest = max(widest, word >> 16u);
        }
        let per_shelf = max(params.atlas_width / widest, 1u);
        let at = params.layout_offset + CLASS_WORDS * c;
        tile_counts[at] = row;
        tile_counts[at + 1u] = per_shelf;
        tile_counts[at + 2u] = widest;
        row += (chosen + per_shelf - 1u) / per_shelf * class_rows(c);
    }
    atomicStore(&counters[C_RETRY_ROWS], row);
}

@compute @workgroup_size(WORKGROUP)
fn place_retry(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = group_of(wg) * WORKGROUP + lid;
    if (i >= params.tiles) {
        return;
    }
    let word = tile_counts[params.retry_offset + i];
    if (word == 0u) {
        return;
    }
    let c = (word & 0xFFu) - 1u;
    let first = tile_counts[params.group_offset + GROUP_WORDS * group_of(wg) + 8u + c];
    let rank = first + (word >> 8u);
    let at = params.layout_offset + CLASS_WORDS * c;
    let per_shelf = tile_counts[at + 1u];
    let row = tile_counts[at] + rank / per_shelf * class_rows(c);
    let retry_round = row / params.retry_rows;
    let local_row = row % params.retry_rows;
    if (retry_round >= params.retry_rounds || local_row + class_rows(c) > params.retry_rows) {
        tile_counts[params.retry_offset + i] = 0u;  // no room: left undecided, for the host
        return;
    }
    let window = tiles[i].window;
    tiles[i].window = vec4u(rank % per_shelf * tile_counts[at + 2u], local_row, window.z,
                            window.w);
    tile_counts[params.retry_offset + i] = retry_round + 1u;
    tile_counts[2u * i + 1u] = 0u;
    tile_counts[params.list_offset + atomicAdd(&counters[C_RETRY_TILES], 1u)] = i;
}

// Before each retry round: its cull's indirect dispatch (args.retry_cull: a workgroup per side of
// every tile laid out, frame_cull.wgsl's cull_retry), or nothing when no tile is laid out in it.
@compute @workgroup_size(1)
fn retry_args() {
    let listed = atomicLoad(&counters[C_RETRY_TILES]);
    let used = listed > 0u && round.retry_row < atomicLoad(&counters[C_RETRY_ROWS]);
    let groups = select(0u, 2u * listed, used);
    args.retry_cull = array<u32, 3>(min(groups, ROW), (groups + ROW - 1u) / ROW, 1u);
}

// At the end of the frame: count the tiles still undecided whose answer could change (their pair
// not found, or every tile wanted). None: the per-pair flags are the whole answer, and the host
// reads nothing per tile.
@compute @workgroup_size(WORKGROUP)
fn count_again(@builtin(workgroup_id) wg: vec3u, @builtin(local_invocation_index) lid: u32) {
    let i = group_of(wg) * WORKGROUP + lid;
    if (i >= params.tiles) {
        return;
    }
    if (tile_counts[2u * i + 1u] > 0u && !frame_decided(tiles[i]) && (params.every_tile != 0u
            || tile_counts[params.pair_offset + tiles[i].pair] == 0u)) {
        atomicAdd(&counters[C_AGAIN], 1u);
    }
}

// The tiles' height classes (HEIGHT_CLASSES in pycinder/focused/plan/plan_numpy.py, five of them,
// as constants CLASS_ROWS_0..4): shared by the planner's atlas (plan_atlas.wgsl) and the retry
// rounds' layout (frame_retry.wgsl). Included with //!include plan_height_classes.wgsl.

// The height class of a tile h pixels tall: the smallest class that holds it (searchsorted).
fn class_of(h: u32) -> u32 {
    if (h <= CLASS_ROWS_0) { return 0u; }
    if (h <= CLASS_ROWS_1) { return 1u; }
    if (h <= CLASS_ROWS_2) { return 2u; }
    if (h <= CLASS_ROWS_3) { return 3u; }
    return 4u;
}

fn class_rows(c: u32) -> u32 {
    switch c {
        case 0u: { return CLASS_ROWS_0; }
        case 1u: { return CLASS_ROWS_1; }
        case 2u: { return CLASS_ROWS_2; }
        case 3u: { return CLASS_ROWS_3; }
        default: { return CLASS_ROWS_4; }
    }
}

// Reading the per-pixel crossings of pass F3 (included by passes F4 and F5, which declare the
// `pixels` and `crossings` bindings).

// A body's winding outside the box, from the pixel's packed word (body a: low 16 bits, b: high).
fn winding_outside(packed: u32, side: u32) -> i32 {
    let lo = i32(packed << 16u) >> 16u;                  // the low half, sign-extended
    if (side == 0u) {
        return lo;
    }
    let rest = (packed - u32(lo)) >> 16u;                 // the high half, once the low is taken off
    return i32(rest << 16u) >> 16u;
}

// The winding number of body `side` at depth z (pixels from the box's near side) on the ray of a
// pixel centre: its winding outside the box, plus its listed crossings between z and the
// counting side (front faces +1 and back faces -1 in front of z; the opposite behind it).
// Non-zero: the point is inside the body.
fn winding_at(pixel: u32, listed: u32, capacity: u32, side: u32, z: f32, back: bool) -> i32 {
    var winding = winding_outside(pixels[3u * pixel + 1u], side);
    for (var k = 0u; k < listed; k++) {
        let entry = crossings[pixel * capacity + k].x;
        if ((entry & 1u) != side) {
            continue;
        }
        let ze = bitcast<f32>(entry & 0xFFFFFFFCu);
        let front = (entry & 2u) != 0u;
        if (!back && ze < z) {
            winding += select(-1, 1, front);
        } else if (back && ze > z) {
            winding += select(1, -1, front);
        }
    }
    return winding;
}

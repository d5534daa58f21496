// A frame that asks only whether anything collides (its tiles carry FLAG_STOP_AT_FIRST) stops
// once any pair is found: included after frame_tiles.wgsl by the shaders that declare `counters`.

// Whether tile `t` is of such a frame, and a pair of it was found.
fn frame_decided(t: Tile) -> bool {
    return (t.flags & FLAG_STOP_AT_FIRST) != 0u && atomicLoad(&counters[C_FOUND]) != 0u;
}

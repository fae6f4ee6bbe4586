// The dilation's offset codes (compute_raster_fill.wgsl's scatter writes them, its resolve and
// the display through the winners read them): the offset of the covering pixel from the covered
// one, in dilate_main's scan order over the window (rows, then columns), the pixel itself first
// (code 0), 8 bits a coordinate (radius <= 127) so that a reader needs no radius.
fn dilate_offset_code(dx: i32, dy: i32) -> u32 {
  if (dx == 0 && dy == 0) {
    return 0u;
  }
  return u32((dy + 128) * 256 + dx + 128) + 1u;
}

// The offset (dx, dy) of a code other than 0.
fn dilate_offset_of(code: u32) -> vec2<i32> {
  return vec2<i32>(i32((code - 1u) % 256u), i32((code - 1u) / 256u)) - 128;
}

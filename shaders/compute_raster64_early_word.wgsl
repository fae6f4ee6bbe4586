// The 64-bit pass's early depth test on the depth word (compute_raster64_pass.wgsl): the key's
// depth against the pixel's depth, read through a 32-bit view of the visibility buffer (plain or
// atomic: depth_word), since only min and max are allowed on its 64-bit atomics.
alias Early = u32;

fn early_value(pixel: u32) -> u32 {
  return depth_word(pixel);
}

// Whether `key` cannot lower the pixel's key whose depth word is `early`.
fn early_hidden(key: u64, early: u32) -> bool {
  return key_depth(key) > early;
}

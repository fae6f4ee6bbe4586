// The 32-bit depth passes' early-test load (depth_word) as an atomic load: a plain view of the
// depth buffer would alias its writable binding, which Dawn (and so browsers) refuses.
fn depth_word(pixel: u32) -> u32 {
  return atomicLoad(&depth_buffer[pixel]);
}

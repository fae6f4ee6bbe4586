// The 32-bit depth passes' early-test load (depth_word) as a plain load of a second, non-atomic
// binding of the depth buffer, as the 64-bit pass reads it (wgpu-native allows the aliasing,
// Dawn does not). On the H200 the atomic load made the 32-bit depth pass 1.24x slower
// (bench/RESULTS.md, run AB).
@group(0) @binding(8) var<storage, read_write> depth_plain: array<u32>;

fn depth_word(pixel: u32) -> u32 {
  return depth_plain[pixel];
}

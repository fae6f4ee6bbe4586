// Compute rasterizer, depth pass with a 64-bit visibility buffer (seed 001, sections 3.2-3.4):
// one workgroup per batch culls it against the frustum and picks the precision from its size on
// screen (compute_raster_batch.wgsl), and its threads project the batch's points, keeping the
// nearest per pixel with a 64-bit atomicMin of (depth << 32 | point index): the smallest depth,
// then the lowest index, so the image does not depend on the order the threads run in. The
// resolve pass (compute_raster_resolve.wgsl) then colours each pixel's point. Needs
// ShaderInt64AtomicMinMax (wgpu-native).
#include "compute_raster_batch.wgsl"
#include "compute_raster_counted.wgsl"

@group(0) @binding(5) var<storage, read_write> visibility: array<atomic<u64>>;
// The same buffer as plain 32-bit words for the early depth test, as seed 001's Listing 1 reads
// it: only min and max are allowed on 64-bit atomics, and an atomic load would bypass the L1
// that a plain load hits (1.25x slower on the H200: bench/RESULTS.md, runs AA-AB). wgpu-native
// allows the aliasing.
@group(0) @binding(8) var<storage, read_write> visibility_plain: array<u32>;

alias Key = u64;

fn point_key(depth: u32, index: u32) -> u64 {
  return (u64(depth) << 32u) | u64(params.segment_base + index);
}

fn write_key(pixel: u32, key: u64) {
  // The ablations' writes stay behind conditions that never hold, to keep the work alive.
  if (ablated(ABLATE_WRITE)) {
    if (key == u64(0u)) {
      atomicMin(&visibility[pixel], key);
    }
    return;
  }
  // Early depth test on the depth (high) word: a key whose depth is above the pixel's cannot
  // lower it (a tie in depth may, by its index).
  if (!ablated(ABLATE_EARLY) && u32(key >> 32u) > visibility_plain[pixel * 2u + 1u]) {
    return;
  }
  if (ablated(ABLATE_ATOMIC) && key != u64(0u)) {
    return;
  }
  atomicMin(&visibility[pixel], key);
}

#include "compute_raster_write.wgsl"

// Compute rasterizer, depth pass with a 64-bit visibility buffer held as atomic<vec2u>: the
// WebGPU feature "atomic-vec2u-min-max" (WGSL `atomic_vec2u_min_max`), which browsers offer
// where the GPU has 64-bit atomics (Chromium on Vulkan with shaderBufferInt64Atomics). The key is
// compute_raster64.wgsl's, depth in the more significant word (y), the point index in x: the same
// 8 bytes in memory, so the resolve pass and everything after it read it unchanged. The feature
// allows only atomicStoreMin/Max, no load, and a second plain binding of the buffer (the 64-bit
// pass's early test) is refused by browsers as aliasing: this pass has no early depth test.
enable atomic_vec2u_min_max;

#include "compute_raster_batch.wgsl"
#include "compute_raster_counted.wgsl"

@group(0) @binding(5) var<storage, read_write> visibility: array<atomic<vec2u>>;

alias Key = vec2u;

fn point_key(depth: u32, index: u32) -> vec2u {
  return vec2u(params.segment_base + index, depth);
}

fn write_key(pixel: u32, key: vec2u) {
  // The ablations' writes stay behind conditions that never hold, to keep the work alive.
  if (ablated(ABLATE_WRITE)) {
    if (all(key == vec2u(0u))) {
      atomicStoreMin(&visibility[pixel], key);
    }
    return;
  }
  if (ablated(ABLATE_ATOMIC) && any(key != vec2u(0u))) {
    return;
  }
  atomicStoreMin(&visibility[pixel], key);
}

#include "compute_raster_write.wgsl"

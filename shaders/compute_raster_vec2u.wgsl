// Compute rasterizer, depth pass with a 64-bit visibility buffer held as atomic<vec2u>: the
// WebGPU feature "atomic-vec2u-min-max" (WGSL `atomic_vec2u_min_max`), which browsers offer
// where the GPU has 64-bit atomics (Chromium on Vulkan with shaderBufferInt64Atomics). The key is
// compute_raster64.wgsl's, depth in the more significant word (y), the point index in x: the same
// 8 bytes in memory, so the resolve pass and everything after it read it unchanged. The feature
// allows only atomicStoreMin/Max, no load, and a second plain binding of the buffer (the 64-bit
// pass's early test) is refused by browsers as aliasing: the early depth test reads a buffer of
// its own instead (depth_hint).
enable atomic_vec2u_min_max;

#include "compute_raster_batch.wgsl"
#include "compute_raster_counted.wgsl"

@group(0) @binding(5) var<storage, read_write> visibility: array<atomic<vec2u>>;
// The early depth test's depth per pixel, kept beside the visibility buffer: the bitwise
// complement of the smallest depth written there so far (0, cleared with clearBuffer: none).
// Each write updates it after the visibility buffer, so it is never nearer than what that
// holds: a point deeper than it cannot win.
@group(0) @binding(8) var<storage, read_write> depth_hint: array<atomic<u32>>;

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
  let early = !ablated(ABLATE_EARLY);
  var nearest = 0xffffffffu;
  if (early) {
    // A key whose depth is above the pixel's cannot lower it (a tie in depth may, by its index).
    nearest = ~atomicLoad(&depth_hint[pixel]);
    if (key.y > nearest) {
      return;
    }
  }
  if (ablated(ABLATE_ATOMIC) && any(key != vec2u(0u))) {
    return;
  }
  atomicStoreMin(&visibility[pixel], key);
  if (early && key.y < nearest) {
    atomicMax(&depth_hint[pixel], ~key.y);
  }
}

#include "compute_raster_write.wgsl"

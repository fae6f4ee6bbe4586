// Compute rasterizer fallback without 64-bit atomics (seed 003, section 4.2), its depth pass: as
// compute_raster64.wgsl, but the nearest depth per pixel is kept with a 32-bit atomicMin, and
// the colours follow in a second pass over the points (compute_raster_accumulate.wgsl: the
// points at that depth add their colours). Where the device allows, the winner events
// (compute_raster_depth32_events_pass.wgsl) stand in for that second pass. The including shader
// (compute_raster_depth32 or _depth32_plain.wgsl) defines depth_word(pixel), the early test's
// load.
#include "compute_raster_batch.wgsl"
#include "compute_raster_counted.wgsl"

@group(0) @binding(5) var<storage, read_write> depth_buffer: array<atomic<u32>>;

alias Key = u32;

fn point_key(depth: u32, index: u32) -> u32 {
  return depth;
}

fn write_key(pixel: u32, depth: u32) {
  if (!ablated(ABLATE_EARLY) && depth >= depth_word(pixel)) {
    return;
  }
  atomicMin(&depth_buffer[pixel], depth);
}

#include "compute_raster_write.wgsl"

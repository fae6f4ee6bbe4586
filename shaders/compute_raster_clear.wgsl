// Clears the depth/visibility buffer to "empty" (all ones: the largest depth) and the
// accumulation buffer to zero.
#include "compute_raster_common.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> depth_buffer: array<u32>;
@group(0) @binding(2) var<storage, read_write> accum: array<vec4<u32>>;

// CLEAR_ACCUM off: the accumulation buffer is left alone (the 64-bit path without HQS, whose
// resolve pass writes every pixel of it).
override CLEAR_ACCUM: bool = true;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= params.width || id.y >= params.height) {
    return;
  }
  let pixel = id.y * params.width + id.x;
  for (var k = 0u; k < params.depth_stride; k++) {
    depth_buffer[pixel * params.depth_stride + k] = 0xffffffffu;
  }
  if (CLEAR_ACCUM) {
    accum[pixel] = vec4<u32>(0u);
  }
}

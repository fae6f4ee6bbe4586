// After the packed accumulation (compute_raster_accumulate.wgsl, PACKED): each pixel's packed
// sums and its overflow sums become the plain layout (r, g, b, count) the later passes read.
#include "compute_raster_common.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> packed: array<vec4<u32>>;  // two per pixel
@group(0) @binding(2) var<storage, read_write> accum: array<vec4<u32>>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= params.width || id.y >= params.height) {
    return;
  }
  let pixel = id.y * params.width + id.x;
  let a = packed[pixel * 2u];
  let overflow = packed[pixel * 2u + 1u];
  accum[pixel] = vec4<u32>(a.x & 0xffffu, a.x >> 16u, a.y & 0xffffu, a.y >> 16u) +
                 vec4<u32>(a.z, a.w, overflow.x, overflow.y);
}

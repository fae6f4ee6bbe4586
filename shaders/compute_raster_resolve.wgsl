// Visibility buffer resolve (seed 001, section 3.3): the point index of each pixel's nearest
// point becomes its colour; only visible points' colours are read. Runs once per segment, each
// resolving the pixels whose point it holds. Writes the accumulation layout (sum, count = 1) so
// one display pass serves every variant.
#include "compute_raster_common.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> visibility: array<u32>;
@group(0) @binding(2) var<storage, read> colors: array<u32>;
@group(0) @binding(3) var<storage, read_write> accum: array<u32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= params.width || id.y >= params.height) {
    return;
  }
  let pixel = id.y * params.width + id.x;
  if (visibility[pixel * 2u + 1u] == 0xffffffffu) {
    return;  // empty
  }
  let local_index = visibility[pixel * 2u] - params.segment_base;  // wraps when below
  if (local_index >= params.segment_points) {
    return;
  }
  let rgba = colors[local_index];
  let o = pixel * 4u;
  accum[o] = rgba & 255u;
  accum[o + 1u] = (rgba >> 8u) & 255u;
  accum[o + 2u] = (rgba >> 16u) & 255u;
  accum[o + 3u] = 1u;
}

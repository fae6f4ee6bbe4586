// Visibility buffer resolve (seed 001, section 3.3): the point index of each pixel's nearest
// point becomes its colour; only visible points' words are read. Runs once per segment, each
// resolving the pixels whose point it holds. The elevation mode needs the point's height: its
// batch is found by binary search in the segment's batch table (sorted by first index) and the
// point dequantized at full precision, as the billboard path colours the exact position (a ray
// through the pixel centre would favour the near half of each pixel). Writes the accumulation
// layout (sum, count = 1) so one display pass serves every variant. Hidden points never got
// here (the geometry pass dropped them); highlighted ones are tinted.
#include "compute_raster_common.wgsl"
#include "compute_raster_shading.wgsl"
#include "compute_raster_filter.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> visibility: array<u32>;
@group(0) @binding(2) var<storage, read> colors: array<u32>;
@group(0) @binding(3) var<storage, read_write> accum: array<vec4<u32>>;  // r, g, b, count

@group(0) @binding(4) var<storage, read> batches: array<GpuBatch>;
@group(0) @binding(5) var<storage, read> coarse: array<vec4<u32>>;  // four points a word
@group(0) @binding(6) var<storage, read> medium: array<vec4<u32>>;
@group(0) @binding(7) var<storage, read> fine: array<vec4<u32>>;

// Camera-relative position of point `index` of this segment (30 bits per axis).
fn point_position(index: u32) -> vec3<f32> {
  var lo = 0u;
  var hi = params.batch_count;  // the batch holding index is the last with first <= index
  while (hi - lo > 1u) {
    let mid = (lo + hi) / 2u;
    if (batches[mid].first <= index) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  let b = batches[lo];
  let v = index >> 2u;
  let k = index & 3u;
  return b.offset + box_fraction(30u, coarse[v][k], medium[v][k], fine[v][k]) * b.size;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= params.width || id.y >= params.height) {
    return;
  }
  let pixel = id.y * params.width + id.x;
  let depth_bits = visibility[pixel * 2u + 1u];
  let local_index = visibility[pixel * 2u] - params.segment_base;  // wraps when below
  if (depth_bits == 0xffffffffu || local_index >= params.segment_points) {
    // Empty, or another segment's point: the first segment's dispatch writes the empty pixel
    // (the clear pass leaves this buffer alone), a later segment's overwrites it.
    if (params.segment_base == 0u) {
      accum[pixel] = vec4<u32>(0u);
    }
    return;
  }
  // Highlight needs the position too: is the visible point inside the clip region?
  let highlight = (filters.flags & 4u) != 0u && filters.clip_mode == 2u;
  var position = vec3<f32>(0.0);
  if ((shading.mode == 4u || highlight) && params.batch_count > 0u) {
    position = point_position(local_index);
  }
  var color = shade(colors[local_index], attributes_of(local_index), position.y);
  if (highlight && params.batch_count > 0u && clip_state(position) == 2u) {
    color = highlighted(color);
  }
  let c = channels(color);
  accum[pixel] = vec4<u32>(c, 1u);
}

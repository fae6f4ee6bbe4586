// Filters and clip regions in the compute rasterizer's passes (point_filter.wgsl): the geometry
// passes drop hidden points before they reach the depth test, the colour passes skip them and
// tint the highlighted ones. GPS-time and point-source filters are the billboard path's (the
// batches hold no extras).
#include "compute_raster_attributes.wgsl"
#include "point_filter.wgsl"

@group(0) @binding(11) var<uniform> filters: Filter;
@group(0) @binding(12) var<storage, read> polygon_vertices: array<vec2<f32>>;

// 0: hidden, 1: shown, 2: shown highlighted; `index` is the point's index in its segment,
// `rel` its camera-relative position.
fn raster_filter(index: u32, rel: vec3<f32>) -> u32 {
  if (filters.flags == 0u) {
    return 1u;
  }
  if ((filters.flags & 1u) != 0u && !attributes_pass(attributes[index])) {
    return 0u;
  }
  return clip_state(rel);
}

fn highlighted(c: vec3<f32>) -> vec3<f32> {
  return mix(c, filters.highlight.rgb, filters.highlight.a);
}

// Display pass (seed 003, section 4.4): a full-screen triangle divides each pixel's colour sums
// by its count; empty pixels show the background.
#include "compute_raster_common.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> accum: array<vec4<u32>>;

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
  let uv = vec2<f32>(f32((vertex << 1u) & 2u), f32(vertex & 2u));
  return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
  let a = accum[u32(frag.y) * params.width + u32(frag.x)];
  if (a.w == 0u) {
    return vec4<f32>(params.background.rgb, 1.0);
  }
  return vec4<f32>(vec3<f32>(a.xyz) / (f32(a.w) * 255.0), 1.0);
}

// Display pass (seed 003, section 4.4) as a full-screen triangle, for targets a compute pass
// cannot write (compute_raster_display_cs_pass.wgsl is the other form): see display_color.
// Included by compute_raster_display.wgsl and _display_translucent.wgsl.
#include "compute_raster_display_common.wgsl"

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
  let uv = vec2<f32>(f32((vertex << 1u) & 2u), f32(vertex & 2u));
  return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
  return display_color(vec2<i32>(frag.xy));
}

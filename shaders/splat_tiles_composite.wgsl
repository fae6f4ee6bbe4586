// Lays the tile rasterizer's splats over the frame: (colour, 1 - T) per pixel, blended with
// one, one minus source alpha (the splats are premultiplied).
#include "splat_common.wgsl"

@group(0) @binding(0) var<uniform> frame: SplatFrame;
@group(0) @binding(1) var<storage, read> splat_pixels: array<vec4<f32>>;

@vertex
fn vs_fullscreen(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
  let uv = vec2<f32>(f32((vertex << 1u) & 2u), f32(vertex & 2u));
  return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_composite(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
  let p = vec2<u32>(position.xy);
  return splat_pixels[p.y * u32(frame.viewport.x) + p.x];
}

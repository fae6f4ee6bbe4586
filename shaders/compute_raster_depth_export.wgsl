// The compute rasterizer's depth as a reverse-Z depth texture for later passes of the frame
// (splats test against it): per pixel, the nearest point's view distance from the depth buffer
// the display reads, as near / distance (the billboard path's depth); no point: 0 (far).
#include "compute_raster_common.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> depth_buffer: array<u32>;

const NO_DEPTH: u32 = 0xffffffffu;
// WINNER: the buffer holds the dilation's winners (compute_raster_display_common.wgsl's WINNER).
override WINNER: bool = false;

@vertex
fn vs_fullscreen(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
  let uv = vec2<f32>(f32((vertex << 1u) & 2u), f32(vertex & 2u));
  return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_depth(@builtin(position) position: vec4<f32>) -> @builtin(frag_depth) f32 {
  let xy = vec2<u32>(position.xy);
  let pixel = xy.y * params.width + xy.x;
  var word: u32;
  if (WINNER) {
    word = ~depth_buffer[2u * pixel];  // none (0) reads as NO_DEPTH
  } else {
    word = depth_buffer[pixel * params.depth_stride + params.depth_word];
  }
  if (word == NO_DEPTH) {
    return 0.0;
  }
  // view_proj is the projection times a rotation: its last column is the projection's,
  // (0, 0, near, 0).
  return clamp(params.view_proj[3][2] / bitcast<f32>(word), 0.0, 1.0);
}

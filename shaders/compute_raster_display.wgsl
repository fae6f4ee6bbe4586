// Display pass (seed 003, section 4.4): a full-screen triangle divides each pixel's colour sums
// by its count; empty pixels show the background. With edl_strength > 0 it also applies
// eye-dome lighting (seed 000, eqs. 10-12) from the nearest depths of the pixel and of eight
// neighbours at edl_radius; pixels without a depth of their own (filled holes) and empty
// neighbours give no response.
#include "compute_raster_common.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> accum: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> depth_buffer: array<u32>;

const NO_DEPTH: u32 = 0xffffffffu;  // what the clear pass leaves

fn depth_word_of(pixel: u32) -> u32 {
  return depth_buffer[pixel * params.depth_stride + params.depth_word];
}

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
  let uv = vec2<f32>(f32((vertex << 1u) & 2u), f32(vertex & 2u));
  return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
  let pixel = u32(frag.y) * params.width + u32(frag.x);
  let a = accum[pixel];
  if (a.w == 0u) {
    return vec4<f32>(params.background.rgb, 1.0);
  }
  var color = vec3<f32>(a.xyz) / (f32(a.w) * 255.0);
  let own = depth_word_of(pixel);
  if (params.edl_strength > 0.0 && own != NO_DEPTH) {
    let log_c = log2(bitcast<f32>(own));
    let size = vec2<i32>(i32(params.width), i32(params.height));
    var response = 0.0;
    for (var i = 0u; i < 8u; i++) {
      let angle = f32(i) * 0.78539816;
      let offset = vec2<i32>(round(vec2<f32>(cos(angle), sin(angle)) * params.edl_radius));
      let q = clamp(vec2<i32>(frag.xy) + offset, vec2<i32>(0), size - 1);
      let w = depth_word_of(u32(q.y) * params.width + u32(q.x));
      if (w != NO_DEPTH) {
        response += max(0.0, log_c - log2(bitcast<f32>(w)));  // eq. 10
      }
    }
    color *= exp(-(response / 8.0) * params.edl_strength);  // eqs. 11-12
  }
  return vec4<f32>(color, 1.0);
}

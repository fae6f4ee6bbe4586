// The display pass's shading, shared by its fragment form (compute_raster_display_fs.wgsl) and
// its compute form (compute_raster_display_cs_pass.wgsl): each pixel's colour sums divided by its
// count, the background where nothing was drawn, and with edl_strength > 0 eye-dome lighting
// (seed 000, eqs. 10-12) from the nearest depths of the pixel and of eight neighbours at
// edl_radius; pixels without a depth of their own (filled holes) and empty neighbours give no
// response. The including shader defines over_translucent(pixel, colour): the colour itself
// (compute_raster_display_opaque.wgsl), or the translucent points laid over it
// (compute_raster_display_oit.wgsl).
#include "compute_raster_common.wgsl"
#include "compute_raster_dilate_code.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> accum: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> depth_buffer: array<u32>;

const NO_DEPTH: u32 = 0xffffffffu;  // what the clear pass leaves

// WINNER: the points were dilated by scatter and not resolved (compute_raster_fill.wgsl):
// `depth_buffer` holds the dilation's winners, two words a pixel (the nearest covering depth and
// the covering pixel's offset code, each complemented, 0 for none), and `accum` the sums before
// dilation; each pixel reads its colour from the pixel that covers it. The same image as the
// resolve pass's buffers, one full-screen pass fewer (for CPU adapters: on SwiftShader ~40 ms at
// 1280x720).
override WINNER: bool = false;

fn depth_word_of(pixel: u32) -> u32 {
  if (WINNER) {
    return ~depth_buffer[2u * pixel];  // none (0) reads as NO_DEPTH
  }
  return depth_buffer[pixel * params.depth_stride + params.depth_word];
}

// The colour sums shown at the pixel: its own, or with WINNER those of the pixel covering it.
fn sums_of(xy: vec2<i32>, pixel: u32) -> vec4<u32> {
  if (WINNER && depth_buffer[2u * pixel] != 0u) {
    let code = ~depth_buffer[2u * pixel + 1u];
    if (code != 0u) {
      let source = xy + dilate_offset_of(code);
      return accum[u32(source.y) * params.width + u32(source.x)];
    }
  }
  return accum[pixel];
}

fn display_color(xy: vec2<i32>) -> vec4<f32> {
  let pixel = u32(xy.y) * params.width + u32(xy.x);
  return vec4<f32>(over_translucent(pixel, opaque_color(xy, pixel)), 1.0);
}

// The opaque points' colour at the pixel (EDL included), or the background.
fn opaque_color(xy: vec2<i32>, pixel: u32) -> vec3<f32> {
  let a = sums_of(xy, pixel);
  if (a.w == 0u) {
    return background_at(params.sky, params.background.rgb, vec2<f32>(xy) + 0.5);
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
      let q = clamp(xy + offset, vec2<i32>(0), size - 1);
      let w = depth_word_of(u32(q.y) * params.width + u32(q.x));
      if (w != NO_DEPTH) {
        response += max(0.0, log_c - log2(bitcast<f32>(w)));  // eq. 10
      }
    }
    color *= exp(-(response / 8.0) * params.edl_strength);  // eqs. 11-12
  }
  return color;
}

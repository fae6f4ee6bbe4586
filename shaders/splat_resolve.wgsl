// Full-screen resolve: normalisation of the accumulated splats (sum of weighted colours / sum of
// weights; naive passes write weight 1) merged with eye-dome lighting (seed 000, eqs. 10-12).
#include "point_common.wgsl"

@group(1) @binding(0) var accumulated: texture_2d<f32>;
@group(1) @binding(1) var depth: texture_depth_2d;

@vertex
fn vs_fullscreen(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
  let uv = vec2<f32>(f32((vertex << 1u) & 2u), f32(vertex & 2u));
  return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

// Reverse Z with an infinite far plane: depth = near / z, so z = near / depth.
fn linear_depth(d: f32) -> f32 {
  return frame.near / d;
}

@fragment
fn fs_resolve(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
  let p = vec2<i32>(position.xy);
  let sum = textureLoad(accumulated, p, 0);
  let d = textureLoad(depth, p, 0);
  if (sum.a <= 0.0 || d <= 0.0) {
    // Background stays background: the plain colour, or the sky.
    return vec4<f32>(background_at(frame.sky, frame.background.rgb, position.xy), 1.0);
  }
  var color = sum.rgb / sum.a;
  if (frame.edl_enabled != 0u) {
    let size = vec2<i32>(textureDimensions(depth));
    let log_c = log2(linear_depth(d));
    var response = 0.0;
    for (var i = 0u; i < 8u; i = i + 1u) {
      let angle = f32(i) * 0.78539816;
      let offset = vec2<i32>(round(vec2<f32>(cos(angle), sin(angle)) * frame.edl_radius));
      let q = clamp(p + offset, vec2<i32>(0), size - 1);
      let di = textureLoad(depth, q, 0);
      // Eq. 10; a background neighbour (no depth) is infinitely far: no response.
      if (di > 0.0) {
        response = response + max(0.0, log_c - log2(linear_depth(di)));
      }
    }
    color = color * exp(-(response / 8.0) * frame.edl_strength);  // eqs. 11-12
  }
  return vec4<f32>(color, 1.0);
}

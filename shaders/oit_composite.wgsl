// Composite of the billboard path's translucent points (point_draw.wgsl, weighted blended OIT):
// over the image the opaque passes and the resolve made (their EDL included), the translucent
// points' weighted average colour with their coverage 1 - exp(-sum w) (1 minus the product of
// their (1 - alpha)), blended by the pipeline (src alpha, one minus src alpha).

@group(0) @binding(0) var accumulated: texture_2d<f32>;  // (sum rgb * w, sum w), w = -ln(1 - a)

@vertex
fn vs_fullscreen(@builtin(vertex_index) vertex: u32) -> @builtin(position) vec4<f32> {
  let uv = vec2<f32>(f32((vertex << 1u) & 2u), f32(vertex & 2u));
  return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_composite(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
  let sum = textureLoad(accumulated, vec2<i32>(position.xy), 0);
  if (sum.a <= 0.0) {
    discard;  // no translucent point here
  }
  return vec4<f32>(sum.rgb / sum.a, 1.0 - exp(-sum.a));
}

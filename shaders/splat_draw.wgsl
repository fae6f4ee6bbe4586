// Splats drawn back to front as instanced quads (4-vertex strips), instance i being the i-th
// pair of the depth sort: the quad is the splat's box (splat_half_extent), the fragment its
// Gaussian, alpha = min(0.99, opacity * exp(power)), fragments under 1/255 dropped, the colour
// premultiplied (blend: one, one minus source alpha). Depth-tested, never written.
#include "splat_common.wgsl"

@group(0) @binding(0) var<uniform> frame: SplatFrame;
@group(0) @binding(1) var<storage, read> projected: array<Projected>;
@group(0) @binding(2) var<storage, read> sorted_keys: array<u32>;
@group(0) @binding(3) var<storage, read> sorted_values: array<u32>;

struct VertexOut {
  @builtin(position) position: vec4<f32>,
  @location(0) @interpolate(flat) centre: vec2<f32>,
  @location(1) @interpolate(flat) conic: vec3<f32>,
  @location(2) @interpolate(flat) color: vec4<f32>,  // rgb, opacity
}

@vertex
fn vs_splat(@builtin(vertex_index) vertex: u32, @builtin(instance_index) instance: u32) -> VertexOut {
  let p = projected[sorted_values[instance]];
  let corner = vec2<f32>(f32(vertex & 1u), f32((vertex >> 1u) & 1u)) * 2.0 - 1.0;
  let pixel = p.centre + corner * splat_half_extent(p);
  let ndc = vec2<f32>(pixel.x / frame.viewport.x * 2.0 - 1.0, 1.0 - pixel.y / frame.viewport.y * 2.0);
  // Reverse Z with the far plane at infinity: depth = near / z.
  let depth = frame.near / key_depth(sorted_keys[instance]);
  var out: VertexOut;
  out.position = vec4<f32>(ndc, depth, 1.0);
  out.centre = p.centre;
  out.conic = vec3<f32>(p.conic_xy, p.conic_z);
  let ba = unpack2x16float(p.color_b_opacity);
  out.color = vec4<f32>(unpack2x16float(p.color_rg), ba.x, ba.y);
  return out;
}

@fragment
fn fs_splat(in: VertexOut) -> @location(0) vec4<f32> {
  // Pixel centres are at half-integer positions, as the centre's.
  let d = in.centre - in.position.xy;
  let power = -0.5 * (in.conic.x * d.x * d.x + in.conic.z * d.y * d.y) - in.conic.y * d.x * d.y;
  if (power > 0.0) {
    discard;
  }
  let alpha = min(0.99, in.color.a * exp(power));
  if (alpha < MIN_ALPHA) {
    discard;
  }
  return vec4<f32>(in.color.rgb * alpha, alpha);
}

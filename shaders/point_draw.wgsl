// Vertex pulling: 6 vertices per point (two triangles), no vertex buffers, no instancing.
// `point_index(slot)` comes from the including file (every point, or the CLOD survivors), as do
// `point_extra(index)` and `kHasExtra` (whether the extras buffer is bound: GPS-time and
// point-source filters). Filtered points collapse to a vertex outside the clip volume.
//
// Translucent points (alpha under 255 in a cloud that has them, RGB mode: frame.translucent)
// are left to a pass of their own after the opaque ones: weighted blended order-independent
// transparency (McGuire and Bavoil 2013). vs_translucent and fs_translucent add each fragment in
// front of the opaque depth to one target (see fs_translucent); oit_composite.wgsl lays the
// average colour over the image by the coverage.
#include "point_common.wgsl"

@group(1) @binding(0) var<storage, read> points: array<Point>;

struct VertexOut {
  @builtin(position) clip: vec4<f32>,
  @location(0) color: vec3<f32>,
  @location(1) corner: vec2<f32>,
  @location(2) @interpolate(flat) size_px: f32,
}

// The translucent pass's vertex: the colour's alpha too.
struct TranslucentOut {
  @builtin(position) clip: vec4<f32>,
  @location(0) color: vec4<f32>,
  @location(1) corner: vec2<f32>,
  @location(2) @interpolate(flat) size_px: f32,
}

struct PlacedCorner {
  out: VertexOut,
  alpha: f32,
}

// z > w: outside the clip volume, so both triangles are dropped before rasterisation.
const kDropped = vec4<f32>(0.0, 0.0, 2.0, 1.0);

// A point's quad corner, its colour and size. `translucent_pass` (a literal at each call): the
// translucent pass keeps the points under full opacity; the opaque passes keep the others where
// the frame splits them (frame.translucent), every point otherwise.
fn place_corner(vertex: u32, translucent_pass: bool) -> PlacedCorner {
  let index = point_index(vertex / 6u);
  let p = points[index];
  var placed: PlacedCorner;
  if (translucent_pass) {
    if ((p.rgba >> 24u) == 255u) {
      placed.out.clip = kDropped;
      return placed;
    }
  } else if (frame.translucent != 0u && (p.rgba >> 24u) != 255u) {
    placed.out.clip = kDropped;
    return placed;
  }
  // Corners of triangles (-1,-1) (1,-1) (-1,1) and (-1,1) (1,-1) (1,1), as bit masks.
  let c = vertex % 6u;
  let corner = vec2<f32>(f32((0x32u >> c) & 1u), f32((0x2cu >> c) & 1u)) * 2.0 - 1.0;
  let rel = vec3<f32>(p.x, p.y, p.z) + chunk.offset;
  var shown = 1u;
  if (filters.flags != 0u) {
    shown = point_filter(p, point_extra(index), kHasExtra, rel);
    if (shown == 0u) {
      placed.out.clip = kDropped;
      return placed;
    }
  }
  var clip = frame.view_proj * vec4<f32>(rel, 1.0);
  let size = point_pixels(rel);
  // Offset in clip space so the quad spans `size` pixels whatever the depth.
  clip = vec4<f32>(clip.xy + corner * size / frame.viewport * clip.w, clip.zw);
  placed.out.clip = clip;
  placed.out.color = point_color(p);
  if (shown == 2u) {
    placed.out.color = mix(placed.out.color, filters.highlight.rgb, filters.highlight.a);
  }
  placed.out.corner = corner;
  placed.out.size_px = size;
  placed.alpha = f32(p.rgba >> 24u) / 255.0;
  return placed;
}

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32) -> VertexOut {
  return place_corner(vertex, false).out;
}

@vertex
fn vs_translucent(@builtin(vertex_index) vertex: u32) -> TranslucentOut {
  let placed = place_corner(vertex, true);
  var out: TranslucentOut;
  out.clip = placed.out.clip;
  out.color = vec4<f32>(placed.out.color, placed.alpha);
  out.corner = placed.out.corner;
  out.size_px = placed.out.size_px;
  return out;
}

// Naive: the nearest fragment wins (depth test and write). Weight 1 in alpha for the resolve.
@fragment
fn fs_naive(in: VertexOut) -> @location(0) vec4<f32> {
  if (frame.round_points != 0u && in.size_px >= 3.0 && dot(in.corner, in.corner) > 1.0) {
    discard;
  }
  return vec4<f32>(in.color, 1.0);
}

// Splat pass 1: depth pre-pass pushed back by blend_depth of the distance. Reverse Z with an
// infinite far plane stores near / z, so z * (1 + b) is depth / (1 + b): smaller is further.
@fragment
fn fs_depth(in: VertexOut) -> @builtin(frag_depth) f32 {
  if (in.size_px >= 3.0 && dot(in.corner, in.corner) > 1.0) {
    discard;
  }
  return in.clip.z / (1.0 + frame.blend_depth);
}

// Splat pass 2: weighted colour (weight in alpha), added up where the fragment lies within the
// tolerance of the pre-pass depth. Paraboloid weights 1 - r^2 over a disc; tiny splats (< 3 px)
// cover one or two pixels and weigh 1.
@fragment
fn fs_accum(in: VertexOut) -> @location(0) vec4<f32> {
  var w = 1.0;
  if (in.size_px >= 3.0) {
    let r2 = dot(in.corner, in.corner);
    if (r2 > 1.0) {
      discard;
    }
    w = max(1.0 - r2, 1e-3);
  }
  return vec4<f32>(in.color * w, w);
}

// The translucent pass (depth tested against the opaque points, not written), additive into one
// RGBA16Float target: (rgb * w, w) with w = -ln(1 - alpha). The sum of w gives both the average
// colour (sum rgb * w / sum w) and the revealage, the product of (1 - alpha) = exp(-sum w),
// whatever order the fragments come in: McGuire and Bavoil's weights alpha * w(z) with a weight
// of its own, -ln(1 - alpha) / alpha, which grows with alpha (1 for faint points) rather than
// with depth, since points carry no depth range that a depth weight could be scaled to. One
// target, and only additive blending.
@fragment
fn fs_translucent(in: TranslucentOut) -> @location(0) vec4<f32> {
  if (frame.round_points != 0u && in.size_px >= 3.0 && dot(in.corner, in.corner) > 1.0) {
    discard;
  }
  // Alpha is at most 254 / 255 here (opaque points are the other passes').
  let w = -log(1.0 - in.color.a);
  return vec4<f32>(in.color.rgb * w, w);
}

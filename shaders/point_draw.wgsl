// Vertex pulling: 6 vertices per point (two triangles), no vertex buffers, no instancing.
// `point_index(slot)` comes from the including file (every point, or the CLOD survivors), as do
// `point_extra(index)` and `kHasExtra` (whether the extras buffer is bound: GPS-time and
// point-source filters). Filtered points collapse to a vertex outside the clip volume.
#include "point_common.wgsl"

@group(1) @binding(0) var<storage, read> points: array<Point>;

struct VertexOut {
  @builtin(position) clip: vec4<f32>,
  @location(0) color: vec3<f32>,
  @location(1) corner: vec2<f32>,
  @location(2) @interpolate(flat) size_px: f32,
}

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32) -> VertexOut {
  let index = point_index(vertex / 6u);
  let p = points[index];
  // Corners of triangles (-1,-1) (1,-1) (-1,1) and (-1,1) (1,-1) (1,1), as bit masks.
  let c = vertex % 6u;
  let corner = vec2<f32>(f32((0x32u >> c) & 1u), f32((0x2cu >> c) & 1u)) * 2.0 - 1.0;
  let rel = vec3<f32>(p.x, p.y, p.z) + chunk.offset;
  var out: VertexOut;
  var shown = 1u;
  if (filters.flags != 0u) {
    shown = point_filter(p, point_extra(index), kHasExtra, rel);
    if (shown == 0u) {
      // z > w: outside the clip volume, so both triangles are dropped before rasterisation.
      out.clip = vec4<f32>(0.0, 0.0, 2.0, 1.0);
      return out;
    }
  }
  var clip = frame.view_proj * vec4<f32>(rel, 1.0);
  let size = point_pixels(rel);
  // Offset in clip space so the quad spans `size` pixels whatever the depth.
  clip = vec4<f32>(clip.xy + corner * size / frame.viewport * clip.w, clip.zw);
  out.clip = clip;
  out.color = point_color(p);
  if (shown == 2u) {
    out.color = mix(out.color, filters.highlight.rgb, filters.highlight.a);
  }
  out.corner = corner;
  out.size_px = size;
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

// Shared by the point passes: frame and chunk uniforms, the point record, colour modes, point
// size modes and the CLOD filter (seed 000, eqs. 6-9).
#include "point_colors.wgsl"
#include "point_filter.wgsl"
#include "sky.wgsl"

struct Frame {
  view_proj: mat4x4<f32>,  // projection * rotation-only view (camera at the origin)
  viewport: vec2<f32>,
  focal_px: f32,  // pixels per world unit at distance 1
  point_size: f32,  // fixed size mode, pixels
  size_mode: u32,  // 0 fixed, 1 attenuated, 2 adaptive
  size_scale: f32,
  max_point_px: f32,
  clod_k: f32,
  color_mode: u32,  // ColorMode: 1 rgb, 2 intensity, 3 classification, 4 elevation, 5 return, 6 constant
  round_points: u32,
  blend_depth: f32,
  near: f32,
  edl_radius: f32,
  edl_strength: f32,
  edl_enabled: u32,
  // 1: the cloud has translucent points and the mode is RGB: the opaque passes skip the points
  // whose alpha is under 255, the translucent pass draws them (point_draw.wgsl). 0: every point
  // is opaque.
  translucent: u32,
  ranges: vec4<f32>,  // elevation min (unused: per chunk), 1 / elevation span, intensity min, 1 / span
  constant_color: vec4<f32>,
  background: vec4<f32>,
  palette: array<vec4<f32>, 32>,  // ASPRS classes
  sky: Sky,  // the background where nothing was drawn, when on (sky.wgsl)
}

struct Chunk {
  offset: vec3<f32>,  // chunk origin - camera position, subtracted in double on the CPU
  spacing: f32,  // s_native
  elevation: f32,  // chunk origin elevation - elevation range minimum (double on the CPU)
  count: u32,
  gps_range: vec2<f32>,  // the GPS-time filter relative to the chunk's GPS origin (double on the CPU)
}

// PointChunk::Extra: GPS time relative to the chunk's origin; point source (bits 0-15), flags
// (16-23), user data (24-31). Bound only by the pipelines of GPS-time / point-source filters.
struct PointExtra {
  gps: f32,
  word: u32,
}

// PointChunk::Vertex, 20 bytes.
struct Point {
  x: f32,
  y: f32,
  z: f32,
  rgba: u32,
  attributes: u32,  // intensity 0-15, class 16-23, return 24-27, returns 28-31
}

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> chunk: Chunk;
@group(0) @binding(2) var<uniform> filters: Filter;
// Polygon ring vertices, camera-relative source x/y (world x, -z).
@group(0) @binding(3) var<storage, read> polygon_vertices: array<vec2<f32>>;

fn point_color(p: Point) -> vec3<f32> {
  switch (frame.color_mode) {
    case 1u: {
      return unpack4x8unorm(p.rgba).rgb;
    }
    case 2u: {
      let v = clamp((f32(p.attributes & 0xffffu) - frame.ranges.z) * frame.ranges.w, 0.0, 1.0);
      return vec3<f32>(v);
    }
    case 3u: {
      return frame.palette[min((p.attributes >> 16u) & 0xffu, 31u)].rgb;
    }
    case 5u: {
      return return_color((p.attributes >> 24u) & 0xfu, p.attributes >> 28u);
    }
    case 6u: {
      return frame.constant_color.rgb;
    }
    default: {
      // World Y is the source elevation; the chunk's part was subtracted in double.
      return ramp((chunk.elevation + p.y) * frame.ranges.y);
    }
  }
}

// Eq. 6: a stable pseudo-random value from the point's chunk-local position.
fn clod_random(local: vec3<f32>) -> f32 {
  return fract(cos(local.x + local.y + local.z) * 43758.5453);
}

// Eqs. 8-9: keep when r < s_native / (d * k).
fn clod_keep(local: vec3<f32>, k: f32) -> bool {
  if (k <= 0.0) {
    return true;
  }
  let d = length(local + chunk.offset);
  return clod_random(local) < chunk.spacing / (d * k);
}

// Point diameter in pixels for the size mode; `rel` is camera-relative.
fn point_pixels(rel: vec3<f32>) -> f32 {
  var px = frame.point_size;
  if (frame.size_mode != 0u) {
    let d = max(length(rel), 1e-6);
    var world = chunk.spacing * frame.size_scale;
    if (frame.size_mode == 2u && frame.clod_k > 0.0) {
      // Survivors of eq. 9 on a surface lie 1/sqrt(kept fraction) further apart.
      let kept = clamp(chunk.spacing / (d * frame.clod_k), 1e-6, 1.0);
      world = world / sqrt(kept);
    }
    px = world * frame.focal_px / d;
  }
  return clamp(px, 1.0, frame.max_point_px);
}

// 0: hidden, 1: shown, 2: shown highlighted. `extra` counts only with has_extra (the pipelines
// that bind the extras buffer).
fn point_filter(p: Point, extra: PointExtra, has_extra: bool, rel: vec3<f32>) -> u32 {
  if (!attributes_pass(p.attributes)) {
    return 0u;
  }
  if ((filters.flags & 2u) != 0u && has_extra) {
    if (extra.gps < chunk.gps_range.x || extra.gps > chunk.gps_range.y) {
      return 0u;
    }
    let source = f32(extra.word & 0xffffu);
    if (source < filters.point_source.x || source > filters.point_source.y) {
      return 0u;
    }
  }
  return clip_state(rel);
}

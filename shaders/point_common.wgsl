// Shared by the point passes: frame and chunk uniforms, the point record, colour modes, point
// size modes and the CLOD filter (seed 000, eqs. 6-9).
#include "point_colors.wgsl"

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
  pad0: u32,
  ranges: vec4<f32>,  // elevation min (unused: per chunk), 1 / elevation span, intensity min, 1 / span
  constant_color: vec4<f32>,
  background: vec4<f32>,
  palette: array<vec4<f32>, 32>,  // ASPRS classes
}

struct Chunk {
  offset: vec3<f32>,  // chunk origin - camera position, subtracted in double on the CPU
  spacing: f32,  // s_native
  elevation: f32,  // chunk origin elevation - elevation range minimum (double on the CPU)
  count: u32,
  gps_range: vec2<f32>,  // the GPS-time filter relative to the chunk's GPS origin (double on the CPU)
}

// Filters and clip regions (pointcloud/filters.hpp, FilterUniforms on the CPU). Clip shapes are
// camera-relative like the points: their transforms had the camera subtracted in double.
struct Filter {
  classes: array<vec4<u32>, 2>,  // bit c: class c kept
  returns: u32,  // ReturnKind bits: 1 first, 2 last, 4 single, 8 intermediate; 0 every return
  flags: u32,  // 1 attribute tests, 2 GPS-time / point-source tests, 4 clip region
  clip_mode: u32,  // 0 inside, 1 outside, 2 highlight
  counts: u32,  // boxes (bits 0-7), rings (8-15), planes (16-23), polygons (24-31)
  intensity: vec2<f32>,
  point_source: vec2<f32>,
  highlight: vec4<f32>,  // tint of the region's points in highlight mode; a: how much
  boxes: array<mat4x4<f32>, 8>,  // camera-relative world -> box coordinates, inside |u| <= 1
  planes: array<vec4<f32>, 8>,  // camera-relative world: dot(xyz, p) + w >= 0 is kept
  rings: array<vec4<u32>, 32>,  // first vertex, vertex count, polygon
  polygons: array<vec4<f32>, 8>,  // camera-relative height range (world y) of each polygon
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

fn return_matches(kinds: u32, number: u32, count: u32) -> bool {
  return kinds == 0u || ((kinds & 1u) != 0u && number <= 1u) ||
         ((kinds & 2u) != 0u && number >= count) || ((kinds & 4u) != 0u && count <= 1u) ||
         ((kinds & 8u) != 0u && number > 1u && number < count);
}

// Even-odd rule over the polygon's rings, in the horizontal plane.
fn in_polygon(polygon: u32, rel: vec3<f32>) -> bool {
  let range = filters.polygons[polygon];
  if (rel.y < range.x || rel.y > range.y) {
    return false;
  }
  let q = vec2<f32>(rel.x, -rel.z);
  var inside = false;
  let rings = (filters.counts >> 8u) & 0xffu;
  for (var r = 0u; r < rings; r++) {
    let ring = filters.rings[r];
    if (ring.z != polygon) {
      continue;
    }
    var j = ring.x + ring.y - 1u;
    for (var i = ring.x; i < ring.x + ring.y; i++) {
      let a = polygon_vertices[i];
      let b = polygon_vertices[j];
      if ((a.y > q.y) != (b.y > q.y) && q.x < (b.x - a.x) * (q.y - a.y) / (b.y - a.y) + a.x) {
        inside = !inside;
      }
      j = i;
    }
  }
  return inside;
}

// Whether the camera-relative position lies in the clip region (pointcloud::ClipRegion).
fn in_clip_region(rel: vec3<f32>) -> bool {
  let boxes = filters.counts & 0xffu;
  let planes = (filters.counts >> 16u) & 0xffu;
  let polygons = filters.counts >> 24u;
  for (var i = 0u; i < planes; i++) {
    if (dot(filters.planes[i].xyz, rel) + filters.planes[i].w < 0.0) {
      return false;
    }
  }
  if (boxes == 0u && polygons == 0u) {
    return true;
  }
  for (var i = 0u; i < boxes; i++) {
    let u = (filters.boxes[i] * vec4<f32>(rel, 1.0)).xyz;
    if (all(abs(u) <= vec3<f32>(1.0))) {
      return true;
    }
  }
  for (var i = 0u; i < polygons; i++) {
    if (in_polygon(i, rel)) {
      return true;
    }
  }
  return false;
}

// 0: hidden, 1: shown, 2: shown highlighted. `extra` counts only with has_extra (the pipelines
// that bind the extras buffer).
fn point_filter(p: Point, extra: PointExtra, has_extra: bool, rel: vec3<f32>) -> u32 {
  if ((filters.flags & 1u) != 0u) {
    let class_id = (p.attributes >> 16u) & 0xffu;
    let word = filters.classes[class_id >> 7u][(class_id >> 5u) & 3u];
    if (((word >> (class_id & 31u)) & 1u) == 0u) {
      return 0u;
    }
    if (!return_matches(filters.returns, (p.attributes >> 24u) & 0xfu, p.attributes >> 28u)) {
      return 0u;
    }
    let intensity = f32(p.attributes & 0xffffu);
    if (intensity < filters.intensity.x || intensity > filters.intensity.y) {
      return 0u;
    }
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
  if ((filters.flags & 4u) != 0u) {
    let inside = in_clip_region(rel);
    if (filters.clip_mode == 2u) {
      return select(1u, 2u, inside);
    }
    if (inside != (filters.clip_mode == 0u)) {
      return 0u;
    }
  }
  return 1u;
}

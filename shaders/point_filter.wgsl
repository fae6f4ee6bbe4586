// Filters and clip regions on the GPU (pointcloud/filters.hpp; FilterUniforms on the CPU), shared
// by the billboard passes (point_common.wgsl) and the compute rasterizer
// (compute_raster_filter.wgsl). The including file declares `filters: Filter` and
// `polygon_vertices: array<vec2<f32>>` at its own bindings. Positions are camera-relative world
// coordinates (Y up), like the points: the clip shapes' transforms had the camera subtracted in
// double on the CPU.

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

// Class, return and intensity tests on the attribute word (intensity 0-15, class 16-23, return
// 24-27, returns 28-31).
fn attributes_pass(attr: u32) -> bool {
  if ((filters.flags & 1u) == 0u) {
    return true;
  }
  let class_id = (attr >> 16u) & 0xffu;
  let word = filters.classes[class_id >> 7u][(class_id >> 5u) & 3u];
  if (((word >> (class_id & 31u)) & 1u) == 0u) {
    return false;
  }
  if (!return_matches(filters.returns, (attr >> 24u) & 0xfu, attr >> 28u)) {
    return false;
  }
  let intensity = f32(attr & 0xffffu);
  return intensity >= filters.intensity.x && intensity <= filters.intensity.y;
}

// The clip region's verdict: 0 hidden, 1 shown, 2 shown highlighted.
fn clip_state(rel: vec3<f32>) -> u32 {
  if ((filters.flags & 4u) == 0u) {
    return 1u;
  }
  let inside = in_clip_region(rel);
  if (filters.clip_mode == 2u) {
    return select(1u, 2u, inside);
  }
  return select(0u, 1u, inside == (filters.clip_mode == 0u));
}

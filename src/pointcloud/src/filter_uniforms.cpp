#include "filter_uniforms.hpp"

#include <cmath>

#include "stipple/core/error.hpp"

namespace stipple::pc::detail {

// The filter and clip region as the shaders test them, camera-relative: every transform is made
// in double with the camera position subtracted, then cast (seed 000, section 5).
std::vector<float> make_filter_uniforms(const PointFilter& filter, const ClipRegion& clip,
                                        const glm::vec4& highlight, const Camera& camera,
                                        FilterUniforms& u) {
  u = {};
  std::vector<float> polygon_vertices;
  std::copy(filter.classes.begin(), filter.classes.end(), u.classes);
  u.returns = filter.returns;
  u.flags = (filter.filters_classes() || filter.returns || filter.intensity ? 1u : 0u) |
            (filter.needs_extras() ? 2u : 0u) | (clip.empty() ? 0u : 4u);
  const glm::dvec2 everything(-kFloatHuge, kFloatHuge);
  const glm::dvec2 in = filter.intensity.value_or(everything);
  const glm::dvec2 source = filter.point_source.value_or(everything);
  u.intensity[0] = clamp_float(in.x);
  u.intensity[1] = clamp_float(in.y);
  u.point_source[0] = clamp_float(source.x);
  u.point_source[1] = clamp_float(source.y);
  for (int c = 0; c < 4; ++c) u.highlight[c] = highlight[c];
  u.clip_mode = uint32_t(clip.mode);
  if (clip.boxes.size() > kMaxGpuClipShapes || clip.planes.size() > kMaxGpuClipShapes ||
      clip.polygons.size() > kMaxGpuClipShapes)
    fail("at most {} clip boxes, {} planes and {} polygons can be drawn at once", kMaxGpuClipShapes,
         kMaxGpuClipShapes, kMaxGpuClipShapes);
  // The camera in the source frame (Z up): world (x, y, z) is source (x, -z, y).
  const glm::dvec3 cam = y_up_to_z_up(camera.position);
  for (size_t i = 0; i < clip.boxes.size(); ++i) {
    const ClipBox& b = clip.boxes[i];
    const double c = std::cos(b.yaw), s = std::sin(b.yaw);
    const glm::dvec3 inv(1.0 / std::max(b.half_size.x, 1e-12), 1.0 / std::max(b.half_size.y, 1e-12),
                         1.0 / std::max(b.half_size.z, 1e-12));
    // Rows of S * R on source offsets: box coordinates of (source - centre).
    const double sr[3][3] = {{c * inv.x, s * inv.x, 0}, {-s * inv.y, c * inv.y, 0}, {0, 0, inv.z}};
    // source = P * world with P's rows (1,0,0), (0,0,-1), (0,1,0): columns of S R P.
    double a[3][3];
    for (int r = 0; r < 3; ++r) {
      a[r][0] = sr[r][0];
      a[r][1] = sr[r][2];
      a[r][2] = -sr[r][1];
    }
    const glm::dvec3 d = cam - b.center;
    float* m = u.boxes[i];  // column-major
    for (int r = 0; r < 3; ++r) {
      for (int col = 0; col < 3; ++col) m[col * 4 + r] = float(a[r][col]);
      m[12 + r] = float(sr[r][0] * d.x + sr[r][1] * d.y + sr[r][2] * d.z);
    }
    m[15] = 1.0f;
  }
  for (size_t i = 0; i < clip.planes.size(); ++i) {
    const ClipPlane& pl = clip.planes[i];
    const glm::dvec3 n = pl.normal;
    u.planes[i][0] = float(n.x);
    u.planes[i][1] = float(n.z);
    u.planes[i][2] = float(-n.y);
    u.planes[i][3] = float(pl.offset + glm::dot(n, cam));
  }
  size_t rings = 0;
  for (size_t i = 0; i < clip.polygons.size(); ++i) {
    const ClipPolygon& poly = clip.polygons[i];
    u.polygons[i][0] = clamp_float(poly.min_z - cam.z);
    u.polygons[i][1] = clamp_float(poly.max_z - cam.z);
    for (const auto& ring : poly.rings) {
      if (rings == kMaxGpuRings) fail("clip polygons have more than {} rings", kMaxGpuRings);
      u.rings[rings][0] = uint32_t(polygon_vertices.size() / 2);
      u.rings[rings][1] = uint32_t(ring.size());
      u.rings[rings][2] = uint32_t(i);
      ++rings;
      for (const glm::dvec2& v : ring) {
        polygon_vertices.push_back(float(v.x - cam.x));
        polygon_vertices.push_back(float(v.y - cam.y));
      }
    }
  }
  if (polygon_vertices.size() / 2 > kMaxGpuPolygonVertices)
    fail("clip polygons have {} vertices; at most {} can be drawn", polygon_vertices.size() / 2,
         kMaxGpuPolygonVertices);
  u.counts = uint32_t(clip.boxes.size()) | uint32_t(rings) << 8 |
             uint32_t(clip.planes.size()) << 16 | uint32_t(clip.polygons.size()) << 24;
  return polygon_vertices;
}

}  // namespace stipple::pc::detail

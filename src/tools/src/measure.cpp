#include "stipple/tools/measure.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include "stipple/core/error.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/math/geo.hpp"

namespace stipple::tools {

namespace {
struct ToolInfo {
  const char* name;
  int points;      // 0: open
  int min_points;  // open tools
};
constexpr std::array<ToolInfo, kToolCount> kTools = {{
    {"none", 0, 0},
    {"inspect", 1, 1},
    {"distance", 0, 2},
    {"height", 2, 2},
    {"area", 0, 3},
    {"angle", 3, 3},
    {"circle", 3, 3},
    {"volume", 4, 4},
    {"profile", 0, 2},
    {"annotation", 1, 1},
    {"clip_box", 3, 3},
    {"clip_polygon", 0, 3},
}};
}  // namespace

const char* tool_name(Tool tool) {
  return kTools[size_t(tool)].name;
}

std::optional<Tool> parse_tool(const std::string& name) {
  for (size_t i = 0; i < kTools.size(); ++i)
    if (name == kTools[i].name) return Tool(i);
  return std::nullopt;
}

int tool_points(Tool tool) {
  return kTools[size_t(tool)].points;
}

int tool_min_points(Tool tool) {
  return kTools[size_t(tool)].min_points;
}

std::optional<Circle> circle_through(const glm::dvec3& a, const glm::dvec3& b,
                                     const glm::dvec3& c) {
  // Circumcentre in the triangle's plane: a + (|u|^2 (v x n) ... ) with u = b - a, v = c - a.
  const glm::dvec3 u = b - a, v = c - a, n = glm::cross(u, v);
  const double n2 = glm::dot(n, n);
  const double scale = std::max({glm::dot(u, u), glm::dot(v, v), 1e-300});
  if (n2 <= 1e-18 * scale * scale) return std::nullopt;
  const glm::dvec3 offset =
      (glm::dot(u, u) * glm::cross(v, n) + glm::dot(v, v) * glm::cross(n, u)) / (2.0 * n2);
  return Circle{a + offset, glm::length(offset)};
}

pc::ClipBox box_from_clicks(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c,
                            double min_z, double max_z) {
  const glm::dvec2 a2(a), b2(b), c2(c);
  glm::dvec2 along = b2 - a2;
  const double length = glm::length(along);
  along = length > 0 ? along / length : glm::dvec2(1, 0);
  const glm::dvec2 across(-along.y, along.x);
  const double width = glm::dot(c2 - a2, across);  // signed: the side c is on
  const glm::dvec2 center = a2 + along * (length / 2) + across * (width / 2);
  pc::ClipBox box;
  box.center = {center.x, center.y, (min_z + max_z) / 2};
  box.half_size = {length / 2, std::abs(width) / 2, (max_z - min_z) / 2};
  box.yaw = std::atan2(along.y, along.x);
  return box;
}

pc::ClipBox volume_box(const Measurement& m) {
  if (m.points.size() < 4) return {};
  const double plane = m.points[0].z;
  double top = plane;
  for (const glm::dvec3& p : m.points) top = std::max(top, p.z);
  // The box reaches far above: everything over the footprint counts.
  return box_from_clicks(m.points[1], m.points[2], m.points[3], plane, top + 1e6);
}

void compute_values(Measurement& m) {
  MeasureValues& v = m.values;
  v = {};
  const auto& p = m.points;
  const bool closed = m.tool == Tool::Area || m.tool == Tool::ClipPolygon;
  const size_t n = p.size();
  const size_t edges = closed && n >= 3 ? n : (n > 0 ? n - 1 : 0);
  for (size_t i = 0; i < edges; ++i) {
    const glm::dvec3 a = p[i], b = p[(i + 1) % n];
    const double h = glm::length(glm::dvec2(b - a));
    const double s = glm::length(b - a);
    v.segments_horizontal.push_back(h);
    v.segments_3d.push_back(s);
    v.length_horizontal += h;
    v.length_3d += s;
  }
  if (n >= 2) v.height = p.back().z - p.front().z;
  if (closed && n >= 3) {
    v.perimeter = v.length_3d;
    // Shoelace on X/Y (relative to the first point for precision), Newell's normal for 3D.
    double twice = 0;
    glm::dvec3 newell(0.0);
    for (size_t i = 0; i < n; ++i) {
      const glm::dvec3 a = p[i] - p[0], b = p[(i + 1) % n] - p[0];
      twice += a.x * b.y - b.x * a.y;
      newell += glm::cross(a, b);
    }
    v.area_horizontal = std::abs(twice) / 2;
    v.area_3d = glm::length(newell) / 2;
  }
  if (m.tool == Tool::Angle && n == 3) {
    const glm::dvec3 a = p[0] - p[1], b = p[2] - p[1];
    const double la = glm::length(a), lb = glm::length(b);
    if (la > 0 && lb > 0)
      v.angle_degrees = std::acos(std::clamp(glm::dot(a, b) / (la * lb), -1.0, 1.0)) * 180.0 / M_PI;
  }
  if (m.tool == Tool::Circle && n == 3)
    if (const auto c = circle_through(p[0], p[1], p[2])) {
      v.center = c->center;
      v.radius = c->radius;
    }
  if (m.tool == Tool::Volume && n >= 1) v.plane_z = p[0].z;
  if (m.tool == Tool::Volume && n == 4) {
    const pc::ClipBox box = volume_box(m);
    v.area_horizontal = 4 * box.half_size.x * box.half_size.y;
  }
}

double volume_above(const pc::PointCloud& cloud, const pc::ClipBox& box, double plane_z,
                    double cell, const pc::PointFilter& filter, const pc::ClipRegion& clip,
                    double* covered_fraction) {
  const double length = 2 * box.half_size.x, width = 2 * box.half_size.y;
  if (!(length > 0) || !(width > 0) || !(cell > 0)) return 0;
  const size_t nx = size_t(std::clamp(std::ceil(length / cell), 1.0, 4096.0));
  const size_t ny = size_t(std::clamp(std::ceil(width / cell), 1.0, 4096.0));
  const double cx = length / double(nx), cy = width / double(ny);
  std::vector<double> top(nx * ny, -std::numeric_limits<double>::infinity());
  const double c = std::cos(box.yaw), s = std::sin(box.yaw);
  for (const pc::PointChunk& chunk : cloud.chunks) {
    if (chunk.bounds.empty()) continue;
    for (size_t i = 0; i < chunk.vertices.size(); ++i) {
      const pc::PointChunk::Vertex& v = chunk.vertices[i];
      const glm::dvec3 p = y_up_to_z_up(chunk.origin + glm::dvec3(v.x, v.y, v.z));
      const glm::dvec3 d = p - box.center;
      const double lx = c * d.x + s * d.y + box.half_size.x;
      const double ly = -s * d.x + c * d.y + box.half_size.y;
      if (lx < 0 || ly < 0 || lx >= length || ly >= width) continue;
      if (!pc::chunk_point_shown(chunk, i, filter, clip)) continue;
      double& t = top[std::min(nx - 1, size_t(lx / cx)) + nx * std::min(ny - 1, size_t(ly / cy))];
      t = std::max(t, p.z);
    }
  }
  // Empty cells: the mean of their non-empty neighbours, once.
  std::vector<double> filled = top;
  size_t covered = 0;
  for (size_t y = 0; y < ny; ++y)
    for (size_t x = 0; x < nx; ++x) {
      if (std::isfinite(top[x + nx * y])) {
        ++covered;
        continue;
      }
      double sum = 0;
      int count = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const long xx = long(x) + dx, yy = long(y) + dy;
          if (xx < 0 || yy < 0 || xx >= long(nx) || yy >= long(ny)) continue;
          const double t = top[size_t(xx) + nx * size_t(yy)];
          if (std::isfinite(t)) sum += t, ++count;
        }
      if (count) filled[x + nx * y] = sum / count;
    }
  double volume = 0;
  for (double t : filled)
    if (std::isfinite(t)) volume += std::max(0.0, t - plane_z) * cx * cy;
  if (covered_fraction) *covered_fraction = double(covered) / double(nx * ny);
  return volume;
}

void measure_with_cloud(Measurement& m, const pc::PointCloud* cloud, const pc::PointFilter& filter,
                        const pc::ClipRegion& clip) {
  compute_values(m);
  if (m.tool != Tool::Volume || m.points.size() != 4 || !cloud) return;
  double spacing = 0;
  size_t chunks = 0;
  for (const pc::PointChunk& c : cloud->chunks)
    if (!c.vertices.empty()) spacing += c.spacing, ++chunks;
  spacing = chunks ? spacing / double(chunks) : 1.0;
  m.values.volume_above = volume_above(*cloud, volume_box(m), m.values.plane_z, 2 * spacing, filter,
                                       clip, &m.values.covered_fraction);
}

glm::dvec3 SourceFrame::to_crs(const glm::dvec3& local) const {
  if (!enu_origin) return local;
  return geo::LocalEnu(*enu_origin).to_geodetic(local);
}

glm::dvec3 SourceFrame::from_crs(const glm::dvec3& crs) const {
  if (!enu_origin) return crs;
  glm::dvec3 p = crs;
  if (std::isnan(p.z)) p.z = 0;
  return geo::LocalEnu(*enu_origin).from_geodetic(p);
}

std::string unit_symbol(const std::string& unit) {
  if (unit == "metre" || unit == "meter" || unit.empty()) return "m";
  if (unit == "foot") return "ft";
  if (unit == "US survey foot") return "ftUS";
  return unit;
}

std::string value_text(const Measurement& m, const std::string& unit) {
  const std::string u = unit_symbol(unit);
  const MeasureValues& v = m.values;
  switch (m.tool) {
    case Tool::Distance:
      return fmt::format("{:.3f} {} ({:.3f} {} horizontal)", v.length_3d, u, v.length_horizontal,
                         u);
    case Tool::Height:
      return fmt::format("dz {:+.3f} {}", v.height, u);
    case Tool::Area:
    case Tool::ClipPolygon:
      return fmt::format("{:.3f} {}2 horizontal, {:.3f} {}2 3D", v.area_horizontal, u, v.area_3d,
                         u);
    case Tool::Angle:
      return fmt::format("{:.2f} deg", v.angle_degrees);
    case Tool::Circle:
      return fmt::format("r {:.3f} {}", v.radius, u);
    case Tool::Volume:
      return fmt::format("{:.3f} {}3 above z {:.3f}", v.volume_above, u, v.plane_z);
    case Tool::Profile:
      return fmt::format("profile {:.3f} {}, width {:.3f}", v.length_horizontal, u, m.width);
    default:
      return m.label;
  }
}

io::GeoFeature to_feature(const Measurement& m, const SourceFrame& frame) {
  io::GeoFeature f;
  std::vector<glm::dvec3> crs;
  for (const glm::dvec3& p : m.points) crs.push_back(frame.to_crs(p));
  auto& props = f.properties;
  props["tool"] = std::string(tool_name(m.tool));
  if (!m.label.empty()) props["label"] = m.label;
  props["unit"] = frame.unit.empty() ? std::string("metre") : frame.unit;
  const MeasureValues& v = m.values;
  switch (m.tool) {
    case Tool::Inspect:
    case Tool::Annotation:
      f.type = "Point";
      f.parts = {{crs.at(0)}};
      break;
    case Tool::Area:
    case Tool::ClipPolygon: {
      f.type = "Polygon";
      std::vector<glm::dvec3> ring = crs;
      ring.push_back(crs.front());
      f.parts = {ring};
      f.polygon_of_part = {0};
      props["area_horizontal"] = v.area_horizontal;
      props["area_3d"] = v.area_3d;
      props["perimeter"] = v.perimeter;
      props["segments_3d"] = v.segments_3d;
      break;
    }
    case Tool::Volume:
    case Tool::ClipBox: {
      // The footprint as a polygon at the plane's height; the clicks themselves as properties.
      const pc::ClipBox box = m.tool == Tool::Volume
                                  ? volume_box(m)
                                  : box_from_clicks(m.points[0], m.points[1], m.points[2], 0, 0);
      std::vector<glm::dvec3> ring;
      const auto corners = box.corners();
      const double z = m.tool == Tool::Volume ? m.points[0].z : box.center.z;
      for (int i = 0; i < 4; ++i) ring.push_back(frame.to_crs({corners[i].x, corners[i].y, z}));
      ring.push_back(ring.front());
      f.type = "Polygon";
      f.parts = {ring};
      f.polygon_of_part = {0};
      std::vector<double> clicks;
      for (const glm::dvec3& p : crs) clicks.insert(clicks.end(), {p.x, p.y, p.z});
      props["clicks"] = clicks;
      if (m.tool == Tool::Volume) {
        props["volume_above"] = v.volume_above;
        props["plane_z"] = v.plane_z;
        props["area_horizontal"] = v.area_horizontal;
        props["covered_fraction"] = v.covered_fraction;
      }
      break;
    }
    default:
      f.type = "LineString";
      f.parts = {crs};
      props["length_horizontal"] = v.length_horizontal;
      props["length_3d"] = v.length_3d;
      props["segments_horizontal"] = v.segments_horizontal;
      props["segments_3d"] = v.segments_3d;
      props["height_difference"] = v.height;
      if (m.tool == Tool::Angle) props["angle_degrees"] = v.angle_degrees;
      if (m.tool == Tool::Circle) {
        props["radius"] = v.radius;
        const glm::dvec3 c = frame.to_crs(v.center);
        props["center"] = std::vector<double>{c.x, c.y, c.z};
      }
      if (m.tool == Tool::Profile) props["width"] = m.width;
      break;
  }
  return f;
}

Measurement from_feature(const io::GeoFeature& f, const SourceFrame& frame, size_t index,
                         const std::string& name) {
  Measurement m;
  const std::string tool = f.text("tool", "");
  const std::string where = fmt::format("{}: feature {}", name, index);
  if (tool.empty()) {
    // Plain GeoJSON from elsewhere: points become annotations, lines distances, polygons areas.
    m.tool = f.type == "Point"        ? Tool::Annotation
             : f.type == "LineString" ? Tool::Distance
             : f.type == "Polygon"    ? Tool::Area
                                      : Tool::None;
    if (m.tool == Tool::None) fail("{}: a {} is not a measurement", where, f.type);
  } else {
    const auto parsed = parse_tool(tool);
    if (!parsed || *parsed == Tool::None) fail("{}: unknown tool \"{}\"", where, tool);
    m.tool = *parsed;
  }
  m.label = f.text("label", "");
  m.width = f.number("width", 1.0);
  if (!(m.width > 0)) fail("{}: a profile's width must be positive", where);
  auto local = [&](glm::dvec3 p) {
    if (std::isnan(p.z)) p.z = 0;
    return frame.from_crs(p);
  };
  if (m.tool == Tool::Volume || m.tool == Tool::ClipBox) {
    auto it = f.properties.find("clicks");
    const auto* clicks =
        it == f.properties.end() ? nullptr : std::get_if<std::vector<double>>(&it->second);
    const size_t want = size_t(tool_points(m.tool));
    if (!clicks || clicks->size() != 3 * want)
      fail("{}: a {} needs its {} clicked points in \"clicks\"", where, tool, want);
    for (size_t i = 0; i < want; ++i)
      m.points.push_back(local({(*clicks)[3 * i], (*clicks)[3 * i + 1], (*clicks)[3 * i + 2]}));
  } else {
    if (f.parts.empty() || f.parts[0].empty()) fail("{}: no coordinates", where);
    std::vector<glm::dvec3> pts = f.parts[0];
    const bool ring = f.type == "Polygon";
    if (ring && pts.size() >= 2) pts.pop_back();  // the closing position
    for (const glm::dvec3& p : pts) m.points.push_back(local(p));
    const int fixed = tool_points(m.tool);
    if (fixed > 0 && int(m.points.size()) != fixed)
      fail("{}: a {} takes {} points, the geometry has {}", where, tool_name(m.tool), fixed,
           m.points.size());
    if (fixed == 0 && int(m.points.size()) < tool_min_points(m.tool))
      fail("{}: a {} needs at least {} points", where, tool_name(m.tool), tool_min_points(m.tool));
  }
  m.complete = true;
  compute_values(m);
  return m;
}

}  // namespace stipple::tools

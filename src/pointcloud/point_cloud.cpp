#include "pointcloud/point_cloud.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include "core/error.hpp"
#include "core/log.hpp"
#include "core/progress.hpp"
#include "io/las.hpp"
#include "math/camera.hpp"
#include "math/geo.hpp"

namespace stipple::pc {

ColorMode parse_color_mode(const std::string& name) {
  if (name == "auto") return ColorMode::Auto;
  if (name == "rgb") return ColorMode::Rgb;
  if (name == "intensity") return ColorMode::Intensity;
  if (name == "classification") return ColorMode::Classification;
  if (name == "elevation") return ColorMode::Elevation;
  if (name == "return") return ColorMode::ReturnNumber;
  fail("unknown colour mode '{}' (rgb, intensity, classification, elevation, return, auto)", name);
}

uint32_t pack_rgba(uint8_t r, uint8_t g, uint8_t b, uint8_t a) {
  return uint32_t(r) | uint32_t(g) << 8 | uint32_t(b) << 16 | uint32_t(a) << 24;
}

namespace {

// ASPRS LAS 1.4 standard classes (R6 table), Potree-like colours.
uint32_t classification_color(uint8_t c) {
  static constexpr std::array<std::array<uint8_t, 3>, 19> table = {{
      {160, 160, 160},  // 0 created, never classified
      {190, 190, 190},  // 1 unclassified
      {165, 125, 80},   // 2 ground
      {120, 200, 90},   // 3 low vegetation
      {70, 170, 60},    // 4 medium vegetation
      {30, 120, 40},    // 5 high vegetation
      {220, 80, 60},    // 6 building
      {255, 0, 255},    // 7 low point (noise)
      {200, 200, 0},    // 8 reserved / model key-point
      {40, 110, 230},   // 9 water
      {240, 170, 40},   // 10 rail
      {90, 90, 100},    // 11 road surface
      {250, 250, 120},  // 12 reserved / overlap
      {230, 230, 40},   // 13 wire guard
      {230, 200, 40},   // 14 wire conductor
      {180, 120, 220},  // 15 transmission tower
      {200, 160, 220},  // 16 wire-structure connector
      {120, 120, 140},  // 17 bridge deck
      {255, 40, 120},   // 18 high noise
  }};
  auto& rgb = table[c < table.size() ? c : 1];
  return pack_rgba(rgb[0], rgb[1], rgb[2]);
}

// A perceptual ramp (dark blue, cyan, green, yellow, red) for elevation.
uint32_t ramp_color(double t) {
  static constexpr std::array<std::array<double, 3>, 5> stops = {
      {{0.15, 0.15, 0.6}, {0.1, 0.6, 0.8}, {0.3, 0.75, 0.3}, {0.95, 0.85, 0.2}, {0.85, 0.2, 0.1}}};
  t = std::clamp(t, 0.0, 1.0) * (stops.size() - 1);
  size_t i = std::min<size_t>(size_t(t), stops.size() - 2);
  double f = t - double(i);
  uint8_t c[3];
  for (int k = 0; k < 3; ++k)
    c[k] = uint8_t(std::lround(255.0 * (stops[i][k] * (1.0 - f) + stops[i + 1][k] * f)));
  return pack_rgba(c[0], c[1], c[2]);
}

uint32_t return_color(uint8_t number, uint8_t count) {
  if (count <= 1) return pack_rgba(240, 200, 60);       // single return
  if (number <= 1) return pack_rgba(220, 60, 50);       // first of many
  if (number >= count) return pack_rgba(40, 110, 230);  // last of many
  return pack_rgba(60, 190, 80);                        // intermediate
}

}  // namespace

void append_batch(PointCloud& cloud, const io::PointBatch& batch, ColorMode mode, int rgb_bits,
                  glm::dvec2 elevation_range, size_t chunk_points) {
  if (mode == ColorMode::Auto) mode = batch.rgb.empty() ? ColorMode::Elevation : ColorMode::Rgb;
  if (mode == ColorMode::Rgb && batch.rgb.empty()) mode = ColorMode::Elevation;
  if (mode == ColorMode::Intensity && batch.intensity.empty()) mode = ColorMode::Elevation;
  if (mode == ColorMode::Classification && batch.classification.empty())
    mode = ColorMode::Elevation;
  if (mode == ColorMode::ReturnNumber && batch.return_number.empty()) mode = ColorMode::Elevation;
  static constexpr const char* names[] = {"auto",           "rgb",       "intensity",
                                          "classification", "elevation", "return"};
  cloud.color_source = names[int(mode)];

  const double z_span = std::max(elevation_range.y - elevation_range.x, 1e-9);
  // Intensity is 16-bit by the spec but many files hold 8-bit values: scale by what is there.
  int intensity_shift = 0;
  if (mode == ColorMode::Intensity) {
    uint16_t max_intensity = *std::max_element(batch.intensity.begin(), batch.intensity.end());
    while ((max_intensity >> intensity_shift) > 255) ++intensity_shift;
  }
  size_t i = 0;
  while (i < batch.size()) {
    if (cloud.chunks.empty() || cloud.chunks.back().vertices.size() >= chunk_points) {
      cloud.chunks.emplace_back();
      // Origin: the first point of the chunk; the chunk's points are spatially close in
      // scan order, and float offsets from it stay precise.
      cloud.chunks.back().origin = z_up_to_y_up(batch.positions[i]);
      cloud.chunks.back().vertices.reserve(std::min(chunk_points, batch.size() - i));
    }
    PointChunk& chunk = cloud.chunks.back();
    size_t end = std::min(batch.size(), i + (chunk_points - chunk.vertices.size()));
    for (; i < end; ++i) {
      const glm::dvec3& source = batch.positions[i];
      cloud.source_bounds.extend(source);
      glm::dvec3 world = z_up_to_y_up(source);
      cloud.world_bounds.extend(world);
      glm::dvec3 rel = world - chunk.origin;
      uint32_t color = 0;
      switch (mode) {
        case ColorMode::Rgb: {
          auto c = batch.rgb[i];
          if (rgb_bits == 16) c /= uint16_t(257);  // 16-bit to 8-bit with rounding of 255*257
          color = pack_rgba(uint8_t(std::min<int>(c.r, 255)), uint8_t(std::min<int>(c.g, 255)),
                            uint8_t(std::min<int>(c.b, 255)));
          break;
        }
        case ColorMode::Intensity: {
          uint8_t v = uint8_t(batch.intensity[i] >> intensity_shift);
          color = pack_rgba(v, v, v);
          break;
        }
        case ColorMode::Classification:
          color = classification_color(batch.classification[i]);
          break;
        case ColorMode::ReturnNumber:
          color = return_color(batch.return_number[i],
                               batch.number_of_returns.empty() ? 1 : batch.number_of_returns[i]);
          break;
        default:
          color = ramp_color((source.z - elevation_range.x) / z_span);
          break;
      }
      chunk.vertices.push_back({float(rel.x), float(rel.y), float(rel.z), color});
    }
  }
  cloud.point_count += batch.size();
}

PointCloud load_point_cloud(const std::vector<std::filesystem::path>& files,
                            const LoadOptions& options) {
  PointCloud cloud;
  std::vector<io::LasHeader> headers;
  uint64_t total = 0;
  for (const auto& file : files) {
    headers.push_back(io::read_las_header(file));
    total += headers.back().point_count;
  }
  // Geographic inputs (lon/lat degrees) go through a local ENU frame so that metres are metres.
  bool any_geographic = false, any_projected = false;
  Aabb header_box;
  for (const auto& h : headers) {
    (h.crs.geographic ? any_geographic : any_projected) = true;
    header_box.extend(h.min);
    header_box.extend(h.max);
  }
  if (any_geographic && any_projected)
    fail("cannot mix geographic (lon/lat) and projected inputs in one render: {} and {}",
         files.front().string(), files.back().string());
  cloud.geographic = any_geographic;
  std::optional<geo::LocalEnu> enu;
  if (any_geographic) enu.emplace(glm::dvec3(header_box.center().x, header_box.center().y, 0.0));

  glm::dvec2 z_range(header_box.min.z, header_box.max.z);
  // Intensity is 16-bit by the spec but often holds 8-bit data; decided per file below.
  Progress progress("reading", total);
  io::PointBatch batch;
  for (size_t f = 0; f < files.size(); ++f) {
    io::LasReader reader(files[f]);
    const io::LasHeader& header = reader.header();
    while (true) {
      batch.clear();
      size_t n = reader.read(batch, options.chunk_points);
      if (n == 0) break;
      if (enu)
        for (auto& p : batch.positions) p = enu->from_geodetic(p);
      append_batch(cloud, batch, options.color, header.rgb_bits, z_range, options.chunk_points);
      progress.advance(n);
    }
    if (reader.points_read() != header.point_count)
      STIPPLE_WARN("{}: header says {} points, read {}", files[f].string(), header.point_count,
                   reader.points_read());
  }
  progress.finish();
  return cloud;
}

}  // namespace stipple::pc

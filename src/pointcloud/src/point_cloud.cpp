#include "stipple/pointcloud/point_cloud.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numeric>
#include <optional>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/progress.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/math/geo.hpp"

namespace stipple::pc {

ColorMode parse_color_mode(const std::string& name) {
  if (name == "auto") return ColorMode::Auto;
  if (name == "rgb") return ColorMode::Rgb;
  if (name == "intensity") return ColorMode::Intensity;
  if (name == "classification") return ColorMode::Classification;
  if (name == "elevation") return ColorMode::Elevation;
  if (name == "return") return ColorMode::ReturnNumber;
  if (name == "constant") return ColorMode::Constant;
  fail(
      "unknown colour mode '{}' (rgb, intensity, classification, elevation, return, constant, "
      "auto)",
      name);
}

const char* color_mode_name(ColorMode mode) {
  static constexpr const char* names[] = {"auto",      "rgb",    "intensity", "classification",
                                          "elevation", "return", "constant"};
  return names[int(mode)];
}

uint32_t pack_rgba(uint8_t r, uint8_t g, uint8_t b, uint8_t a) {
  return uint32_t(r) | uint32_t(g) << 8 | uint32_t(b) << 16 | uint32_t(a) << 24;
}

uint32_t pack_attributes(uint16_t intensity, uint8_t classification, uint8_t return_number,
                         uint8_t number_of_returns) {
  return uint32_t(intensity) | uint32_t(classification) << 16 |
         uint32_t(std::min<uint8_t>(return_number, 15)) << 24 |
         uint32_t(std::min<uint8_t>(number_of_returns, 15)) << 28;
}

const std::array<glm::vec3, 32>& classification_palette() {
  // ASPRS LAS 1.4 standard classes (R6 table), Potree-like colours.
  static const std::array<glm::vec3, 32> palette = [] {
    static constexpr std::array<std::array<int, 3>, 19> table = {{
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
    std::array<glm::vec3, 32> p;
    for (size_t i = 0; i < p.size(); ++i) {
      auto& c = table[i < table.size() ? i : 1];
      p[i] = glm::vec3(c[0], c[1], c[2]) / 255.0f;
    }
    return p;
  }();
  return palette;
}

ColorMode resolve_color_mode(const CloudAttributes& cloud, ColorMode mode) {
  if (mode == ColorMode::Auto)
    mode = cloud.has_rgb && !cloud.rgb_uniform ? ColorMode::Rgb : ColorMode::Elevation;
  if ((mode == ColorMode::Rgb && !cloud.has_rgb) ||
      (mode == ColorMode::Intensity && !cloud.has_intensity) ||
      (mode == ColorMode::Classification && !cloud.has_classification) ||
      (mode == ColorMode::ReturnNumber && !cloud.has_returns))
    mode = ColorMode::Elevation;
  return mode;
}

uint32_t rgba_of(glm::u16vec3 c, int rgb_bits) {
  if (rgb_bits == 16) c /= uint16_t(257);  // 16-bit to 8-bit with rounding of 255*257
  return pack_rgba(uint8_t(std::min<int>(c.r, 255)), uint8_t(std::min<int>(c.g, 255)),
                   uint8_t(std::min<int>(c.b, 255)));
}

uint32_t batch_rgba(const io::PointBatch& batch, size_t i, int rgb_bits) {
  return batch.rgb.empty() ? 0 : rgba_of(batch.rgb[i], rgb_bits);
}

uint32_t batch_attributes(const io::PointBatch& batch, size_t i) {
  return pack_attributes(batch.intensity.empty() ? 0 : batch.intensity[i],
                         batch.classification.empty() ? 1 : batch.classification[i],
                         batch.return_number.empty() ? 1 : batch.return_number[i],
                         batch.number_of_returns.empty() ? 1 : batch.number_of_returns[i]);
}

uint32_t batch_extra_word(const io::PointBatch& batch, size_t i) {
  return uint32_t(batch.point_source_id.empty() ? 0 : batch.point_source_id[i]) |
         uint32_t(batch.flags.empty() ? 0 : batch.flags[i]) << 16 |
         uint32_t(batch.user_data.empty() ? 0 : batch.user_data[i]) << 24;
}

void append_batch(PointCloud& cloud, const io::PointBatch& batch, int rgb_bits,
                  size_t chunk_points) {
  const size_t n = batch.size();
  if (n == 0) return;
  // A cloud has an attribute when every batch so far had it.
  bool first = cloud.point_count == 0;
  auto has = [&](bool cloud_has, bool batch_has) { return (first || cloud_has) && batch_has; };
  CloudAttributes& a = cloud.attributes;
  a.has_rgb = has(a.has_rgb, !batch.rgb.empty());
  a.has_intensity = has(a.has_intensity, !batch.intensity.empty());
  a.has_classification = has(a.has_classification, !batch.classification.empty());
  a.has_returns = has(a.has_returns, !batch.return_number.empty());
  size_t i = 0;
  while (i < n) {
    if (cloud.chunks.empty() || cloud.chunks.back().vertices.size() >= chunk_points) {
      cloud.chunks.emplace_back();
      // Origin: the first point of the chunk; the chunk's points are spatially close in
      // scan order, and float offsets from it stay precise. The same for GPS time.
      cloud.chunks.back().origin = z_up_to_y_up(batch.positions[i]);
      cloud.chunks.back().vertices.reserve(std::min(chunk_points, n - i));
      cloud.chunks.back().first_point = cloud.point_count + i;
      if (cloud.keep_extras) {
        cloud.chunks.back().gps_origin = batch.gps_time.empty() ? 0.0 : batch.gps_time[i];
        cloud.chunks.back().extras.reserve(std::min(chunk_points, n - i));
      }
    }
    PointChunk& chunk = cloud.chunks.back();
    size_t end = std::min(n, i + (chunk_points - chunk.vertices.size()));
    for (; i < end; ++i) {
      const glm::dvec3& source = batch.positions[i];
      cloud.source_bounds.extend(source);
      glm::dvec3 world = z_up_to_y_up(source);
      cloud.world_bounds.extend(world);
      chunk.bounds.extend(world);
      glm::dvec3 rel = world - chunk.origin;
      chunk.vertices.push_back({float(rel.x), float(rel.y), float(rel.z),
                                batch_rgba(batch, i, rgb_bits), batch_attributes(batch, i)});
      if (cloud.keep_extras)
        chunk.extras.push_back(
            {float(batch.gps_time.empty() ? 0.0 : batch.gps_time[i] - chunk.gps_origin),
             batch_extra_word(batch, i)});
    }
  }
  cloud.point_count += n;
}

glm::dvec2 percentile_range(std::vector<double> values, std::vector<double> weights, double lo,
                            double hi) {
  if (values.empty()) return {0.0, 1.0};
  // The sample at which the cumulative weight first exceeds q * (W - 1) + 1/2: with unit weights
  // the nearest rank round(q * (n - 1)), found by selection rather than a sort.
  std::vector<double> at(2);
  const double q[2] = {lo, hi};
  if (weights.empty()) {
    for (int i = 0; i < 2; ++i) {
      size_t k = std::min(values.size() - 1, size_t(q[i] * double(values.size() - 1) + 0.5));
      std::nth_element(values.begin(), values.begin() + ptrdiff_t(k), values.end());
      at[i] = values[k];
    }
  } else {
    std::vector<size_t> order(values.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::sort(order.begin(), order.end(),
              [&](size_t a, size_t b) { return values[a] < values[b]; });
    const double total = std::accumulate(weights.begin(), weights.end(), 0.0);
    for (int i = 0; i < 2; ++i) {
      const double target = q[i] * std::max(total - 1.0, 0.0) + 0.5;
      double seen = 0;
      at[i] = values[order.back()];
      for (size_t k : order)
        if ((seen += weights[k]) > target) {
          at[i] = values[k];
          break;
        }
    }
  }
  glm::dvec2 r(at[0], at[1]);
  if (r.y <= r.x) r.y = r.x + 1.0;  // flat data: a unit range instead of a division by zero
  return r;
}

void finish_cloud(PointCloud& cloud) {
  for (PointChunk& chunk : cloud.chunks) {
    // Airborne data covers the horizontal plane (x, -z in world space): the mean spacing of
    // points spread evenly over the chunk's footprint. A per-chunk s_native for CLOD.
    glm::dvec3 size = chunk.bounds.empty() ? glm::dvec3(0.0) : chunk.bounds.size();
    double area = std::max(size.x * size.z, 1e-12);
    chunk.spacing =
        std::max(std::sqrt(area / double(std::max<size_t>(chunk.vertices.size(), 1))), 1e-6);
  }
  // About 1M samples, evenly strided through every chunk.
  std::vector<double> elevation, intensity;
  uint64_t stride = std::max<uint64_t>(1, cloud.point_count / (1 << 20));
  for (const PointChunk& chunk : cloud.chunks)
    for (size_t i = 0; i < chunk.vertices.size(); i += stride) {
      elevation.push_back(chunk.origin.y + double(chunk.vertices[i].y));
      intensity.push_back(double(chunk.vertices[i].attributes & 0xffffu));
    }
  cloud.attributes.elevation_percentiles = percentile_range(std::move(elevation), {}, 0.02, 0.98);
  cloud.attributes.intensity_percentiles = percentile_range(std::move(intensity), {}, 0.02, 0.98);
}

PointCloud generate_scene_cloud(const io::SceneParams& params, size_t chunk_points,
                                bool keep_extras) {
  const uint64_t block = std::max<uint64_t>(1, std::min<uint64_t>(chunk_points, 1 << 20));
  const uint64_t blocks = (params.point_count + block - 1) / block;
  std::vector<PointCloud> parts(blocks);
  ThreadPool pool;
  // Each block is its own chunk: generated and packed independently, then concatenated.
  pool.parallel_for(blocks, 1, [&](size_t begin, size_t end) {
    io::PointBatch batch;
    for (size_t b = begin; b < end; ++b) {
      batch.clear();
      uint64_t first = b * block;
      io::generate_scene(params, first, std::min(block, params.point_count - first), batch);
      parts[b].keep_extras = keep_extras;
      append_batch(parts[b], batch, 8, block);
      for (PointChunk& chunk : parts[b].chunks) chunk.first_point += first;
    }
  });
  PointCloud cloud;
  cloud.keep_extras = keep_extras;
  for (PointCloud& part : parts) {
    if (part.point_count == 0) continue;
    bool first = cloud.point_count == 0;
    CloudAttributes& a = cloud.attributes;
    const CloudAttributes& b = part.attributes;
    a.has_rgb = (first || a.has_rgb) && b.has_rgb;
    a.has_intensity = (first || a.has_intensity) && b.has_intensity;
    a.has_classification = (first || a.has_classification) && b.has_classification;
    a.has_returns = (first || a.has_returns) && b.has_returns;
    cloud.point_count += part.point_count;
    cloud.source_bounds.extend(part.source_bounds.min);
    cloud.source_bounds.extend(part.source_bounds.max);
    cloud.world_bounds.extend(part.world_bounds.min);
    cloud.world_bounds.extend(part.world_bounds.max);
    for (PointChunk& chunk : part.chunks) cloud.chunks.push_back(std::move(chunk));
  }
  finish_cloud(cloud);
  return cloud;
}

void fit_chunks(ViewFit& fit, std::span<const PointChunk* const> chunks) {
  Aabb all;
  for (const PointChunk* c : chunks) all.extend(c->bounds);
  if (all.empty()) return;
  // Outermost first: the extremes are found early, and inner chunks are then skipped whole.
  std::vector<std::pair<double, const PointChunk*>> order;
  order.reserve(chunks.size());
  for (const PointChunk* c : chunks)
    if (!c->bounds.empty() && !c->vertices.empty())
      order.emplace_back(glm::length(c->bounds.center() - all.center()), c);
  std::sort(order.begin(), order.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  for (const auto& [distance, c] : order) {
    if (!fit.empty() && !fit.could_widen(c->bounds)) continue;
    for (const auto& v : c->vertices) fit.add(c->origin + glm::dvec3(v.x, v.y, v.z));
  }
}

void fit_cloud(ViewFit& fit, const PointCloud& cloud) {
  std::vector<const PointChunk*> chunks;
  chunks.reserve(cloud.chunks.size());
  for (const PointChunk& c : cloud.chunks) chunks.push_back(&c);
  fit_chunks(fit, chunks);
}

uint64_t read_las_sample(io::LasReader& reader, uint64_t want,
                         const std::function<void(io::PointBatch&)>& take) {
  const io::LasHeader& header = reader.header();
  const uint64_t n = header.point_count;
  io::PointBatch batch;
  uint64_t read = 0;
  auto flush = [&] {
    if (batch.size() > 0) take(batch);
    batch.clear();
  };
  // Reads append to the batch, handed on in blocks (a batch per record would cost more than
  // the record).
  auto read_at = [&](uint64_t first, uint64_t count) {
    if (batch.size() >= (1 << 16)) flush();
    reader.seek(first);
    read += reader.read(batch, size_t(count));
  };
  if (want >= n) {
    for (uint64_t first = 0; first < n; first += 1 << 16) read_at(first, 1 << 16);
  } else if (header.compressed && header.laz_chunk_points > 0) {
    const uint64_t chunk = header.laz_chunk_points;
    const uint64_t chunks = (n + chunk - 1) / chunk;
    const uint64_t per = std::clamp<uint64_t>((want + chunks - 1) / chunks, 1, chunk);
    // Every 8th point of a chunk's first 8 * per: a chunk's first points are a run along a
    // scan line, and a run 8 times as long covers more ground for a little more decoding.
    const uint64_t thin = std::clamp<uint64_t>(chunk / per, 1, 8);
    std::vector<uint8_t> keep;
    for (uint64_t c = 0; c < chunks; ++c) {
      if (batch.size() >= (1 << 16)) flush();  // before `before`: read_at must not flush
      const size_t before = batch.size();
      read_at(c * chunk, std::min(per * thin, n - c * chunk));
      if (thin == 1 || batch.size() <= before) continue;
      keep.assign(batch.size(), 1);
      for (size_t i = before; i < keep.size(); ++i) keep[i] = (i - before) % thin == 0;
      batch.compact(keep);
      read -= batch.size() < keep.size() ? keep.size() - batch.size() : 0;
    }
  } else {
    // Single records at a stride: runs of consecutive records would draw scan lines as dashes.
    for (uint64_t i = 0; i < want; ++i) read_at(uint64_t(double(i) * double(n) / double(want)), 1);
  }
  flush();
  return read;
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
    // Degrees are turned into metres below: "degrees" that are not would make nonsense.
    if (const std::string problem = io::geographic_bounds_problem(h); !problem.empty())
      fail("{}", problem);
    (h.crs.geographic ? any_geographic : any_projected) = true;
    header_box.extend(h.min);
    header_box.extend(h.max);
  }
  if (any_geographic && any_projected)
    fail("cannot mix geographic (lon/lat) and projected inputs in one render: {} and {}",
         files.front().string(), files.back().string());
  cloud.geographic = any_geographic;
  cloud.keep_extras = options.keep_extras;
  std::optional<geo::LocalEnu> enu;
  if (any_geographic) {
    cloud.enu_origin = glm::dvec3(header_box.center().x, header_box.center().y, 0.0);
    enu.emplace(*cloud.enu_origin);
  }

  Progress progress("reading", options.sample > 0 ? std::min(options.sample, total) : total);
  io::PointBatch batch;
  bool all_uniform = true;
  for (size_t f = 0; f < files.size(); ++f) {
    cloud.files.push_back(files[f]);
    cloud.file_first_point.push_back(cloud.point_count);
    io::LasReader reader(files[f]);
    const io::LasHeader& header = reader.header();
    if (header.has_rgb && header.rgb_uniform) {
      const auto& c = *header.rgb_uniform;
      STIPPLE_WARN_ONCE(
          "{}: the RGB of the first {} points is {},{},{} for every one: --color auto colours by "
          "elevation instead (--color rgb shows it)",
          files[f].string(), header.rgb_probed, c[0], c[1], c[2]);
    }
    all_uniform = all_uniform && header.has_rgb && header.rgb_uniform.has_value();
    if (options.sample > 0) {
      // This file's share of the sample, by its points.
      const uint64_t want =
          total > 0 ? std::max<uint64_t>(1, options.sample * header.point_count / total) : 0;
      read_las_sample(reader, want, [&](io::PointBatch& b) {
        if (enu)
          for (auto& p : b.positions) p = enu->from_geodetic(p);
        append_batch(cloud, b, header.rgb_bits, options.chunk_points);
        progress.advance(b.size());
      });
      continue;
    }
    while (true) {
      batch.clear();
      size_t n = reader.read(batch, options.chunk_points);
      if (n == 0) break;
      if (enu)
        for (auto& p : batch.positions) p = enu->from_geodetic(p);
      append_batch(cloud, batch, header.rgb_bits, options.chunk_points);
      progress.advance(n);
    }
    if (reader.points_read() != header.point_count)
      STIPPLE_WARN("{}: header says {} points, read {}", files[f].string(), header.point_count,
                   reader.points_read());
  }
  progress.finish();
  cloud.attributes.rgb_uniform = cloud.attributes.has_rgb && all_uniform;
  finish_cloud(cloud);
  return cloud;
}

}  // namespace stipple::pc

#include "stipple/pointcloud/profile.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>

#include <fmt/format.h>

#include "selection.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/clip.hpp"
#include "stipple/renderer/png.hpp"

namespace stipple::pc {

double ProfileLine::length() const {
  double total = 0;
  for (size_t i = 1; i < vertices.size(); ++i) total += glm::length(vertices[i] - vertices[i - 1]);
  return total;
}

std::optional<ProfileLine::Hit> ProfileLine::locate(const glm::dvec2& p) const {
  double best = std::numeric_limits<double>::infinity(), along = 0, offset = 0, start = 0;
  for (size_t i = 0; i + 1 < vertices.size(); ++i) {
    const glm::dvec2 a = vertices[i], d = vertices[i + 1] - a, w = p - a;
    const double l2 = glm::dot(d, d), l = std::sqrt(l2);
    const double t = l2 > 0 ? std::clamp(glm::dot(w, d) / l2, 0.0, 1.0) : 0.0;
    const glm::dvec2 q = a + t * d;
    const double dist = glm::length(p - q);
    if (dist < best) {
      best = dist;
      along = start + t * l;
      const double cross = d.x * w.y - d.y * w.x;
      offset = cross >= 0 ? dist : -dist;
    }
    start += l;
  }
  if (!(best <= width / 2)) return std::nullopt;
  return Hit{along, offset};
}

ProfileLine parse_profile_line(const std::string& text, double width) {
  ProfileLine line;
  std::vector<double> v;
  size_t start = 0;
  while (true) {
    const size_t comma = text.find(',', start);
    const std::string part = text.substr(start, comma == std::string::npos ? comma : comma - start);
    size_t used = 0;
    double x = 0;
    try {
      x = std::stod(part, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != part.size() || !std::isfinite(x))
      fail("--line '{}': '{}' is not a finite number", text, part);
    v.push_back(x);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (v.size() < 4 || v.size() % 2 != 0)
    fail("--line '{}': expected 'x0,y0,x1,y1[,x2,y2...]' (an even count, at least 4), got {}", text,
         v.size());
  for (size_t i = 0; i < v.size(); i += 2) line.vertices.emplace_back(v[i], v[i + 1]);
  if (!(width > 0) || !std::isfinite(width)) fail("--width {}: must be a positive number", width);
  line.width = width;
  if (!(line.length() > 0)) fail("--line '{}': the line has no length", text);
  return line;
}

namespace {

// 1, 2 or 5 times a power of ten, near range / 8.
double nice_step(double range) {
  if (!(range > 0)) return 1.0;
  const double raw = range / 8.0;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (raw <= m * p) return m * p;
  return 10.0 * p;
}

constexpr double kMarginX = 0.02, kMarginY = 0.05;

}  // namespace

ProfileFrame make_profile_frame(double length, glm::dvec2 z_range, double z_origin,
                                const glm::uvec2& size) {
  ProfileFrame f;
  f.length = std::max(length, 1e-9);
  if (!(z_range.y > z_range.x)) z_range = {z_range.x - 0.5, z_range.x + 0.5};
  f.z_range = z_range;
  f.z_origin = z_origin;
  f.grid_step = {nice_step(f.length), nice_step(z_range.y - z_range.x)};
  f.pixels_per_unit_x = size.x * (1 - 2 * kMarginX) / f.length;
  f.pixels_per_unit_z = size.y * (1 - 2 * kMarginY) / (z_range.y - z_range.x);
  return f;
}

glm::dvec2 ProfileFrame::to_pixel(double along, double z, const glm::uvec2& size) const {
  return {size.x * kMarginX + along * pixels_per_unit_x,
          size.y * (1 - kMarginY) - (z - z_range.x) * pixels_per_unit_z};
}

glm::dvec2 ProfileFrame::from_pixel(const glm::dvec2& pixel, const glm::uvec2& size) const {
  return {(pixel.x - size.x * kMarginX) / pixels_per_unit_x,
          z_range.x + (size.y * (1 - kMarginY) - pixel.y) / pixels_per_unit_z};
}

namespace {

// The colour modes on the CPU for the cross-section image, mirroring point_colors.wgsl (the
// ramps both GPU paths use) and point_color in point_common.wgsl.
glm::vec3 elevation_ramp(float t_in) {
  static constexpr glm::vec3 stops[5] = {{0.15f, 0.15f, 0.6f},
                                         {0.1f, 0.6f, 0.8f},
                                         {0.3f, 0.75f, 0.3f},
                                         {0.95f, 0.85f, 0.2f},
                                         {0.85f, 0.2f, 0.1f}};
  const float t = std::clamp(t_in, 0.0f, 1.0f) * 4.0f;
  const int i = std::min(int(t), 3);
  return stops[i] + (stops[i + 1] - stops[i]) * (t - float(i));
}

glm::vec3 return_rgb(uint32_t number, uint32_t count) {
  if (count <= 1) return glm::vec3(240, 200, 60) / 255.0f;       // single return
  if (number <= 1) return glm::vec3(220, 60, 50) / 255.0f;       // first of many
  if (number >= count) return glm::vec3(40, 110, 230) / 255.0f;  // last of many
  return glm::vec3(60, 190, 80) / 255.0f;                        // intermediate
}

uint32_t pack_unorm(const glm::vec3& c) {
  auto q = [](float x) { return uint32_t(std::lround(std::clamp(x, 0.0f, 1.0f) * 255.0f)); };
  return q(c.r) | q(c.g) << 8 | q(c.b) << 16 | 0xff000000u;
}

uint32_t shade_sample(const PointShading& s, const ProfileSample& p, double z) {
  switch (s.mode) {
    case ColorMode::Rgb:
      return p.rgba | 0xff000000u;
    case ColorMode::Intensity: {
      const double span = std::max(s.intensity_range.y - s.intensity_range.x, 1e-9);
      return pack_unorm(
          glm::vec3(float((double(p.attributes & 0xffffu) - s.intensity_range.x) / span)));
    }
    case ColorMode::Classification:
      return pack_unorm(
          classification_palette()[std::min<uint32_t>((p.attributes >> 16) & 0xffu, 31)]);
    case ColorMode::ReturnNumber:
      return pack_unorm(return_rgb((p.attributes >> 24) & 0xfu, p.attributes >> 28));
    case ColorMode::Constant:
      return pack_unorm(s.constant_color);
    default: {
      const double span = std::max(s.elevation_range.y - s.elevation_range.x, 1e-9);
      return pack_unorm(elevation_ramp(float((z - s.elevation_range.x) / span)));
    }
  }
}

// An image being drawn: samples may come in blocks (the CLI's spill file); the per-pixel depth
// (the sample's offset: the nearest wins, as a depth test would) carries across them.
struct ProfileCanvas {
  glm::uvec2 size;
  const ProfileFrame& frame;
  PointShading shading;
  int radius;
  gpu::Image image;
  std::vector<float> depth;

  ProfileCanvas(const ProfileFrame& f, const ProfileImageOptions& o,
                const CloudAttributes& attributes)
      : size(std::max(o.width, 16u), std::max(o.height, 16u)),
        frame(f),
        radius(std::max(0, o.point_radius)) {
    image = {size.x, size.y, std::vector<uint8_t>(size_t(size.x) * size.y * 4)};
    depth.assign(size_t(size.x) * size.y, std::numeric_limits<float>::infinity());
    shading.mode = resolve_color_mode(attributes, o.color);
    shading.elevation_range = frame.z_range;
    shading.intensity_range = attributes.intensity_percentiles;
    const uint32_t bg =
        pack_rgba(uint8_t(o.background.r * 255 + 0.5f), uint8_t(o.background.g * 255 + 0.5f),
                  uint8_t(o.background.b * 255 + 0.5f));
    for (uint32_t y = 0; y < size.y; ++y)
      for (uint32_t x = 0; x < size.x; ++x) put(x, y, bg);
    // Grid lines at round steps of distance and height.
    const uint32_t grid = pack_rgba(60, 64, 72);
    for (double a = 0; a <= frame.length + 1e-9; a += frame.grid_step.x) {
      const long x = std::lround(frame.to_pixel(a, frame.z_range.x, size).x);
      if (x >= 0 && x < long(size.x))
        for (uint32_t y = 0; y < size.y; ++y) put(uint32_t(x), y, grid);
    }
    for (double z = std::ceil(frame.z_range.x / frame.grid_step.y) * frame.grid_step.y;
         z <= frame.z_range.y + 1e-9; z += frame.grid_step.y) {
      const long y = std::lround(frame.to_pixel(0, z, size).y);
      if (y >= 0 && y < long(size.y))
        for (uint32_t x = 0; x < size.x; ++x) put(x, uint32_t(y), grid);
    }
  }

  void put(uint32_t x, uint32_t y, uint32_t rgba) {
    std::memcpy(&image.rgba[(size_t(y) * size.x + x) * 4], &rgba, 4);
  }

  void draw(const std::vector<ProfileSample>& samples) {
    for (const ProfileSample& s : samples) {
      const double z = frame.z_origin + double(s.height);
      const glm::dvec2 px = frame.to_pixel(double(s.along), z, size);
      const long cx = std::lround(px.x), cy = std::lround(px.y);
      const uint32_t color = shade_sample(shading, s, z);
      for (long y = cy - radius; y <= cy + radius; ++y)
        for (long x = cx - radius; x <= cx + radius; ++x) {
          if (x < 0 || y < 0 || x >= long(size.x) || y >= long(size.y)) continue;
          const size_t i = size_t(y) * size.x + size_t(x);
          if (s.offset >= depth[i]) continue;
          depth[i] = s.offset;
          put(uint32_t(x), uint32_t(y), color);
        }
    }
  }
};

}  // namespace

gpu::Image draw_profile(const std::vector<ProfileSample>& samples, const ProfileFrame& frame,
                        const ProfileImageOptions& o, const CloudAttributes& attributes) {
  ProfileCanvas canvas(frame, o, attributes);
  canvas.draw(samples);
  return std::move(canvas.image);
}

const char* profile_csv_header() {
  return "distance,x,y,z,offset,intensity,classification,return_number,number_of_returns,"
         "gps_time,point_source_id,red,green,blue,scan_angle,user_data";
}

namespace {

// The corridor's points for the image, spilled to an anonymous temporary file so that memory
// stays bounded whatever the corridor holds.
class SampleSpill {
 public:
  SampleSpill() : file_(std::tmpfile()) {
    if (!file_) fail("cannot create a temporary file for the profile: {}", std::strerror(errno));
    buffer_.reserve(kBuffer);
  }
  ~SampleSpill() { std::fclose(file_); }
  SampleSpill(const SampleSpill&) = delete;
  SampleSpill& operator=(const SampleSpill&) = delete;

  void add(const ProfileSample& s) {
    buffer_.push_back(s);
    if (buffer_.size() == kBuffer) flush();
  }
  // Calls `f` with consecutive blocks of every sample added.
  template <typename F>
  void each_block(F f) {
    flush();
    std::rewind(file_);
    std::vector<ProfileSample> block(kBuffer);
    while (true) {
      const size_t n = std::fread(block.data(), sizeof(ProfileSample), block.size(), file_);
      if (n == 0) break;
      block.resize(n);
      f(block);
      block.resize(kBuffer);
    }
    if (std::ferror(file_)) fail("cannot read the profile's temporary file back");
  }

 private:
  void flush() {
    if (buffer_.empty()) return;
    if (std::fwrite(buffer_.data(), sizeof(ProfileSample), buffer_.size(), file_) != buffer_.size())
      fail("cannot write the profile's temporary file: {}", std::strerror(errno));
    buffer_.clear();
  }
  static constexpr size_t kBuffer = 1 << 16;
  std::FILE* file_;
  std::vector<ProfileSample> buffer_;
};

void check_folder(const std::filesystem::path& path) {
  const std::filesystem::path parent =
      path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
  std::error_code ec;
  if (!std::filesystem::is_directory(parent, ec))
    fail("{}: the folder {} does not exist", path.string(), parent.string());
}

}  // namespace

ProfileResult run_profile(const ProfileJob& job) {
  if (job.line.vertices.size() < 2) fail("a profile needs a line of at least two points");
  if (!(job.line.width > 0)) fail("a profile needs a positive width");
  if (job.png.empty() && job.csv.empty() && job.las.empty())
    fail("a profile needs at least one output (an image, a CSV or a LAS file)");
  detail::StreamOptions stream;
  stream.inputs = job.inputs;
  stream.filter = job.filter;
  stream.region = job.region;
  stream.enu_origin = job.enu_origin;
  stream.progress = job.progress;
  stream.points_done = job.points_done;
  stream.label = "profiling";
  const std::vector<io::LasHeader> headers = detail::read_headers(stream);
  for (const auto& out : {job.png, job.csv, job.las}) {
    if (out.empty()) continue;
    check_folder(out);
    std::error_code ec;
    for (const auto& in : job.inputs)
      if (std::filesystem::equivalent(in, out, ec))
        fail("{}: the output would overwrite the input {}", out.string(), in.string());
  }

  std::unique_ptr<io::LasWriter> las;
  if (!job.las.empty())
    las = std::make_unique<io::LasWriter>(job.las, clip_output_options(headers, job.las));
  std::unique_ptr<AtomicFile> csv_file;
  std::ofstream csv;
  if (!job.csv.empty()) {
    csv_file = std::make_unique<AtomicFile>(job.csv);
    csv.open(csv_file->temp_path(), std::ios::binary | std::ios::trunc);
    if (!csv) fail("{}: cannot create: {}", job.csv.string(), std::strerror(errno));
    csv << profile_csv_header() << '\n';
  }
  SampleSpill spill;
  const double z_origin = headers.front().offset.z;
  ProfileResult result;
  result.length = job.line.length();
  glm::dvec2 z_range(std::numeric_limits<double>::infinity(),
                     -std::numeric_limits<double>::infinity());
  glm::dvec2 intensity_range = z_range;
  bool all_rgb = true;
  for (const auto& h : headers) all_rgb &= h.has_rgb;

  detail::StreamCounts counts;
  io::PointBatch corridor;
  std::vector<uint8_t> keep;
  fmt::memory_buffer rows;
  detail::stream_inputs(
      stream, headers, counts,
      [&](io::PointBatch& batch, const detail::Selection& selection, const io::LasHeader& header) {
        keep.assign(batch.size(), 0);
        size_t kept = 0;
        for (size_t i = 0; i < batch.size(); ++i) {
          const glm::dvec3 p = selection.local(batch.positions[i]);
          const auto hit = job.line.locate({p.x, p.y});
          if (!hit) continue;
          keep[i] = 1;
          ++kept;
          z_range = {std::min(z_range.x, p.z), std::max(z_range.y, p.z)};
          const double in = batch.intensity.empty() ? 0.0 : batch.intensity[i];
          intensity_range = {std::min(intensity_range.x, in), std::max(intensity_range.y, in)};
          spill.add({float(hit->along), float(p.z - z_origin), float(hit->offset),
                     batch_rgba(batch, i, header.rgb_bits), batch_attributes(batch, i)});
          if (csv_file) {
            const glm::dvec3& s = batch.positions[i];
            const glm::u16vec3 c = batch.rgb.empty() ? glm::u16vec3(0) : batch.rgb[i];
            fmt::format_to(
                std::back_inserter(rows), "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
                hit->along, s.x, s.y, s.z, hit->offset, unsigned(in),
                unsigned(batch.classification.empty() ? 1 : batch.classification[i]),
                unsigned(batch.return_number.empty() ? 1 : batch.return_number[i]),
                unsigned(batch.number_of_returns.empty() ? 1 : batch.number_of_returns[i]),
                batch.gps_time.empty() ? 0.0 : batch.gps_time[i],
                unsigned(batch.point_source_id.empty() ? 0 : batch.point_source_id[i]), c.r, c.g,
                c.b, batch.scan_angle.empty() ? 0.0f : batch.scan_angle[i],
                unsigned(batch.user_data.empty() ? 0 : batch.user_data[i]));
          }
        }
        result.points_in_corridor += kept;
        if (csv_file && rows.size() > 0) {
          csv.write(rows.data(), std::streamsize(rows.size()));
          rows.clear();
          if (!csv) fail("{}: write failed", job.csv.string());
        }
        if (las && kept > 0) {
          if (kept != batch.size()) batch.compact(keep);
          las->write(batch);
        }
      });
  result.points_read = counts.points_read;
  if (result.points_in_corridor > 0) result.z_range = z_range;

  // The image first: outputs are committed last, all together.
  if (!job.png.empty()) {
    const glm::uvec2 size(job.image.width, job.image.height);
    result.frame = make_profile_frame(
        result.length, result.points_in_corridor ? z_range : glm::dvec2(0.0, 1.0), z_origin, size);
    CloudAttributes attributes;
    attributes.has_rgb = all_rgb;
    attributes.has_intensity = attributes.has_classification = attributes.has_returns = true;
    if (result.points_in_corridor > 0 && intensity_range.y > intensity_range.x)
      attributes.intensity_percentiles = intensity_range;
    ProfileCanvas canvas(result.frame, job.image, attributes);
    spill.each_block([&](const std::vector<ProfileSample>& block) { canvas.draw(block); });
    const gpu::Image& image = canvas.image;
    gpu::write_png(job.png, image);
  }
  if (las) las->close();
  if (csv_file) {
    csv.close();
    if (!csv) fail("{}: write failed", job.csv.string());
    csv_file->commit();
  }
  return result;
}

std::vector<ProfileSample> profile_samples(const PointCloud& cloud, const ProfileLine& line,
                                           const PointFilter& filter, const ClipRegion& region,
                                           double z_origin) {
  std::vector<ProfileSample> out;
  // Chunks whose bounds lie outside the corridor's box are skipped.
  glm::dvec2 lo(std::numeric_limits<double>::infinity()), hi(-lo);
  for (const glm::dvec2& v : line.vertices) {
    lo = glm::min(lo, v);
    hi = glm::max(hi, v);
  }
  lo -= line.width / 2;
  hi += line.width / 2;
  for (const PointChunk& chunk : cloud.chunks) {
    if (chunk.bounds.empty()) continue;
    const glm::dvec3 a = y_up_to_z_up(chunk.bounds.min), b = y_up_to_z_up(chunk.bounds.max);
    if (std::max(a.x, b.x) < lo.x || std::min(a.x, b.x) > hi.x || std::max(a.y, b.y) < lo.y ||
        std::min(a.y, b.y) > hi.y)
      continue;
    for (size_t i = 0; i < chunk.vertices.size(); ++i) {
      const PointChunk::Vertex& v = chunk.vertices[i];
      const glm::dvec3 p = y_up_to_z_up(chunk.origin + glm::dvec3(v.x, v.y, v.z));
      const auto hit = line.locate({p.x, p.y});
      if (!hit || !chunk_point_shown(chunk, i, filter, region)) continue;
      out.push_back(
          {float(hit->along), float(p.z - z_origin), float(hit->offset), v.rgba, v.attributes});
    }
  }
  return out;
}

}  // namespace stipple::pc

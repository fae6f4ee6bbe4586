#pragma once
// A LAS file built byte by byte from the specification (LAS 1.2 and 1.4, point formats 0-3, 6
// and 7), for tests that need what other writers produce and ours never does: several Extra
// Bytes VLRs, space-padded strings, GeoTIFF keys beside a WKT, odd header fields. Everything
// the reader must cope with is a plain field here; nothing is checked.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace stipple::test {

struct LasVlr {
  std::string user_id;
  uint16_t record_id = 0;
  std::vector<uint8_t> data;
  std::string description;
};

struct LasPoint {
  double x = 0, y = 0, z = 0;
  uint16_t intensity = 0;
  uint16_t r = 0, g = 0, b = 0;
  uint8_t classification = 1;
  std::vector<uint8_t> extra;  // the record's extra bytes (extra_bytes_per_point of them)
};

struct LasFile {
  uint8_t version_minor = 2;  // 2 or 4
  uint8_t point_format = 3;   // 0-3 (1.2), 6 or 7 (1.4)
  uint16_t global_encoding = 0;
  // Written as is into the 32-byte fields: longer strings are cut, shorter ones NUL-padded.
  std::string system_identifier = "test";
  std::string generating_software = "las_bytes.hpp";
  std::array<double, 3> scale{0.01, 0.01, 0.01}, offset{0, 0, 0};
  std::vector<LasVlr> vlrs;
  uint16_t extra_bytes_per_point = 0;
  std::vector<LasPoint> points;
};

namespace las_bytes_detail {
template <typename T>
void put(std::vector<uint8_t>& b, size_t at, T v) {
  std::memcpy(b.data() + at, &v, sizeof v);
}
inline void put_string(std::vector<uint8_t>& b, size_t at, const std::string& s, size_t n) {
  std::memcpy(b.data() + at, s.data(), std::min(s.size(), n));
}
inline uint16_t format_size(uint8_t format) {
  static constexpr uint16_t kSizes[8] = {20, 28, 26, 34, 0, 0, 30, 36};
  return format < 8 ? kSizes[format] : 0;
}
}  // namespace las_bytes_detail

inline std::vector<uint8_t> las_bytes(const LasFile& f) {
  using las_bytes_detail::put;
  const bool v14 = f.version_minor >= 4;
  const uint16_t header_size = v14 ? 375 : 227;
  const uint16_t record = las_bytes_detail::format_size(f.point_format) + f.extra_bytes_per_point;
  size_t vlr_bytes = 0;
  for (const auto& v : f.vlrs) vlr_bytes += 54 + v.data.size();
  const size_t offset_to_points = header_size + vlr_bytes;
  std::vector<uint8_t> b(offset_to_points + f.points.size() * record, 0);
  std::memcpy(b.data(), "LASF", 4);
  put<uint16_t>(b, 6, f.global_encoding);
  b[24] = 1;
  b[25] = f.version_minor;
  las_bytes_detail::put_string(b, 26, f.system_identifier, 32);
  las_bytes_detail::put_string(b, 58, f.generating_software, 32);
  put<uint16_t>(b, 90, 1);
  put<uint16_t>(b, 92, 2024);
  put<uint16_t>(b, 94, header_size);
  put<uint32_t>(b, 96, uint32_t(offset_to_points));
  put<uint32_t>(b, 100, uint32_t(f.vlrs.size()));
  b[104] = f.point_format;
  put<uint16_t>(b, 105, record);
  const bool legacy_count = f.point_format < 6;
  put<uint32_t>(b, 107, legacy_count ? uint32_t(f.points.size()) : 0u);
  put<uint32_t>(b, 111, legacy_count ? uint32_t(f.points.size()) : 0u);  // all first returns
  std::array<double, 3> lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const auto& p : f.points) {
    const double v[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], v[k]), hi[k] = std::max(hi[k], v[k]);
  }
  if (f.points.empty()) lo = hi = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    put<double>(b, 131 + 8 * k, f.scale[k]);
    put<double>(b, 155 + 8 * k, f.offset[k]);
    put<double>(b, 179 + 16 * k, hi[k]);
    put<double>(b, 187 + 16 * k, lo[k]);
  }
  if (v14) {
    put<uint64_t>(b, 247, f.points.size());
    put<uint64_t>(b, 255, f.points.size());
  }
  size_t at = header_size;
  for (const auto& v : f.vlrs) {
    las_bytes_detail::put_string(b, at + 2, v.user_id, 16);
    put<uint16_t>(b, at + 18, v.record_id);
    put<uint16_t>(b, at + 20, uint16_t(v.data.size()));
    las_bytes_detail::put_string(b, at + 22, v.description, 32);
    std::memcpy(b.data() + at + 54, v.data.data(), v.data.size());
    at += 54 + v.data.size();
  }
  for (const auto& p : f.points) {
    const double v[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k)
      put<int32_t>(b, at + 4 * k, int32_t(std::lround((v[k] - f.offset[k]) / f.scale[k])));
    put<uint16_t>(b, at + 12, p.intensity);
    int rgb = -1;
    if (f.point_format < 6) {
      b[at + 14] = 0x09;  // return 1 of 1
      b[at + 15] = p.classification;
      rgb = f.point_format == 2 ? 20 : f.point_format == 3 ? 28 : -1;
    } else {
      b[at + 14] = 0x11;  // return 1 of 1
      b[at + 16] = p.classification;
      rgb = f.point_format == 7 ? 30 : -1;
    }
    if (rgb >= 0) {
      put<uint16_t>(b, at + rgb, p.r);
      put<uint16_t>(b, at + rgb + 2, p.g);
      put<uint16_t>(b, at + rgb + 4, p.b);
    }
    const size_t base = las_bytes_detail::format_size(f.point_format);
    if (!p.extra.empty())  // an empty vector's data() may be null, which memcpy may not take
      std::memcpy(b.data() + at + base, p.extra.data(),
                  std::min<size_t>(p.extra.size(), f.extra_bytes_per_point));
    at += record;
  }
  return b;
}

inline void write_las(const std::filesystem::path& path, const LasFile& f) {
  const std::vector<uint8_t> b = las_bytes(f);
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

// One Extra Bytes descriptor (LAS 1.4 R15 table 24): 192 bytes, the type and name set.
inline std::vector<uint8_t> extra_bytes_descriptor(uint8_t data_type, const std::string& name) {
  std::vector<uint8_t> d(192, 0);
  d[2] = data_type;
  las_bytes_detail::put_string(d, 4, name, 32);
  return d;
}

// A GeoKeyDirectoryTag VLR payload (LASF_Projection 34735) of inline keys {id, value}.
inline std::vector<uint8_t> geokey_directory(
    const std::vector<std::pair<uint16_t, uint16_t>>& keys) {
  std::vector<uint16_t> words = {1, 1, 0, uint16_t(keys.size())};
  for (auto [id, value] : keys) words.insert(words.end(), {id, 0, 1, value});
  std::vector<uint8_t> out(words.size() * 2);
  std::memcpy(out.data(), words.data(), out.size());
  return out;
}

// A random-free cloud: n points on a grid covering `size` metres from (x0, y0), z rising.
inline std::vector<LasPoint> grid_points(size_t n, double x0, double y0, double size,
                                         double z0 = 100.0) {
  std::vector<LasPoint> out(n);
  const size_t side = size_t(std::ceil(std::sqrt(double(n))));
  for (size_t i = 0; i < n; ++i) {
    out[i].x = x0 + size * double(i % side) / double(side);
    out[i].y = y0 + size * double(i / side) / double(side);
    out[i].z = z0 + 0.1 * size * double(i % 7) / 7.0;
    out[i].intensity = uint16_t(100 * (i % 50));
  }
  return out;
}

}  // namespace stipple::test

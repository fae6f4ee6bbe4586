#include "stipple/io/splat_readers.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>

#include "splat_detail.hpp"
#include "stipple/io/fetch.hpp"

namespace stipple::io {
namespace splat_detail {

float half_to_float(uint16_t h) {
  const uint32_t sign = uint32_t(h >> 15) << 31;
  uint32_t exponent = (h >> 10) & 0x1f, mantissa = h & 0x3ff, bits;
  if (exponent == 0x1f) {
    bits = sign | 0x7f800000u | (mantissa << 13);
  } else if (exponent != 0) {
    bits = sign | ((exponent + 112) << 23) | (mantissa << 13);
  } else if (mantissa == 0) {
    bits = sign;
  } else {  // subnormal: normalise
    exponent = 113;
    while (!(mantissa & 0x400)) {
      mantissa <<= 1;
      --exponent;
    }
    bits = sign | (exponent << 23) | ((mantissa & 0x3ff) << 13);
  }
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

void resize_splats(SplatSet& s, size_t n, int degree, const SplatLimits& limits,
                   std::string_view name) {
  if (n > limits.max_splats)
    fail("{}: {} splats exceed the limit of {}", name, n, limits.max_splats);
  if (degree < 0 || degree > 3) fail("{}: SH degree {} is not 0..3", name, degree);
  s.sh_degree = degree;
  s.positions.assign(n, glm::vec3(0.0f));
  s.scales.assign(n, glm::vec3(0.0f));
  s.rotations.assign(n, glm::vec4(0, 0, 0, 1));
  s.opacities.assign(n, 0.0f);
  s.sh_dc.assign(n, glm::vec3(0.0f));
  s.sh_rest.assign(n * s.rest_count(), glm::vec3(0.0f));
}

glm::vec4 unit_quaternion(float x, float y, float z, float w) {
  const float len = std::sqrt(x * x + y * y + z * z + w * w);
  if (!(len > 0.0f) || !std::isfinite(len)) return {0, 0, 0, 1};
  return {x / len, y / len, z / len, w / len};
}

void check_values(SplatSet& s, std::string_view name) {
  for (size_t i = 0; i < s.size(); ++i) {
    const glm::vec3 p = s.positions[i], sc = s.scales[i], dc = s.sh_dc[i];
    if (!std::isfinite(p.x + p.y + p.z + sc.x + sc.y + sc.z + dc.x + dc.y + dc.z) ||
        !std::isfinite(s.opacities[i]))
      fail("{}: splat {} has a value that is not finite", name, i);
    // Linear scales stored as such (.splat, .ksplat, glTF) may carry a sign the covariance
    // ignores; opacity stored linearly may leave [0, 1].
    s.scales[i] = glm::abs(sc);
    s.opacities[i] = std::clamp(s.opacities[i], 0.0f, 1.0f);
  }
  for (const glm::vec3& c : s.sh_rest)
    if (!std::isfinite(c.x + c.y + c.z)) fail("{}: an SH coefficient is not finite", name);
}

}  // namespace splat_detail

namespace {

using namespace splat_detail;

std::string lower_extension(std::string_view path) {
  std::string p = uri_path(std::string(path));
  size_t slash = p.find_last_of("/\\"), dot = p.rfind('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return {};
  std::string ext = p.substr(dot);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

bool ends_with(std::string_view s, std::string_view tail) {
  return s.size() >= tail.size() && s.substr(s.size() - tail.size()) == tail;
}

std::vector<uint8_t> file_head(const std::string& path_or_url, size_t bytes) {
  if (is_url(path_or_url)) {
    FetchOptions options;
    options.max_retries = 1;
    // A server that does not answer ranges, or a file shorter than the range, is an error here:
    // then the whole (short) file is read instead.
    try {
      return fetch(range_uri(path_or_url, 0, bytes), options);
    } catch (const Error&) {
      options.max_bytes = bytes * 16;
      return fetch(path_or_url, options);
    }
  }
  std::ifstream in(uri_path(path_or_url), std::ios::binary);
  if (!in) return {};
  std::vector<uint8_t> head(bytes);
  in.read(reinterpret_cast<char*>(head.data()), std::streamsize(bytes));
  head.resize(size_t(in.gcount()));
  return head;
}

}  // namespace

bool is_splat_tileset_path(std::string_view path_or_url) {
  if (lower_extension(path_or_url) != ".json") return false;
  const std::string p = uri_path(std::string(path_or_url));
  if (ends_with(p, "/meta.json") || p == "meta.json") return false;
  try {
    return is_splat_tileset_json(file_head(std::string(path_or_url), 64 * 1024));
  } catch (const Error&) {
    return false;
  }
}

bool is_splat_path(std::string_view path_or_url) {
  const std::string ext = lower_extension(path_or_url);
  if (ext == ".splat" || ext == ".ksplat" || ext == ".spz" || ext == ".sog") return true;
  if (ext == ".json") {
    std::string p = uri_path(std::string(path_or_url));
    if (ends_with(p, "/meta.json") || p == "meta.json") return true;
    if (is_url(path_or_url)) return false;
    try {
      return is_splat_tileset_json(file_head(std::string(path_or_url), 64 * 1024));
    } catch (const Error&) {
      return false;
    }
  }
  if (ext != ".ply") return false;
  try {
    return is_splat_ply_header(file_head(std::string(path_or_url), 64 * 1024));
  } catch (const Error&) {
    return false;
  }
}

namespace {

SplatSet decode_unchecked(std::span<const uint8_t> bytes, std::string_view name,
                          const SplatLimits& limits) {
  const std::string ext = lower_extension(name);
  auto starts = [&](const char* magic, size_t n) {
    return bytes.size() >= n && std::memcmp(bytes.data(), magic, n) == 0;
  };
  if (starts("ply\n", 4) || starts("ply\r\n", 5)) return decode_ply_splats(bytes, name, limits);
  if (starts("glTF", 4)) return decode_splats_glb(bytes, name, limits);
  if (starts("NGSP", 4) || starts("\x1f\x8b", 2)) return decode_spz(bytes, name, limits);
  if (starts("PK\x03\x04", 4)) {
    if (!sog_supported()) fail("{}: SOG files need libwebp, which this build lacks", name);
    return decode_sog_zip(bytes, name, limits);
  }
  if (ext == ".ksplat") return decode_ksplat(bytes, name, limits);
  if (ext == ".splat") return decode_dot_splat(bytes, name, limits);
  if (ext == ".spz") return decode_spz(bytes, name, limits);
  if (ext == ".json") {
    fail("{}: an unbundled SOG (meta.json) is read with read_splats, which resolves its images",
         name);
  }
  fail("{}: not a splat file this reader knows (PLY, SPZ, .splat, .ksplat, SOG or glTF)", name);
}

}  // namespace

namespace {

// SplatSet::transform leads to a Y-up frame. SPZ stores x right, y up, z back and glTF is Y up:
// they stay as they are. The PLY family (INRIA and PlayCanvas PLY, .splat, .ksplat, SOG) stores
// what its trainers wrote, OpenCV/COLMAP's x right, y down, z forward: half a turn about x.
void orient_y_up(SplatSet& s) {
  if (s.format.starts_with("SPZ") || s.format.starts_with("glTF")) return;
  s.transform = glm::dmat4(glm::dvec4(1, 0, 0, 0), glm::dvec4(0, -1, 0, 0), glm::dvec4(0, 0, -1, 0),
                           glm::dvec4(0, 0, 0, 1)) *
                s.transform;
}

}  // namespace

SplatSet decode_splats(std::span<const uint8_t> bytes, std::string_view name,
                       const SplatLimits& limits) {
  SplatSet s = decode_unchecked(bytes, name, limits);
  check_values(s, name);
  orient_y_up(s);
  return s;
}

SplatSet read_splats(const std::string& path_or_url, const SplatLimits& limits) {
  FetchOptions options;
  options.max_bytes = std::max<uint64_t>(options.max_bytes, 4ull << 30);
  options.reject_html = true;
  std::vector<uint8_t> bytes = fetch(path_or_url, options);
  const std::string ext = lower_extension(path_or_url);
  if (ext == ".json" && is_splat_tileset_json(bytes)) {
    SplatSet s = read_splat_tileset(path_or_url, bytes, limits);
    check_values(s, path_or_url);
    return s;
  }
  if (ext == ".json") {
    if (!sog_supported()) fail("{}: SOG files need libwebp, which this build lacks", path_or_url);
    SplatSet s = decode_sog_meta(
        bytes, path_or_url,
        [&](const std::string& file) { return fetch(resolve_uri(path_or_url, file), options); },
        limits);
    check_values(s, path_or_url);
    orient_y_up(s);
    return s;
  }
  return decode_splats(bytes, path_or_url, limits);
}

}  // namespace stipple::io

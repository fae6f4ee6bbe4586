// Niantic's SPZ. Versions 1-3: a 16-byte NGSP header and the attribute arrays one after another
// (positions, alphas, colours, scales, rotations, SH), the whole gzipped (some writers leave the
// payload bare); version 4: a 32-byte header, a table of (compressed, decompressed) sizes and
// one zstd stream per attribute array, in the same order.
#include <algorithm>
#include <array>

#include "splat_detail.hpp"

namespace stipple::io::splat_detail {
namespace {

constexpr uint32_t kMagic = 0x5053474e;  // "NGSP"

struct SpzHeader {
  uint32_t version = 0, count = 0;
  int degree = 0, fractional_bits = 0, flags = 0;
};

size_t sh_coefficients(int degree) {
  return size_t((degree + 1) * (degree + 1) - 1);
}

// The byte sizes of the attribute arrays, in file order.
std::array<uint64_t, 6> array_sizes(const SpzHeader& h) {
  const uint64_t n = h.count;
  return {n * (h.version == 1 ? 6 : 9),     n, n * 3, n * 3, n * (h.version >= 3 ? 4 : 3),
          n * sh_coefficients(h.degree) * 3};
}

SpzHeader parse_header(const uint8_t* p, std::string_view name, const SplatLimits& limits) {
  SpzHeader h;
  if (u32(p) != kMagic) fail("{}: not SPZ (no NGSP magic)", name);
  h.version = u32(p + 4);
  h.count = u32(p + 8);
  h.degree = p[12];
  h.fractional_bits = p[13];
  h.flags = p[14];
  if (h.version < 1 || h.version > 4) fail("{}: SPZ version {} is not supported", name, h.version);
  if (h.degree > 3) fail("{}: SPZ SH degree {} is not 0..3", name, h.degree);
  if (h.fractional_bits > 24)
    fail("{}: SPZ fractional bits {} are more than a 24-bit position holds", name,
         h.fractional_bits);
  if (h.count > limits.max_splats)
    fail("{}: {} splats exceed the limit of {}", name, h.count, limits.max_splats);
  return h;
}

// arrays[k] holds array k of array_sizes(h), checked to be of that size.
SplatSet decode_arrays(const SpzHeader& h, const std::array<std::span<const uint8_t>, 6>& a,
                       std::string_view name, const SplatLimits& limits) {
  SplatSet s;
  s.format = fmt::format("SPZ v{}", h.version);
  resize_splats(s, h.count, h.degree, limits, name);
  const float scale = 1.0f / float(1u << h.fractional_bits);
  const size_t rc = s.rest_count();
  for (size_t i = 0; i < s.size(); ++i) {
    if (h.version == 1) {
      const uint8_t* p = a[0].data() + i * 6;
      s.positions[i] = {half_to_float(u16(p)), half_to_float(u16(p + 2)),
                        half_to_float(u16(p + 4))};
    } else {
      const uint8_t* p = a[0].data() + i * 9;
      for (int k = 0; k < 3; ++k) {
        int32_t fixed = int32_t(uint32_t(p[3 * k]) | (uint32_t(p[3 * k + 1]) << 8) |
                                (uint32_t(p[3 * k + 2]) << 16));
        if (fixed & 0x800000) fixed -= 0x1000000;  // sign-extend 24 bits
        s.positions[i][k] = float(fixed) * scale;
      }
    }
    s.opacities[i] = float(a[1][i]) / 255.0f;
    for (int k = 0; k < 3; ++k) {
      s.sh_dc[i][k] = (float(a[2][i * 3 + k]) / 255.0f - 0.5f) / 0.15f;
      s.scales[i][k] = std::exp(float(a[3][i * 3 + k]) / 16.0f - 10.0f);
    }
    if (h.version >= 3) {
      // Smallest three: two bits for the largest component's index (x, y, z, w), then three
      // 10-bit values (9 bits magnitude over [0, 1/sqrt2], 1 sign bit), last component lowest.
      uint32_t v = u32(a[4].data() + i * 4);
      const uint32_t largest = v >> 30;
      float q[4], sum = 0.0f;
      for (int k = 3; k >= 0; --k) {
        if (uint32_t(k) == largest) continue;
        const float mag = float(v & 0x1ff) / 511.0f * 0.70710678f;
        q[k] = (v >> 9) & 1 ? -mag : mag;
        sum += q[k] * q[k];
        v >>= 10;
      }
      q[largest] = std::sqrt(std::max(0.0f, 1.0f - sum));
      s.rotations[i] = unit_quaternion(q[0], q[1], q[2], q[3]);
    } else {
      const uint8_t* r = a[4].data() + i * 3;
      glm::vec3 xyz = glm::vec3(r[0], r[1], r[2]) / 127.5f - 1.0f;
      const float w = std::sqrt(std::max(0.0f, 1.0f - glm::dot(xyz, xyz)));
      s.rotations[i] = unit_quaternion(xyz.x, xyz.y, xyz.z, w);
    }
    // SH coefficient-major, (R, G, B) per coefficient, x * 128 + 128.
    const uint8_t* sh = a[5].data() + i * rc * 3;
    for (size_t k = 0; k < rc; ++k)
      for (int c = 0; c < 3; ++c)
        s.sh_rest[i * rc + k][c] = (float(sh[k * 3 + size_t(c)]) - 128.0f) / 128.0f;
  }
  return s;
}

SplatSet decode_packed(std::span<const uint8_t> payload, std::string_view name,
                       const SplatLimits& limits) {
  if (payload.size() < 16) fail("{}: too short for an SPZ header", name);
  SpzHeader h = parse_header(payload.data(), name, limits);
  if (h.version == 4) fail("{}: SPZ v4 inside gzip is not a known layout", name);
  std::array<std::span<const uint8_t>, 6> arrays;
  size_t at = 16;
  const auto sizes = array_sizes(h);
  for (int k = 0; k < 6; ++k) {
    if (sizes[k] > payload.size() - at)
      fail("{}: SPZ payload of {} bytes is too short for {} splats", name, payload.size(), h.count);
    arrays[k] = payload.subspan(at, size_t(sizes[k]));
    at += size_t(sizes[k]);
  }
  return decode_arrays(h, arrays, name, limits);
}

SplatSet decode_v4(std::span<const uint8_t> bytes, std::string_view name,
                   const SplatLimits& limits) {
  if (bytes.size() < 32) fail("{}: too short for an SPZ v4 header", name);
  SpzHeader h = parse_header(bytes.data(), name, limits);
  const uint32_t streams = bytes[15], toc = u32(bytes.data() + 16);
  const uint32_t expected = h.degree > 0 ? 6 : 5;
  if (streams != expected)
    fail("{}: SPZ v4 has {} streams, SH degree {} needs {}", name, streams, h.degree, expected);
  if (toc < 32 || toc > bytes.size() || (bytes.size() - toc) / 16 < streams)
    fail("{}: SPZ v4 table of contents at {} lies outside the file", name, toc);
  const auto sizes = array_sizes(h);
  std::array<std::vector<uint8_t>, 6> owned;
  std::array<std::span<const uint8_t>, 6> arrays;
  uint64_t at = toc + uint64_t(streams) * 16;
  for (uint32_t k = 0; k < streams; ++k) {
    const uint64_t compressed = u64(bytes.data() + toc + 16 * k);
    const uint64_t size = u64(bytes.data() + toc + 16 * k + 8);
    if (size != sizes[k])
      fail("{}: SPZ v4 stream {} decompresses to {} bytes, {} splats need {}", name, k, size,
           h.count, sizes[k]);
    if (compressed > bytes.size() - at)
      fail("{}: SPZ v4 stream {} ({} bytes at {}) runs past the end of the file", name, k,
           compressed, at);
    owned[k] = zstd_exact(bytes.subspan(size_t(at), size_t(compressed)), size_t(size), name);
    arrays[k] = owned[k];
    at += compressed;
  }
  return decode_arrays(h, arrays, name, limits);
}

}  // namespace

SplatSet decode_spz(std::span<const uint8_t> bytes, std::string_view name,
                    const SplatLimits& limits) {
  if (bytes.size() >= 8 && u32(bytes.data()) == kMagic) {
    if (u32(bytes.data() + 4) == 4) return decode_v4(bytes, name, limits);
    SplatSet s = decode_packed(bytes, name, limits);  // a bare payload (not gzipped)
    s.format += " (not gzipped)";
    return s;
  }
  if (bytes.size() < 2 || bytes[0] != 0x1f || bytes[1] != 0x8b)
    fail("{}: not SPZ (neither gzip nor NGSP)", name);
  // The payload's size follows from its header: 16 bytes and at most 75 bytes a splat (v3, SH 3).
  const size_t cap = std::min(limits.max_inflated_bytes, 16 + limits.max_splats * 75);
  return decode_packed(inflate_all(bytes, cap, name), name, limits);
}

}  // namespace stipple::io::splat_detail

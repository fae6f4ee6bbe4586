#include "stipple/tiler/spz_writer.hpp"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "stipple/core/error.hpp"

namespace stipple::tiler {

namespace {

uint8_t byte_of(float v) {
  if (!(v == v)) return 0;  // NaN
  return uint8_t(std::clamp(std::lround(v), 0L, 255L));
}

// Niantic's SH quantisation: x * 128 + 128 rounded to a multiple of 2^(8 - bits), clamped.
uint8_t sh_byte(float x, int bits) {
  const long bucket = 1L << (8 - bits);
  long q = std::lround(double(x) * 128.0) + 128;
  q = (q + bucket / 2) / bucket * bucket;
  return uint8_t(std::clamp(q, 0L, 255L));
}

void put_u32(uint8_t* p, uint32_t v) {
  std::memcpy(p, &v, 4);
}

}  // namespace

int spz_fractional_bits(double extent) {
  // |v| * 2^bits must stay below 2^23 (signed 24 bits), with a bit of margin for rounding.
  int bits = 12;
  while (bits > 0 && extent * std::ldexp(1.0, bits) >= std::ldexp(1.0, 23) - 2) --bits;
  return bits;
}

std::vector<uint8_t> spz_payload(const io::SplatSet& s, const SpzOptions& options) {
  const size_t n = s.size(), rc = s.rest_count();
  if (n > 0xffffffffu) fail("SPZ holds at most 2^32 - 1 splats, not {}", n);
  double extent = 0;
  for (const glm::vec3& p : s.positions)
    extent =
        std::max({extent, double(std::abs(p.x)), double(std::abs(p.y)), double(std::abs(p.z))});
  const int bits =
      options.fractional_bits >= 0 ? options.fractional_bits : spz_fractional_bits(extent);
  std::vector<uint8_t> out(16 + n * (9 + 1 + 3 + 3 + 3 + rc * 3));
  uint8_t* h = out.data();
  put_u32(h, 0x5053474e);  // "NGSP"
  put_u32(h + 4, 2);
  put_u32(h + 8, uint32_t(n));
  h[12] = uint8_t(s.sh_degree);
  h[13] = uint8_t(bits);
  h[14] = 0;  // flags: not antialiased
  h[15] = 0;
  uint8_t* pos = out.data() + 16;
  uint8_t* alpha = pos + n * 9;
  uint8_t* colour = alpha + n;
  uint8_t* scale = colour + n * 3;
  uint8_t* rot = scale + n * 3;
  uint8_t* sh = rot + n * 3;
  const double step = std::ldexp(1.0, bits);
  const long limit = (1L << 23) - 1;
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      const long fixed = std::clamp(std::lround(double(s.positions[i][k]) * step), -limit, limit);
      const uint32_t u = uint32_t(fixed) & 0xffffff;
      pos[i * 9 + size_t(3 * k)] = uint8_t(u);
      pos[i * 9 + size_t(3 * k) + 1] = uint8_t(u >> 8);
      pos[i * 9 + size_t(3 * k) + 2] = uint8_t(u >> 16);
    }
    alpha[i] = byte_of(s.opacities[i] * 255.0f);
    for (int k = 0; k < 3; ++k) {
      colour[i * 3 + size_t(k)] = byte_of(s.sh_dc[i][k] * (0.15f * 255.0f) + 127.5f);
      const float sc = s.scales[i][k];
      scale[i * 3 + size_t(k)] = sc > 0 ? byte_of((std::log(sc) + 10.0f) * 16.0f) : 0;
    }
    glm::vec4 q = s.rotations[i];
    const float len = std::sqrt(glm::dot(q, q));
    q = len > 0 && std::isfinite(len) ? q / len : glm::vec4(0, 0, 0, 1);
    if (q.w < 0) q = -q;  // v2 stores x, y, z; w is recovered as the non-negative root
    for (int k = 0; k < 3; ++k) rot[i * 3 + size_t(k)] = byte_of(q[k] * 127.5f + 127.5f);
    for (size_t k = 0; k < rc; ++k)
      for (int c = 0; c < 3; ++c)
        sh[(i * rc + k) * 3 + size_t(c)] = sh_byte(s.sh_rest[i * rc + k][c], k < 3 ? 5 : 4);
  }
  return out;
}

std::vector<uint8_t> gzip_bytes(const std::vector<uint8_t>& data, int level) {
  z_stream z{};
  if (deflateInit2(&z, level, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    fail("cannot start zlib's deflate");
  std::vector<uint8_t> out(deflateBound(&z, uLong(data.size())));
  z.next_in = const_cast<Bytef*>(data.data());
  z.avail_in = uInt(data.size());
  z.next_out = out.data();
  z.avail_out = uInt(out.size());
  const int rc = deflate(&z, Z_FINISH);
  const size_t produced = out.size() - z.avail_out;
  deflateEnd(&z);
  if (rc != Z_STREAM_END) fail("zlib's deflate failed ({})", rc);
  out.resize(produced);
  return out;
}

std::vector<uint8_t> encode_spz(const io::SplatSet& splats, const SpzOptions& options) {
  const std::vector<uint8_t> payload = spz_payload(splats, options);
  if (payload.size() >= (size_t(1) << 32))
    fail("an SPZ payload of {} bytes is more than one zlib call takes", payload.size());
  return gzip_bytes(payload, options.gzip_level);
}

}  // namespace stipple::tiler

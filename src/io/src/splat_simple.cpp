// The two headerless-or-fixed-layout web formats: antimatter15's .splat (32 bytes a splat) and
// GaussianSplats3D's .ksplat (a 4096-byte header, 1024-byte section headers, then per section
// its bucket table and splat records in one of three compression levels).
#include <algorithm>

#include "splat_detail.hpp"

namespace stipple::io::splat_detail {

SplatSet decode_dot_splat(std::span<const uint8_t> bytes, std::string_view name,
                          const SplatLimits& limits) {
  if (bytes.size() % 32 != 0)
    fail("{}: {} bytes are not a whole number of 32-byte .splat records", name, bytes.size());
  SplatSet s;
  s.format = "antimatter15 .splat";
  resize_splats(s, bytes.size() / 32, 0, limits, name);
  for (size_t i = 0; i < s.size(); ++i) {
    const uint8_t* r = bytes.data() + i * 32;
    s.positions[i] = {f32(r), f32(r + 4), f32(r + 8)};
    s.scales[i] = {f32(r + 12), f32(r + 16), f32(r + 20)};  // linear already
    s.sh_dc[i] = (glm::vec3(r[24], r[25], r[26]) / 255.0f - 0.5f) / kShC0;
    s.opacities[i] = float(r[27]) / 255.0f;
    // Rotation bytes are q * 128 + 128, real part first.
    auto q = [&](int k) { return (float(r[28 + k]) - 128.0f) / 128.0f; };
    s.rotations[i] = unit_quaternion(q(1), q(2), q(3), q(0));
  }
  return s;
}

SplatSet decode_ksplat(std::span<const uint8_t> bytes, std::string_view name,
                       const SplatLimits& limits) {
  constexpr size_t kHeader = 4096, kSectionHeader = 1024;
  if (bytes.size() < kHeader) fail("{}: too short for a .ksplat header", name);
  const uint8_t* h = bytes.data();
  if (h[0] != 0 || h[1] < 1)
    fail("{}: .ksplat version {}.{} is not supported (0.1 and later 0.x)", name, h[0], h[1]);
  const uint32_t max_sections = u32(h + 4);
  const uint32_t total_splats = u32(h + 16);
  const uint16_t level = u16(h + 20);
  float sh_min = f32(h + 36), sh_max = f32(h + 40);
  if (sh_min == 0.0f && sh_max == 0.0f) sh_min = -1.5f, sh_max = 1.5f;  // the writer's default
  if (level > 2) fail("{}: .ksplat compression level {} is not 0, 1 or 2", name, level);
  if (max_sections > (bytes.size() - kHeader) / kSectionHeader)
    fail("{}: .ksplat names {} sections, more than the file holds", name, max_sections);
  if (total_splats > limits.max_splats)
    fail("{}: {} splats exceed the limit of {}", name, total_splats, limits.max_splats);

  struct Section {
    uint32_t count, bucket_size, bucket_count, full_buckets, partial_buckets, scale_range;
    float half_block;
    int degree;
    size_t lengths_at, buckets_at, data_at, stride, bucket_bytes;
  };
  std::vector<Section> sections;
  size_t at = kHeader + size_t(max_sections) * kSectionHeader;
  uint64_t splats = 0;
  int degree = 0;
  for (uint32_t k = 0; k < max_sections; ++k) {
    const uint8_t* sh = h + kHeader + k * kSectionHeader;
    Section sec{};
    sec.count = u32(sh);
    const uint32_t max_count = u32(sh + 4);
    sec.bucket_size = u32(sh + 8);
    sec.bucket_count = u32(sh + 12);
    sec.half_block = f32(sh + 16) * 0.5f;
    const uint16_t bucket_bytes = u16(sh + 20);
    sec.scale_range = u32(sh + 24) ? u32(sh + 24) : 32767;
    sec.full_buckets = u32(sh + 32);
    sec.partial_buckets = u32(sh + 36);
    sec.degree = u16(sh + 40);
    if (sec.degree > 3) fail("{}: .ksplat section {} has SH degree {}", name, k, sec.degree);
    if (sec.count > max_count)
      fail("{}: .ksplat section {} holds {} splats, more than its capacity {}", name, k, sec.count,
           max_count);
    static constexpr int kShComponents[4] = {0, 9, 24, 45};
    sec.stride = level == 0 ? 44 + size_t(kShComponents[sec.degree]) * 4
                            : 24 + size_t(kShComponents[sec.degree]) * (level == 1 ? 2 : 1);
    if (level > 0 && (bucket_bytes < 12 || sec.bucket_size == 0))
      fail("{}: .ksplat section {} has an invalid bucket layout", name, k);
    const uint64_t lengths = uint64_t(sec.partial_buckets) * 4;
    const uint64_t buckets = uint64_t(bucket_bytes) * sec.bucket_count;
    const uint64_t data = uint64_t(max_count) * sec.stride;
    if (lengths + buckets + data > bytes.size() - std::min(bytes.size(), at))
      fail("{}: .ksplat section {} ({} splats) runs past the end of the file", name, k, max_count);
    sec.bucket_bytes = bucket_bytes;
    sec.lengths_at = at;
    sec.buckets_at = at + lengths;
    sec.data_at = at + lengths + buckets;
    if (level > 0 && uint64_t(sec.full_buckets) + sec.partial_buckets > sec.bucket_count)
      fail("{}: .ksplat section {} has more full and partial buckets than buckets", name, k);
    at += size_t(lengths + buckets + data);
    splats += sec.count;
    degree = std::max(degree, sec.degree);
    sections.push_back(sec);
  }
  if (splats != total_splats)
    fail("{}: .ksplat sections hold {} splats, its header says {}", name, splats, total_splats);

  SplatSet s;
  s.format = fmt::format(".ksplat (compression level {})", level);
  resize_splats(s, size_t(splats), degree, limits, name);
  const size_t rc = s.rest_count();
  size_t out = 0;
  for (const Section& sec : sections) {
    const size_t src_rest = size_t((sec.degree + 1) * (sec.degree + 1) - 1);
    // Partially filled buckets follow the full ones; their lengths come first in the section.
    size_t bucket = 0, bucket_end = size_t(sec.full_buckets) * sec.bucket_size, partial = 0;
    const float factor = sec.half_block / float(sec.scale_range);
    for (size_t i = 0; i < sec.count; ++i, ++out) {
      const uint8_t* r = bytes.data() + sec.data_at + i * sec.stride;
      const uint8_t* rest;
      if (level == 0) {
        s.positions[out] = {f32(r), f32(r + 4), f32(r + 8)};
        s.scales[out] = {f32(r + 12), f32(r + 16), f32(r + 20)};
        s.rotations[out] = unit_quaternion(f32(r + 28), f32(r + 32), f32(r + 36), f32(r + 24));
        r += 40;
        rest = r + 4;
      } else {
        if (i < size_t(sec.full_buckets) * sec.bucket_size) {
          bucket = i / sec.bucket_size;
        } else {
          while (i >= bucket_end) {
            if (partial >= sec.partial_buckets)
              fail("{}: .ksplat splat {} lies in no bucket", name, out);
            bucket = sec.full_buckets + partial;
            bucket_end += u32(bytes.data() + sec.lengths_at + partial * 4);
            ++partial;
          }
        }
        if (bucket >= sec.bucket_count) fail("{}: .ksplat splat {} lies in no bucket", name, out);
        const uint8_t* b = bytes.data() + sec.buckets_at + bucket * sec.bucket_bytes;
        for (int k = 0; k < 3; ++k)
          s.positions[out][k] =
              (float(u16(r + 2 * k)) - float(sec.scale_range)) * factor + f32(b + 4 * k);
        for (int k = 0; k < 3; ++k) s.scales[out][k] = half_to_float(u16(r + 6 + 2 * k));
        s.rotations[out] = unit_quaternion(half_to_float(u16(r + 14)), half_to_float(u16(r + 16)),
                                           half_to_float(u16(r + 18)), half_to_float(u16(r + 12)));
        r += 20;
        rest = r + 4;
      }
      s.sh_dc[out] = (glm::vec3(r[0], r[1], r[2]) / 255.0f - 0.5f) / kShC0;
      s.opacities[out] = float(r[3]) / 255.0f;
      // SH coefficient-major, (R, G, B) per coefficient.
      for (size_t k = 0; k < std::min(src_rest, rc); ++k)
        for (int c = 0; c < 3; ++c) {
          const size_t j = k * 3 + size_t(c);
          float x = level == 0   ? f32(rest + 4 * j)
                    : level == 1 ? half_to_float(u16(rest + 2 * j))
                                 : sh_min + float(rest[j]) / 255.0f * (sh_max - sh_min);
          s.sh_rest[out * rc + k][c] = x;
        }
    }
  }
  return s;
}

}  // namespace stipple::io::splat_detail

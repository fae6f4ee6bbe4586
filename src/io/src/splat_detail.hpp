#pragma once
// Shared pieces of the splat readers (splat_*.cpp): the per-format decoders that
// splat_readers.cpp dispatches to, little-endian loads from checked offsets, and the activation
// functions of the INRIA layout.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "stipple/core/error.hpp"
#include "stipple/io/splat_readers.hpp"

namespace stipple::io::splat_detail {

constexpr float kShC0 = 0.28209479177387814f;

// Loads at an offset the caller has checked against the span's size.
inline uint32_t u32(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}
inline uint16_t u16(const uint8_t* p) {
  uint16_t v;
  std::memcpy(&v, p, 2);
  return v;
}
inline float f32(const uint8_t* p) {
  float v;
  std::memcpy(&v, p, 4);
  return v;
}
inline uint64_t u64(const uint8_t* p) {
  uint64_t v;
  std::memcpy(&v, p, 8);
  return v;
}
float half_to_float(uint16_t h);

inline float sigmoid(float x) {
  return 1.0f / (1.0f + std::exp(-x));
}

// Sizes every array for n splats of SH degree `degree` (0..3), after checking n against limits.
void resize_splats(SplatSet& s, size_t n, int degree, const SplatLimits& limits,
                   std::string_view name);
// Every value finite (else an Error), linear scales made non-negative, opacities clamped to
// [0, 1]: what every reader returns.
void check_values(SplatSet& s, std::string_view name);
// Normalises a quaternion given (x, y, z, w); a zero or non-finite one becomes the identity.
glm::vec4 unit_quaternion(float x, float y, float z, float w);

// Whole-stream decompression into at most `cap` bytes (more is an error naming `name`).
// gzip or zlib framing (told apart by the header).
std::vector<uint8_t> inflate_all(std::span<const uint8_t> in, size_t cap, std::string_view name);
// Raw deflate (zip entries), exactly `size` bytes expected.
std::vector<uint8_t> inflate_raw(std::span<const uint8_t> in, size_t size, std::string_view name);
// The same without zlib (splat_deflate.cpp): gzip/zlib-wrapped, or raw when `raw`. The web
// build's inflate_all and inflate_raw.
std::vector<uint8_t> inflate_portable(std::span<const uint8_t> in, bool raw, size_t cap,
                                      std::string_view name);
// One zstd frame (or several) decompressing to exactly `size` bytes.
std::vector<uint8_t> zstd_exact(std::span<const uint8_t> in, size_t size, std::string_view name);

// Per-format decoders (the bytes are a whole file).
bool is_splat_ply_header(std::span<const uint8_t> bytes);
SplatSet decode_ply_splats(std::span<const uint8_t> bytes, std::string_view name,
                           const SplatLimits& limits);
SplatSet decode_dot_splat(std::span<const uint8_t> bytes, std::string_view name,
                          const SplatLimits& limits);
SplatSet decode_ksplat(std::span<const uint8_t> bytes, std::string_view name,
                       const SplatLimits& limits);
// SPZ: gzip-wrapped (v1-v3), the bare NGSP payload, or v4 (NGSP header and zstd streams).
SplatSet decode_spz(std::span<const uint8_t> bytes, std::string_view name,
                    const SplatLimits& limits);
bool sog_supported();
SplatSet decode_sog_zip(std::span<const uint8_t> bytes, std::string_view name,
                        const SplatLimits& limits);
// An unbundled SOG: meta.json's bytes and a reader of the files it names.
SplatSet decode_sog_meta(std::span<const uint8_t> meta, std::string_view name,
                         const std::function<std::vector<uint8_t>(const std::string&)>& file,
                         const SplatLimits& limits);

// Splat tilesets (splat_tileset.cpp): whether the head of a .json file is a tileset of splat
// content, and the cut of one read as a set (read_splats' tileset.json case).
bool is_splat_tileset_json(std::span<const uint8_t> head);
SplatSet read_splat_tileset(const std::string& path, std::span<const uint8_t> tileset_json,
                            const SplatLimits& limits);

}  // namespace stipple::io::splat_detail

// libFuzzer target: arbitrary bytes through the splat readers (PLY, compressed PLY, SPZ v1-v4,
// .splat, .ksplat, SOG zip, glTF) and the web build's DEFLATE decoder (io-private: included by
// path). Formats without a magic number are chosen by the name's extension, which the input's
// last byte picks; any stipple::Error is a correct rejection.
#include <cstddef>
#include <cstdint>
#include <span>

#include <spdlog/spdlog.h>

#include "../../src/io/src/splat_detail.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/splat_readers.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::span<const uint8_t> bytes(data, size);
  stipple::io::SplatLimits limits;
  limits.max_splats = 1'000'000;  // keeps allocations within the fuzzer's RSS limit
  limits.max_inflated_bytes = 64 << 20;
  static const char* const kNames[] = {"fuzz.splat", "fuzz.ksplat", "fuzz.spz",
                                       "fuzz.ply",   "fuzz.sog",    "fuzz.glb"};
  const char* name = size ? kNames[data[size - 1] % 6] : kNames[0];
  try {
    (void)stipple::io::decode_splats(bytes, name, limits);
  } catch (const stipple::Error&) {
  }
  try {
    if (size >= 4 && data[0] == 'g') (void)stipple::io::decode_splats_glb(bytes, name, limits);
  } catch (const stipple::Error&) {
  }
  try {
    // gzip inputs (the SPZ seeds) whole; 'z' and a raw or wrapped stream.
    if (size >= 2 && data[0] == 0x1f && data[1] == 0x8b)
      (void)stipple::io::splat_detail::inflate_portable(bytes, false, 1 << 24, "fuzz.gz");
    else if (size >= 1 && data[0] == 'z')
      (void)stipple::io::splat_detail::inflate_portable(bytes.subspan(1), size % 2, 1 << 24,
                                                        "fuzz.gz");
  } catch (const stipple::Error&) {
  }
  return 0;
}

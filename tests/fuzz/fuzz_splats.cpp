// libFuzzer target: arbitrary bytes through the splat readers (PLY, compressed PLY, SPZ v1-v4,
// .splat, .ksplat, SOG zip, glTF). Formats without a magic number are chosen by the name's
// extension, which the input's last byte picks; any stipple::Error is a correct rejection.
#include <cstddef>
#include <cstdint>
#include <span>

#include <spdlog/spdlog.h>

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
  return 0;
}

// libFuzzer target: arbitrary bytes through the 3D Tiles content decoders (pnts with Draco,
// glb point primitives with meshopt, subtree files). The first byte picks the decoder so one
// corpus covers all three; any stipple::Error is a correct rejection.
#include <cstddef>
#include <cstdint>
#include <span>

#include <spdlog/spdlog.h>

#include "stipple/core/error.hpp"
#include "stipple/io/glb_points.hpp"
#include "stipple/io/pnts.hpp"
#include "stipple/io/subtree.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::span<const uint8_t> bytes(data, size);
  stipple::io::DecodeLimits limits;
  limits.max_points = 1'000'000;  // keeps allocations within the fuzzer's RSS limit
  limits.max_json_bytes = 1 << 20;
  try {
    if (size >= 4 && bytes[0] == 'p') {
      (void)stipple::io::decode_pnts(bytes, "fuzz.pnts", limits);
    } else if (size >= 4 && bytes[0] == 's') {
      (void)stipple::io::decode_subtree(bytes, "fuzz.subtree", 4, 3);
      (void)stipple::io::decode_subtree(bytes, "fuzz.subtree", 8, 2);
    } else {
      (void)stipple::io::decode_glb_points(bytes, "fuzz.glb", limits);
    }
  } catch (const stipple::Error&) {
  }
  return 0;
}

// libFuzzer target: arbitrary bytes through the in-memory LAS reader (header, VLRs, EVLRs, CRS,
// extra bytes and every point record, read in small chunks). Any stipple::Error is a correct
// rejection; crashes, sanitizer reports, hangs and huge allocations are bugs. LAZ decoding (the
// LASzip library) is left out unless built with -DSTIPPLE_FUZZ_LAZ: by default compressed inputs
// stop after header and VLR parsing.
#include <cstddef>
#include <cstdint>
#include <span>

#include <spdlog/spdlog.h>

#include "stipple/core/error.hpp"
#include "stipple/io/las.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);  // warnings about odd headers would flood the output
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
#ifdef STIPPLE_FUZZ_LAZ
    constexpr bool kDecodeLaz = true;
#else
    constexpr bool kDecodeLaz = false;
#endif
    stipple::io::LasReader reader(std::span<const uint8_t>(data, size), "fuzz.las", kDecodeLaz);
    const stipple::io::LasHeader& h = reader.header();
    (void)h.crs.describe();
    stipple::io::PointBatch batch;
    while (reader.read(batch, 997) > 0) {
      if (batch.size() > 5000) batch.clear();
    }
  } catch (const stipple::Error&) {
  }
  return 0;
}

// libFuzzer target: arbitrary bytes as a pointlet cache (header, sources, table), then reads of
// its pointlets (whole with their checksums, and prefixes as the virtual memory system reads
// them). Any stipple::Error is a correct rejection; crashes, sanitizer reports, hangs and huge
// allocations are bugs.
#include <cstddef>
#include <cstdint>
#include <vector>

#include <spdlog/spdlog.h>

#include "stipple/core/error.hpp"
#include "stipple/pointcloud/pointlets.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    auto cache = stipple::pc::PointletCache::from_memory(std::vector<uint8_t>(data, data + size),
                                                         "fuzz.pointlets");
    const auto& table = cache.pointlets();
    std::vector<stipple::pc::PointletRecord> out;
    for (uint32_t i = 0; i < table.size() && i < 16; ++i) {
      try {
        for (const auto& r : cache.read_verified(i)) (void)cache.position(table[i], r);
      } catch (const stipple::Error&) {
      }
      out.clear();
      cache.read(i, 0, table[i].count / 2, out);
    }
  } catch (const stipple::Error&) {
  }
  return 0;
}

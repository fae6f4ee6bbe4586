// libFuzzer target: arbitrary bytes through the in-memory LAS reader (header, VLRs, EVLRs, CRS,
// extra bytes, the first and the last point records). Any stipple::Error is a correct
// rejection; crashes, sanitizer reports, hangs and huge allocations are bugs. LAZ decoding (the
// LASzip library) is left out unless built with -DSTIPPLE_FUZZ_LAZ: by default compressed inputs
// stop after header and VLR parsing.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

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
    // The first points and the last, not all: every record goes through the same decoder, and
    // decoding the 2,000 of a 64 KiB real-file head was most of the time of a run. Seeking to
    // the last ones still reaches the end of the data (a file shorter than its header says) and
    // covers seek() too.
    stipple::io::PointBatch batch;
    reader.read(batch, 97);
    if (h.point_count > 2 * 97) reader.seek(h.point_count - 97);
    while (reader.read(batch, 97) > 0) {
    }
    // The positions-only path (the tiler's counting pass) over the same first records: the
    // same count and the same positions as the full decode.
    reader.seek(0);
    std::vector<glm::dvec3> positions;
    const size_t got = reader.read_positions(positions, 97);
    if (got > batch.size() || positions.size() != got) __builtin_trap();
    for (size_t i = 0; i < got; ++i)
      if (!(positions[i] == batch.positions[i]) && positions[i] == positions[i]) __builtin_trap();
    // The drawn-fields path (the pointlet cache's reader): the same count and fields again.
    reader.seek(0);
    std::vector<stipple::io::DrawnPoint> drawn(97);
    if (reader.read_drawn(drawn) != got) __builtin_trap();
    for (size_t i = 0; i < got; ++i)
      if (drawn[i].intensity != batch.intensity[i] ||
          drawn[i].classification != batch.classification[i])
        __builtin_trap();
  } catch (const stipple::Error&) {
  }
  return 0;
}

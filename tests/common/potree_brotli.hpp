#pragma once
// Brotli at PotreeConverter's quality (6): how the tests write a Potree 2.0 cloud's BROTLI nodes
// (potree_writer.hpp's `brotli` argument), in tiles3d/potree_test.cpp and the stipple_write_potree
// program alike. Needs libbrotlienc (the tests link it; the engine itself only decodes).
#include <brotli/encode.h>

#include <cstdint>
#include <stdexcept>
#include <vector>

namespace stipple::test {

inline std::vector<uint8_t> potree_brotli(const std::vector<uint8_t>& in) {
  std::vector<uint8_t> out(BrotliEncoderMaxCompressedSize(in.size()));
  size_t size = out.size();
  if (!BrotliEncoderCompress(6, BROTLI_DEFAULT_WINDOW, BROTLI_DEFAULT_MODE, in.size(), in.data(),
                             &size, out.data()))
    throw std::runtime_error("brotli failed");
  out.resize(size);
  return out;
}

}  // namespace stipple::test

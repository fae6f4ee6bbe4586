// The web build's DEFLATE decoder (src/io/src/splat_deflate.cpp, private to io: included by
// path) against zlib's encoder: stored, fixed and dynamic blocks, the gzip, zlib and raw
// wrappers, and damaged streams failing with an Error.
#include <gtest/gtest.h>
#include <zlib.h>

#include <random>
#include <string>
#include <vector>

#include "../../src/io/src/splat_detail.hpp"
#include "stipple/core/error.hpp"

using stipple::Error;
using stipple::io::splat_detail::inflate_portable;

namespace {

// window_bits: 15 zlib, 31 gzip, -15 raw.
std::vector<uint8_t> deflate_with_zlib(const std::vector<uint8_t>& data, int level, int window_bits,
                                       int strategy = Z_DEFAULT_STRATEGY) {
  z_stream z{};
  EXPECT_EQ(deflateInit2(&z, level, Z_DEFLATED, window_bits, 8, strategy), Z_OK);
  std::vector<uint8_t> out(deflateBound(&z, uLong(data.size())) + 64);
  z.next_in = const_cast<Bytef*>(data.data());
  z.avail_in = uInt(data.size());
  z.next_out = out.data();
  z.avail_out = uInt(out.size());
  EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

// Text-like data with repeats (dynamic blocks, long matches) and a random tail (literals).
std::vector<uint8_t> sample(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<uint8_t> v;
  const std::string words[] = {"splat ", "gaussian ", "opacity ", "scale ", "rotation "};
  while (v.size() < n / 2) {
    const std::string& w = words[rng() % 5];
    v.insert(v.end(), w.begin(), w.end());
  }
  while (v.size() < n) v.push_back(uint8_t(rng()));
  return v;
}

}  // namespace

TEST(SplatDeflate, MatchesZlibOnEveryBlockTypeAndWrapper) {
  for (size_t n : {size_t(0), size_t(1), size_t(1000), size_t(300000)}) {
    const auto data = sample(n, uint32_t(n));
    for (int level : {0, 1, 6, 9})
      for (int strategy : {Z_DEFAULT_STRATEGY, Z_FIXED, Z_HUFFMAN_ONLY, Z_RLE}) {
        SCOPED_TRACE(testing::Message()
                     << n << " bytes, level " << level << ", strategy " << strategy);
        EXPECT_EQ(inflate_portable(deflate_with_zlib(data, level, 31, strategy), false, n, "t"),
                  data);
        EXPECT_EQ(inflate_portable(deflate_with_zlib(data, level, 15, strategy), false, n, "t"),
                  data);
        EXPECT_EQ(inflate_portable(deflate_with_zlib(data, level, -15, strategy), true, n, "t"),
                  data);
      }
  }
}

TEST(SplatDeflate, DamagedOrOversizedStreamsAreErrors) {
  const auto data = sample(20000, 7);
  const auto gz = deflate_with_zlib(data, 6, 31);
  // More output than the cap allows.
  EXPECT_THROW(inflate_portable(gz, false, data.size() - 1, "t"), Error);
  // Every truncation fails (the gzip trailer's size is checked).
  for (size_t k = 0; k < gz.size(); k += 97)
    EXPECT_THROW(inflate_portable({gz.data(), k}, false, data.size(), "t"), Error) << k;
  // Overwritten bytes decode to something or fail; none crashes or overruns the cap.
  std::mt19937 rng(3);
  for (int trial = 0; trial < 500; ++trial) {
    auto bad = gz;
    bad[10 + rng() % (bad.size() - 10)] = uint8_t(rng());
    try {
      EXPECT_LE(inflate_portable(bad, false, data.size(), "t").size(), data.size());
    } catch (const Error&) {
    }
  }
  try {
    inflate_portable(std::vector<uint8_t>{1, 2, 3}, false, 10, "name.spz");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("name.spz"), std::string::npos);
  }
}

// A small DEFLATE decoder (RFC 1951, with the gzip and zlib wrappers of RFC 1952 and 1950) for
// the web build, which has no zlib: gzipped SPZ (the payload of glTF's SPZ compression) must
// open in the browser too. Canonical Huffman codes decoded a bit at a time: simple and bounded
// rather than fast. Native builds use zlib and test this decoder against it.
#include <array>

#include "splat_detail.hpp"

namespace stipple::io::splat_detail {
namespace {

constexpr int kMaxBits = 15;

struct Huffman {
  std::array<uint16_t, kMaxBits + 1> count{};
  std::array<uint16_t, 288> symbol{};
};

struct Inflater {
  std::span<const uint8_t> in;
  size_t pos = 0;
  uint32_t bitbuf = 0;
  int bitcnt = 0;
  std::vector<uint8_t> out;
  size_t cap = 0;
  std::string_view name;

  [[noreturn]] void corrupt(const char* what) const {
    fail("{}: compressed data is corrupt or truncated ({})", name, what);
  }

  uint32_t bits(int n) {
    uint32_t v = bitbuf;
    while (bitcnt < n) {
      if (pos >= in.size()) corrupt("ran out of input");
      v |= uint32_t(in[pos++]) << bitcnt;
      bitcnt += 8;
    }
    bitbuf = uint32_t(uint64_t(v) >> n);
    bitcnt -= n;
    return v & ((1u << n) - 1);
  }

  void put(uint8_t b) {
    if (out.size() >= cap) fail("{}: compressed data inflates to more than {} bytes", name, cap);
    out.push_back(b);
  }

  // Builds the canonical code of `lengths`; an over-subscribed set is an error, an incomplete
  // one is allowed (a code that reaches its hole fails in decode).
  void build(Huffman& h, const uint16_t* lengths, int n) {
    h.count.fill(0);
    for (int s = 0; s < n; ++s) ++h.count[lengths[s]];
    int left = 1;
    for (int len = 1; len <= kMaxBits; ++len) {
      left <<= 1;
      left -= h.count[len];
      if (left < 0) corrupt("over-subscribed Huffman code");
    }
    std::array<uint16_t, kMaxBits + 1> offs{};
    for (int len = 1; len < kMaxBits; ++len) offs[len + 1] = offs[len] + h.count[len];
    for (int s = 0; s < n; ++s)
      if (lengths[s] != 0) h.symbol[offs[lengths[s]]++] = uint16_t(s);
  }

  int decode(const Huffman& h) {
    int code = 0, first = 0, index = 0;
    for (int len = 1; len <= kMaxBits; ++len) {
      code |= int(bits(1));
      const int count = h.count[len];
      if (code - count < first) return h.symbol[size_t(index + (code - first))];
      index += count;
      first += count;
      first <<= 1;
      code <<= 1;
    }
    corrupt("invalid Huffman code");
  }

  void stored() {
    bitbuf = 0;
    bitcnt = 0;
    if (in.size() - pos < 4) corrupt("stored block header");
    const uint16_t len = u16(in.data() + pos), nlen = u16(in.data() + pos + 2);
    pos += 4;
    if (uint16_t(~nlen) != len) corrupt("stored block length");
    if (in.size() - pos < len) corrupt("stored block data");
    for (size_t k = 0; k < len; ++k) put(in[pos + k]);
    pos += len;
  }

  void codes(const Huffman& lencode, const Huffman& distcode) {
    static constexpr uint16_t kLenBase[29] = {3,  4,  5,  6,   7,   8,   9,   10,  11, 13,
                                              15, 17, 19, 23,  27,  31,  35,  43,  51, 59,
                                              67, 83, 99, 115, 131, 163, 195, 227, 258};
    static constexpr uint8_t kLenExtra[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2,
                                              2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};
    static constexpr uint16_t kDistBase[30] = {
        1,   2,   3,   4,   5,   7,    9,    13,   17,   25,   33,   49,   65,    97,    129,
        193, 257, 385, 513, 769, 1025, 1537, 2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577};
    static constexpr uint8_t kDistExtra[30] = {0, 0, 0, 0, 1, 1, 2, 2,  3,  3,  4,  4,  5,  5,  6,
                                               6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13};
    for (;;) {
      int symbol = decode(lencode);
      if (symbol < 256) {
        put(uint8_t(symbol));
        continue;
      }
      if (symbol == 256) return;
      symbol -= 257;
      if (symbol >= 29) corrupt("invalid length symbol");
      const size_t len = kLenBase[symbol] + bits(kLenExtra[symbol]);
      const int d = decode(distcode);
      if (d >= 30) corrupt("invalid distance symbol");
      const size_t dist = kDistBase[d] + bits(kDistExtra[d]);
      if (dist > out.size()) corrupt("distance before the start");
      for (size_t k = 0; k < len; ++k) put(out[out.size() - dist]);
    }
  }

  void fixed() {
    static const std::pair<Huffman, Huffman> tables = [] {
      std::pair<Huffman, Huffman> t;
      uint16_t lengths[288];
      for (int s = 0; s < 288; ++s) lengths[s] = s < 144 ? 8 : s < 256 ? 9 : s < 280 ? 7 : 8;
      Inflater builder;
      builder.build(t.first, lengths, 288);
      for (int s = 0; s < 30; ++s) lengths[s] = 5;
      builder.build(t.second, lengths, 30);
      return t;
    }();
    codes(tables.first, tables.second);
  }

  void dynamic() {
    static constexpr uint8_t kOrder[19] = {16, 17, 18, 0, 8,  7, 9,  6, 10, 5,
                                           11, 4,  12, 3, 13, 2, 14, 1, 15};
    const int nlen = int(bits(5)) + 257, ndist = int(bits(5)) + 1, ncode = int(bits(4)) + 4;
    if (nlen > 286 || ndist > 30) corrupt("too many length or distance codes");
    uint16_t lengths[320] = {};
    for (int k = 0; k < ncode; ++k) lengths[kOrder[k]] = uint16_t(bits(3));
    Huffman lencode, distcode;
    build(lencode, lengths, 19);
    int index = 0;
    while (index < nlen + ndist) {
      int symbol = decode(lencode);
      if (symbol < 16) {
        lengths[index++] = uint16_t(symbol);
        continue;
      }
      uint16_t len = 0;
      int repeat;
      if (symbol == 16) {
        if (index == 0) corrupt("repeat with no previous length");
        len = lengths[index - 1];
        repeat = 3 + int(bits(2));
      } else if (symbol == 17) {
        repeat = 3 + int(bits(3));
      } else {
        repeat = 11 + int(bits(7));
      }
      if (index + repeat > nlen + ndist) corrupt("too many code lengths");
      while (repeat--) lengths[index++] = len;
    }
    if (lengths[256] == 0) corrupt("no end-of-block code");
    build(lencode, lengths, nlen);
    build(distcode, lengths + nlen, ndist);
    codes(lencode, distcode);
  }

  void run() {
    int last;
    do {
      last = int(bits(1));
      switch (bits(2)) {
        case 0:
          stored();
          break;
        case 1:
          fixed();
          break;
        case 2:
          dynamic();
          break;
        default:
          corrupt("invalid block type");
      }
    } while (!last);
  }
};

}  // namespace

std::vector<uint8_t> inflate_portable(std::span<const uint8_t> in, bool raw, size_t cap,
                                      std::string_view name) {
  size_t start = 0;
  bool gzip = false;
  if (!raw) {
    if (in.size() >= 18 && in[0] == 0x1f && in[1] == 0x8b) {
      if (in[2] != 8) fail("{}: gzip compression method {} is not deflate", name, in[2]);
      const uint8_t flags = in[3];
      start = 10;
      auto need = [&](size_t n) {
        if (in.size() - start < n) fail("{}: gzip header is truncated", name);
      };
      if (flags & 4) {
        need(2);
        start += 2 + u16(in.data() + start);
      }
      for (int bit : {8, 16})
        if (flags & bit) {
          while (start < in.size() && in[start] != 0) ++start;
          ++start;
        }
      if (flags & 2) start += 2;
      if (start > in.size()) fail("{}: gzip header is truncated", name);
      gzip = true;
    } else if (in.size() >= 2 && (in[0] & 0x0f) == 8 && (in[0] * 256 + in[1]) % 31 == 0) {
      if (in[1] & 0x20) fail("{}: zlib data with a preset dictionary", name);
      start = 2;
    } else {
      fail("{}: compressed data has neither a gzip nor a zlib header", name);
    }
  }
  Inflater z;
  z.in = in.subspan(start);
  z.cap = cap;
  z.name = name;
  z.run();
  if (gzip) {
    // The trailer's size (mod 2^32) checks the length; its CRC-32 is not checked here.
    const size_t end = start + z.pos;
    if (in.size() - end < 8) fail("{}: gzip trailer is truncated", name);
    if (u32(in.data() + end + 4) != uint32_t(z.out.size()))
      fail("{}: gzip data inflates to {} bytes, its trailer says {}", name, z.out.size(),
           u32(in.data() + end + 4));
  }
  return std::move(z.out);
}

}  // namespace stipple::io::splat_detail

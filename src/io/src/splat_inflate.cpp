// Decompression for the splat readers: gzip/zlib and raw deflate through zlib in native builds
// (the web build has no zlib: there splat_deflate.cpp's decoder), zstd on both.
#include <zstd.h>
#ifndef __EMSCRIPTEN__
#include <zlib.h>
#endif

#include "splat_detail.hpp"

namespace stipple::io::splat_detail {

#ifndef __EMSCRIPTEN__
namespace {

// Inflates with windowBits `bits` into a buffer grown as output arrives (so a small hostile
// input cannot make it allocate its claimed size up front), at most `cap` bytes.
std::vector<uint8_t> inflate_bits(std::span<const uint8_t> in, int bits, size_t cap,
                                  std::string_view name) {
  z_stream z{};
  if (inflateInit2(&z, bits) != Z_OK) fail("{}: cannot start zlib", name);
  std::vector<uint8_t> out(std::min<size_t>(cap, std::max<size_t>(in.size() * 4, 4096)));
  z.next_in = const_cast<Bytef*>(in.data());
  size_t in_left = in.size(), produced = 0;
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    if (produced == out.size()) {
      if (out.size() >= cap) {
        inflateEnd(&z);
        fail("{}: compressed data inflates to more than {} bytes", name, cap);
      }
      out.resize(std::min(cap, out.size() * 2));
    }
    const uInt in_chunk = uInt(std::min<size_t>(in_left, 1u << 30));
    const uInt out_chunk = uInt(std::min<size_t>(out.size() - produced, 1u << 30));
    z.avail_in = in_chunk;
    z.next_out = out.data() + produced;
    z.avail_out = out_chunk;
    rc = inflate(&z, Z_NO_FLUSH);
    in_left -= in_chunk - z.avail_in;
    produced += out_chunk - z.avail_out;
    if (rc == Z_BUF_ERROR && in_left == 0 && z.avail_in == 0) {
      inflateEnd(&z);
      fail("{}: compressed data is truncated", name);
    }
    if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) {
      inflateEnd(&z);
      fail("{}: compressed data is corrupt ({})", name, z.msg ? z.msg : "zlib error");
    }
  }
  inflateEnd(&z);
  out.resize(produced);
  return out;
}

}  // namespace

std::vector<uint8_t> inflate_all(std::span<const uint8_t> in, size_t cap, std::string_view name) {
  return inflate_bits(in, 15 + 32, cap, name);  // +32: gzip or zlib header
}

std::vector<uint8_t> inflate_raw(std::span<const uint8_t> in, size_t size, std::string_view name) {
  std::vector<uint8_t> out = inflate_bits(in, -15, size, name);
  if (out.size() != size)
    fail("{}: deflate data inflates to {} bytes, {} expected", name, out.size(), size);
  return out;
}
#else
std::vector<uint8_t> inflate_all(std::span<const uint8_t> in, size_t cap, std::string_view name) {
  return inflate_portable(in, false, cap, name);
}

std::vector<uint8_t> inflate_raw(std::span<const uint8_t> in, size_t size, std::string_view name) {
  std::vector<uint8_t> out = inflate_portable(in, true, size, name);
  if (out.size() != size)
    fail("{}: deflate data inflates to {} bytes, {} expected", name, out.size(), size);
  return out;
}
#endif

std::vector<uint8_t> zstd_exact(std::span<const uint8_t> in, size_t size, std::string_view name) {
  std::vector<uint8_t> out(size);
  const size_t got = ZSTD_decompress(out.data(), out.size(), in.data(), in.size());
  if (ZSTD_isError(got))
    fail("{}: zstd stream cannot be decoded ({})", name, ZSTD_getErrorName(got));
  if (got != size) fail("{}: zstd stream decodes to {} bytes, {} expected", name, got, size);
  return out;
}

}  // namespace stipple::io::splat_detail

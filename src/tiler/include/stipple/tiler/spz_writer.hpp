#pragma once
// Niantic SPZ encoding of a splat set, for the splat tiler's glb content
// (KHR_gaussian_splatting_compression_spz_2, whose payload is gzipped SPZ) and for whole .spz
// files. Version 2 layout, the one cesium-native writes and every SPZ reader takes (CesiumJS's
// spz-loader, io::decode_splats): a 16-byte NGSP header, then positions as 24-bit fixed point
// with `fractional_bits`, alpha byte (opacity * 255), colour bytes (f_dc * 0.15 * 255 + 127.5),
// scale bytes ((ln s + 10) * 16), rotation as three bytes of x, y, z (w made non-negative), and
// the higher SH coefficients coefficient-major as x * 128 + 128, degree 1 kept to 5 bits and
// degrees 2-3 to 4 bits as Niantic's writer does (gzip then finds the repeats). Values beyond a
// field's range are clamped. Positions are taken as they are: the caller centres them (a glb
// node translation) so that they fit 24 bits at the chosen precision.
#include <cstdint>
#include <vector>

#include "stipple/io/splats.hpp"

namespace stipple::tiler {

struct SpzOptions {
  // Position step 2^-fractional_bits; -1: the finest of at most 12 bits (Niantic's default,
  // about 0.24 mm in metres) at which the largest |coordinate| still fits 24 bits.
  int fractional_bits = -1;
  int gzip_level = 6;  // zlib's default level
};

// The fractional bits SpzOptions{-1} chooses for positions whose largest |coordinate| is `extent`.
int spz_fractional_bits(double extent);

// The uncompressed SPZ v2 payload (header and arrays) and its gzip wrapping (a .spz file).
std::vector<uint8_t> spz_payload(const io::SplatSet& splats, const SpzOptions& options = {});
std::vector<uint8_t> encode_spz(const io::SplatSet& splats, const SpzOptions& options = {});

// Raw gzip of `data` (zlib, gzip framing) at `level`.
std::vector<uint8_t> gzip_bytes(const std::vector<uint8_t>& data, int level);

}  // namespace stipple::tiler

#pragma once
// glTF 2.0 binary content for splat tilesets: one mode-POINTS primitive with
// KHR_gaussian_splatting, as CesiumJS 1.145 and io::decode_splats_glb read it.
//
// The splats are given in glTF's Y-up frame; the node's translation (written as its matrix:
// CesiumJS reads only that) is the centre of their bounds, and the primitive's positions are
// relative to it (so SPZ's 24-bit fixed point keeps its precision far from the origin).
// - Spz (the default): the attributes are accessors without buffer views (POSITION, COLOR_0 as
//   normalized RGBA bytes, KHR_gaussian_splatting:ROTATION, :SCALE, and :SH_DEGREE_l_COEF_n for
//   l >= 1, the set cesium-native writes and CesiumJS decodes), their data one gzipped SPZ v2
//   payload in the buffer view named by KHR_gaussian_splatting_compression_spz_2, nested in the
//   primitive's KHR_gaussian_splatting; both extensions are required.
// - None: float attributes POSITION, KHR_gaussian_splatting:ROTATION (x, y, z, w), :SCALE
//   (linear), :OPACITY (linear), :SH_DEGREE_0_COEF_0 and the higher coefficients; the extension
//   is used, not required (a client without it draws points).
#include <cstdint>
#include <vector>

#include "stipple/io/splats.hpp"

namespace stipple::tiler {

enum class SplatCompression { Spz, None };

std::vector<uint8_t> write_splat_glb(const io::SplatSet& splats, SplatCompression compression);

}  // namespace stipple::tiler

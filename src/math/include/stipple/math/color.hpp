#pragma once
// The sRGB transfer function (IEC 61966-2-1). LAS, pnts RGB and what stipple's shaders write are
// sRGB-encoded display values; glTF defines COLOR_0 as linear, so glb content is converted at
// both ends: the tiler writes linear values, the glb reader turns them back into sRGB bytes.
#include <cstdint>

namespace stipple::color {

// Encoded [0, 1] -> linear [0, 1].
double srgb_to_linear(double encoded);
// Linear [0, 1] (clamped) -> encoded [0, 1].
double linear_to_srgb(double linear);
// An 8-bit sRGB value as linear 16-bit (normalized UNSIGNED_SHORT) with 12 significant bits (the
// low 4 are zero, which compresses): still exact both ways, since the smallest sRGB step (1/255
// near black is 1/3295 linear) is wider than 1/4095.
uint16_t srgb8_to_linear16(uint8_t encoded);
// Linear [0, 1] (clamped) -> the nearest 8-bit sRGB value, through a table of 65536 entries.
uint8_t linear_to_srgb8(double linear);

}  // namespace stipple::color

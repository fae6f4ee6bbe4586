#include "stipple/math/color.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace stipple::color {

double srgb_to_linear(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

double linear_to_srgb(double l) {
  l = std::clamp(l, 0.0, 1.0);
  return l <= 0.0031308 ? l * 12.92 : 1.055 * std::pow(l, 1.0 / 2.4) - 0.055;
}

uint16_t srgb8_to_linear16(uint8_t encoded) {
  static const std::array<uint16_t, 256> table = [] {
    std::array<uint16_t, 256> t{};
    for (int i = 0; i < 256; ++i)
      t[i] = uint16_t(std::lround(srgb_to_linear(i / 255.0) * 4095.0) << 4);
    return t;
  }();
  return table[encoded];
}

uint8_t linear_to_srgb8(double linear) {
  static const std::array<uint8_t, 65536> table = [] {
    std::array<uint8_t, 65536> t{};
    for (int i = 0; i < 65536; ++i)
      t[i] = uint8_t(std::lround(linear_to_srgb(i / 65535.0) * 255.0));
    return t;
  }();
  if (!(linear > 0)) return 0;  // NaN too
  return table[size_t(std::lround(std::min(linear, 1.0) * 65535.0))];
}

}  // namespace stipple::color

#pragma once
// sRGB <-> linear light. Light adds up linearly: a pixel that sees a drop through part of
// the aperture and the street through the rest is the average of the two *radiances*, so
// every mixing of colours in the defocus paths happens on decoded values.
#include <array>
#include <cmath>
#include <cstdint>

namespace raindrop {

inline double srgb_to_linear(double v) {
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

inline double linear_to_srgb(double v) {
  v = v < 0 ? 0 : (v > 1 ? 1 : v);
  return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

// Decoded value of each 8-bit code.
inline const std::array<float, 256>& srgb8_to_linear_table() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[i] = static_cast<float>(srgb_to_linear(i / 255.0));
    return t;
  }();
  return table;
}

// Nearest 8-bit code of a linear value; linear_to_srgb8(table[i]) == i for every code.
inline std::uint8_t linear_to_srgb8(double v) {
  if (!(v == v)) v = 0;  // NaN
  return static_cast<std::uint8_t>(std::floor(linear_to_srgb(v) * 255.0 + 0.5));
}

}  // namespace raindrop

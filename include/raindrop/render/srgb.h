#pragma once
// sRGB <-> linear light. Light adds up linearly: a pixel that sees a drop through part of
// the aperture and the street through the rest is the average of the two *radiances*, so
// every mixing of colours in the defocus paths happens on decoded values.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "raindrop/common/srgb_curve.h"

namespace raindrop {

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

// Table versions for per-pixel loops over large images (the layered defocus decodes every
// traced drop pixel and encodes every covered pixel; a pow costs tens of nanoseconds).
class SrgbTables {
 public:
  static const SrgbTables& get() {
    static const SrgbTables tables;
    return tables;
  }

  // srgb_to_linear for v in [0, 1] (clamped), piecewise linear through 4097 exact samples:
  // within 2e-7 of the formula (tests/render/test_srgb.cpp), far below an 8-bit step.
  float decode(float v) const {
    const float t = std::min(std::max(v, 0.0f), 1.0f) * kBins;
    const int i = std::min(static_cast<int>(t), kBins - 1);
    return decode_[i] + (t - static_cast<float>(i)) * (decode_[i + 1] - decode_[i]);
  }

  // Exactly linear_to_srgb8(v), for every float v: the code from the bin's first code and the
  // smallest float of each code, found with the formula itself. A bin holds at most one
  // code's first float (the curve's steepest slope, 12.92 x 255 codes per unit at 0, is 0.8
  // codes per bin; the constructor checks it), so one comparison finishes, without a branch.
  std::uint8_t encode(float v) const {
    if (!(v > 0.0f)) return 0;  // also NaN, as linear_to_srgb8
    if (v >= 1.0f) return 255;
    const int c = first_code_[static_cast<int>(v * kBins)];
    return static_cast<std::uint8_t>(c + (v >= first_float_[c + 1]));
  }

 private:
  static constexpr int kBins = 4096;
  SrgbTables() {
    for (int i = 0; i <= kBins; ++i) decode_[i] = static_cast<float>(srgb_to_linear(static_cast<double>(i) / kBins));
    // first_float_[c]: the smallest float in (0, 1] whose code is c or more (the formula is
    // non-decreasing), by bisection on the floats' bit patterns, which order positive floats.
    first_float_[0] = 0;
    for (int c = 1; c < 256; ++c) {
      std::uint32_t lo = 0, hi = 0x3f800000;  // bits of 0 and 1.0f; code(1.0f) = 255
      while (hi - lo > 1) {
        const std::uint32_t mid = lo + (hi - lo) / 2;
        float f;
        std::memcpy(&f, &mid, sizeof f);
        (linear_to_srgb8(f) >= c ? hi : lo) = mid;
      }
      std::memcpy(&first_float_[c], &hi, sizeof hi);
    }
    first_float_[256] = INFINITY;  // no code 256: code 255's bins never step past it
    for (int i = 0; i < kBins; ++i) first_code_[i] = linear_to_srgb8(static_cast<double>(static_cast<float>(i) / kBins));
    // encode's one comparison: no bin reaches past its first code's successor.
    for (int i = 0; i < kBins; ++i) {
      const int last = i + 1 < kBins ? first_code_[i + 1] : 255;
      if (last > first_code_[i] + 1) std::abort();
    }
  }
  std::array<float, kBins + 1> decode_{};
  std::array<float, 257> first_float_{};
  std::array<std::uint8_t, kBins> first_code_{};
};

}  // namespace raindrop

#pragma once
// One pixel of the layered composite (defocus.h), shared by the fast path and its exact
// reference so that the two differ only in how each drop's layer was spread:
//     A = sum of the spread coverages,  C = sum of the spread a x R (linear light),
//     I = (1 - A) B + C,
// and where spread drops overlap past full coverage they share it (C / A, A = 1).
#include <algorithm>
#include <array>
#include <cstdint>

#include "raindrop/render/highlights.h"
#include "raindrop/render/srgb.h"

namespace raindrop {

// Below this, a pixel's coverage is rounding noise of the convolution, not light: the pixel
// keeps its clean bytes and coverage 0.
inline constexpr float kNoCoverage = 1e-5f;

// `A`, `C`: the pixel's sums; `clean`: its 8-bit RGB, lifted by `lift` like the drops' radiance
// in C, and the mix stored again through its inverse (highlights.h). Returns false where A <= kNoCoverage (nothing to write); else sets
// `coverage` (A clamped to 1) and `out` (8-bit sRGB).
inline bool mix_layers(float A, const float* C, const std::uint8_t* clean, const HighlightLift& lift, float* coverage,
                       std::uint8_t* out) {
  if (!(A > kNoCoverage)) return false;
  const auto& lin = srgb8_to_linear_table();
  const SrgbTables& srgb = SrgbTables::get();
  const float scale = A > 1.0f ? 1.0f / A : 1.0f;
  const float a = std::min(A, 1.0f);
  float b[3] = {lin[clean[0]], lin[clean[1]], lin[clean[2]]};
  lift.apply(b);
  float mixed[3];
  for (int k = 0; k < 3; ++k) mixed[k] = (1.0f - a) * b[k] + scale * C[k];
  lift.restore(mixed);
  for (int k = 0; k < 3; ++k) out[k] = srgb.encode(mixed[k]);
  *coverage = a;
  return true;
}

}  // namespace raindrop

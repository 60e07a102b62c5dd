#pragma once
// The sRGB transfer curve (IEC 61966-2-1) on one value in [0, 1]: stored 8/16-bit images are
// sRGB-encoded, float images (EXR, HDR) and every mixing of light hold linear values. Shared by
// image I/O (float files in and out) and the renderer (render/srgb.h adds its tables).
#include <cmath>

namespace raindrop {

inline double srgb_to_linear(double v) {
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

// Clamped to [0, 1] first.
inline double linear_to_srgb(double v) {
  v = v < 0 ? 0 : (v > 1 ? 1 : v);
  return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

}  // namespace raindrop

#pragma once
// Points of the thin lens's disk: where the aperture paths' rays start (the reference's
// trace_aperture and the layered path's drops in focus, tracer.cpp). Inline: a render asks
// for one per ray, millions a frame.
#include <cmath>
#include <cstdint>

#include <glm/vec2.hpp>

#include "raindrop/common/rng.h"

namespace raindrop {

// A hash of pixel (x, y) and `salt`: per-pixel random numbers that do not depend on the
// thread count.
inline std::uint64_t pixel_hash(int x, int y, std::uint64_t salt) {
  return mix64((static_cast<std::uint64_t>(y) << 40) ^ (static_cast<std::uint64_t>(x) << 16) ^ salt);
}
// Two numbers in [0, 1) from a hash's halves.
inline glm::dvec2 unit_pair(std::uint64_t h) {
  return {static_cast<double>(h & 0xffffffffULL) * 0x1.0p-32, static_cast<double>(h >> 32) * 0x1.0p-32};
}

// sin and cos of |x| <= pi/4: their Taylor series to x^17 and x^18 (the next terms are under
// 1e-19), in Horner's form: within an ulp of std::sin and std::cos
// (tests/render/test_lens_disk.cpp), for a few multiplications where the library's sincos
// first reduces its argument (a tenth of the aperture reference's time went there).
inline void quarter_sincos(double x, double* sn, double* cs) {
  const double x2 = x * x;
  double s = 1.0 / 355687428096000.0;  // 1/17!
  s = s * x2 - 1.0 / 1307674368000.0;
  s = s * x2 + 1.0 / 6227020800.0;
  s = s * x2 - 1.0 / 39916800.0;
  s = s * x2 + 1.0 / 362880.0;
  s = s * x2 - 1.0 / 5040.0;
  s = s * x2 + 1.0 / 120.0;
  s = s * x2 - 1.0 / 6.0;
  s = s * x2 + 1.0;
  double c = -1.0 / 6402373705728000.0;  // -1/18!
  c = c * x2 + 1.0 / 20922789888000.0;
  c = c * x2 - 1.0 / 87178291200.0;
  c = c * x2 + 1.0 / 479001600.0;
  c = c * x2 - 1.0 / 3628800.0;
  c = c * x2 + 1.0 / 40320.0;
  c = c * x2 - 1.0 / 720.0;
  c = c * x2 + 1.0 / 24.0;
  c = c * x2 - 0.5;
  c = c * x2 + 1.0;
  *sn = x * s;
  *cs = c;
}

// A point of the lens disk of `radius` for pixel (x, y), stratum (i, j) of a k x k grid: the
// strata jittered per pixel and stratum by a hash (so a render is the same for any thread
// count), mapped onto the disk by Shirley and Chiu's concentric map, which keeps the strata's
// equal areas. Without the jitter, every pixel would use the same k/2 rings of the disk and
// coverage would come in visible steps. The map's angle is pi/4 (b/a) in the sectors where
// |a| > |b|, else pi/2 - pi/4 (a/b), whose cosine and sine are the sine and cosine of pi/4 (a/b):
// both within a quarter turn of zero.
inline glm::dvec2 lens_disk_point(int x, int y, int i, int j, int k, double radius) {
  const glm::dvec2 jitter = unit_pair(pixel_hash(x, y, static_cast<std::uint64_t>(j * k + i)));
  const double a = 2.0 * (i + jitter.x) / k - 1.0, b = 2.0 * (j + jitter.y) / k - 1.0;
  if (a == 0 && b == 0) return glm::dvec2(0.0);
  double r, c, s;
  if (std::abs(a) > std::abs(b)) {
    r = a;
    quarter_sincos(M_PI / 4 * (b / a), &s, &c);
  } else {
    r = b;
    quarter_sincos(M_PI / 4 * (a / b), &c, &s);
  }
  return radius * r * glm::dvec2(c, s);
}

// All k x k points of pixel (x, y) at once, out[j * k + i] = lens_disk_point(x, y, i, j, k,
// radius) to the bit: in SIMD lanes, as many points at a time as a register holds doubles, on
// GCC builds for x86-64 (lens_disk.cpp), one at a time elsewhere. A pixel's 16 points one at a
// time were a sixth of the aperture reference's time at 2048x1024.
void lens_disk_points(int x, int y, int k, double radius, glm::dvec2* out);

}  // namespace raindrop

#pragma once
// An irregular contact line: where a real drop meets the glass. Water pinned on dirt and
// scratches does not relax into a circle; large drops on real windshields show wavy, lobed
// outlines. The contact line is the circle stretched per azimuth:
//   rim(phi) = a s(phi),   s(phi) = 1 + sum_{k=2..K} (c_k cos k phi + d_k sin k phi),
// and the drop's surface is the spherical cap stretched the same way, radially:
//   height(rho, phi) = cap(rho / s(phi)),
// so each azimuthal section is the cap's own profile, scaled. Mode k = 1 would only move the
// drop (left out); k >= 2 make ovals, triangles, lobes. The stretch keeps the cap's height and
// changes the contact angle along the rim: tan(local angle) = tan(tau) / s(phi) across the
// line, lower where the water reached further, as on a real pinned drop. It is not the
// surface of least energy over that outline (which has no closed form); it is smooth, has the
// drawn outline exactly and conserves what a test can check in closed form:
//   footprint area = pi a^2 <s^2>,   volume = cap volume x <s^2>,
// <s^2> = 1 + sum (c_k^2 + d_k^2) / 2 the mean of s^2 over the azimuth. A drawn outline is
// scaled to the footprint radius a / sqrt(<s^2>), so turning the effect on keeps every drop's
// footprint area and volume.
#include <algorithm>
#include <vector>

#include "raindrop/common/rng.h"

namespace raindrop {

// The most modes an outline may have: higher ones are finer than any defocused drop shows, and
// each costs the intersection a sine and cosine per evaluation.
inline constexpr int kMaxOutlineModes = 16;

class Outline {
 public:
  Outline() = default;  // the circle
  // Explicit coefficients: cos_terms[i], sin_terms[i] belong to mode k = i + 2. The peak
  // deviation max |s - 1| must be below 1 (s stays positive); throws raindrop::Error otherwise.
  Outline(std::vector<double> cos_terms, std::vector<double> sin_terms);

  // A random outline whose peak deviation from the circle is exactly `peak` (in [0, 0.9]):
  // modes 2..max_mode, amplitudes uniform in [-1, 1] / k (a rough, lobed line: low modes
  // dominate, as in photographs), then scaled to the peak. peak 0 is the circle.
  static Outline draw(double peak, int max_mode, Rng& rng);

  bool circular() const { return cos_.empty(); }
  double s(double phi) const;                 // rim radius / a at azimuth phi
  double s_at(double cos_phi, double sin_phi) const;  // the same from the azimuth's cosine and sine
  void s_and_slope(double phi, double* s, double* ds) const;  // s and ds/dphi
  double s_max() const { return s_max_; }     // max over phi (1 for the circle)
  double s_min() const { return s_min_; }
  double mean_square() const;                 // <s^2>
  double peak_deviation() const { return std::max(s_max_ - 1.0, 1.0 - s_min_); }
  const std::vector<double>& cos_terms() const { return cos_; }
  const std::vector<double>& sin_terms() const { return sin_; }

 private:
  void find_extremes();
  std::vector<double> cos_, sin_;
  double s_max_ = 1.0, s_min_ = 1.0;
};

}  // namespace raindrop

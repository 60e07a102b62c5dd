#include "raindrop/render/outline.h"

#include <cmath>
#include <utility>

#include "raindrop/common/error.h"

namespace raindrop {
namespace {

// Azimuths at which the extremes are searched; between them s can exceed the sampled values by
// at most (step^2 / 8) max|s''|, which find_extremes adds so that s_max bounds s from above.
constexpr int kExtremeSamples = 2048;

// s(phi) - 1 and its derivative from cos phi and sin phi, with cos k phi and sin k phi by the
// angle-addition recurrence (no trigonometric call, whatever the number of modes).
void perturbation(const std::vector<double>& c, const std::vector<double>& d, double c1, double s1, double* p,
                  double* dp) {
  double ck = c1 * c1 - s1 * s1, sk = 2 * s1 * c1;  // k = 2
  double v = 0, dv = 0;
  for (size_t i = 0; i < c.size(); ++i) {
    const double k = static_cast<double>(i + 2);
    v += c[i] * ck + d[i] * sk;
    dv += k * (d[i] * ck - c[i] * sk);
    const double cn = ck * c1 - sk * s1;
    sk = sk * c1 + ck * s1;
    ck = cn;
  }
  *p = v;
  if (dp) *dp = dv;
}

void perturbation(const std::vector<double>& c, const std::vector<double>& d, double phi, double* p, double* dp) {
  perturbation(c, d, std::cos(phi), std::sin(phi), p, dp);
}

}  // namespace

Outline::Outline(std::vector<double> cos_terms, std::vector<double> sin_terms)
    : cos_(std::move(cos_terms)), sin_(std::move(sin_terms)) {
  if (cos_.size() != sin_.size()) throw Error("outline: as many sine as cosine terms are needed");
  if (static_cast<int>(cos_.size()) > kMaxOutlineModes - 1)
    throw Error("outline: at most modes 2.." + std::to_string(kMaxOutlineModes));
  for (size_t i = 0; i < cos_.size(); ++i) {
    if (!std::isfinite(cos_[i]) || !std::isfinite(sin_[i])) throw Error("outline: a coefficient is not finite");
  }
  // Trailing zero modes are dropped, so that an all-zero outline is the circle exactly.
  while (!cos_.empty() && cos_.back() == 0.0 && sin_.back() == 0.0) cos_.pop_back(), sin_.pop_back();
  find_extremes();
  if (s_min_ <= 0.05) throw Error("outline: the contact line would pass through the drop's centre (peak deviation >= 0.95)");
}

Outline Outline::draw(double peak, int max_mode, Rng& rng) {
  if (!(peak >= 0.0 && peak <= 0.9)) throw Error("outline: peak deviation must lie in [0, 0.9]");
  if (max_mode < 2 || max_mode > kMaxOutlineModes) throw Error("outline: modes must lie in [2, 16]");
  std::vector<double> c(max_mode - 1), d(max_mode - 1);
  for (int k = 2; k <= max_mode; ++k) {
    c[k - 2] = rng.uniform(-1.0, 1.0) / k;
    d[k - 2] = rng.uniform(-1.0, 1.0) / k;
  }
  if (peak == 0.0) return Outline();
  // Scale to the peak, measured on the same grid the extremes are found on.
  double worst = 0;
  for (int i = 0; i < kExtremeSamples; ++i) {
    double p;
    perturbation(c, d, 2 * M_PI * i / kExtremeSamples, &p, nullptr);
    worst = std::max(worst, std::abs(p));
  }
  if (worst == 0.0) return Outline();
  for (int i = 0; i < max_mode - 1; ++i) c[i] *= peak / worst, d[i] *= peak / worst;
  return Outline(std::move(c), std::move(d));
}

void Outline::find_extremes() {
  s_max_ = s_min_ = 1.0;
  if (cos_.empty()) return;
  double curvature = 0;  // bound on |s''|
  for (size_t i = 0; i < cos_.size(); ++i) {
    const double k = static_cast<double>(i + 2);
    curvature += k * k * (std::abs(cos_[i]) + std::abs(sin_[i]));
  }
  double hi = -1e300, lo = 1e300;
  for (int i = 0; i < kExtremeSamples; ++i) {
    double p;
    perturbation(cos_, sin_, 2 * M_PI * i / kExtremeSamples, &p, nullptr);
    hi = std::max(hi, p), lo = std::min(lo, p);
  }
  const double step = 2 * M_PI / kExtremeSamples;
  const double slack = step * step / 8 * curvature;
  s_max_ = 1.0 + hi + slack;
  s_min_ = 1.0 + lo - slack;
}

double Outline::s(double phi) const {
  if (cos_.empty()) return 1.0;
  double p;
  perturbation(cos_, sin_, phi, &p, nullptr);
  return 1.0 + p;
}

void Outline::s_and_slope(double phi, double* s, double* ds) const {
  if (cos_.empty()) {
    *s = 1.0, *ds = 0.0;
    return;
  }
  double p;
  perturbation(cos_, sin_, phi, &p, ds);
  *s = 1.0 + p;
}

double Outline::s_at(double cos_phi, double sin_phi) const {
  if (cos_.empty()) return 1.0;
  double p;
  perturbation(cos_, sin_, cos_phi, sin_phi, &p, nullptr);
  return 1.0 + p;
}

double Outline::mean_square() const {
  double m = 1.0;
  for (size_t i = 0; i < cos_.size(); ++i) m += 0.5 * (cos_[i] * cos_[i] + sin_[i] * sin_[i]);
  return m;
}

}  // namespace raindrop

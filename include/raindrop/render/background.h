#pragma once
// The background plane's texture: the clean frame, sampled bilinearly at continuous pixel
// coordinates (pixel centres at integers). Refracted rays often land outside the frame (a
// drop shows a strongly minified, inverted view of a wide cone); `border` says what is seen
// there: `clamp` repeats the edge pixel (the authors' released code; it smears the border
// into streaks), `mirror` reflects the frame about its edges (a plausible continuation of
// sky and road; the default).
#include <cmath>
#include <algorithm>
#include <cstdint>

#include <glm/vec3.hpp>
#include <opencv2/core.hpp>

#include "raindrop/render/scene_config.h"

namespace raindrop {

class BackgroundSampler {
 public:
  BackgroundSampler(const cv::Mat& rgb8, BorderMode border) : img_(rgb8), border_(border) {
    CV_Assert(rgb8.type() == CV_8UC3);
  }

  bool inside(double x, double y) const {
    return x >= -0.5 && y >= -0.5 && x <= img_.cols - 0.5 && y <= img_.rows - 0.5;
  }

  // Above the frame, the view fades from the border mode's continuation into `rgb` over
  // `fade_px` rows (the sky effect); fade_px <= 0 turns it off.
  void set_sky(const glm::dvec3& rgb, double fade_px) {
    sky_ = rgb;
    sky_fade_px_ = fade_px;
  }

  // RGB in [0, 1]. Finite for any finite input; non-finite coordinates give the nearest
  // corner's colour.
  glm::dvec3 sample(double x, double y) const {
    const glm::dvec3 c = sample_frame(x, y);
    const double w = sky_weight(y);
    return w > 0 ? c + w * (sky_ - c) : c;
  }

  // How much of the sky is seen at row y, from 0 (the frame's continuation) to 1.
  double sky_weight(double y) const {
    if (sky_fade_px_ <= 0 || !(y < -0.5)) return 0.0;
    return std::isfinite(y) ? std::min(1.0, (-0.5 - y) / sky_fade_px_) : 1.0;
  }

  // Maps a coordinate into [0, n - 1] according to the border mode (n: the frame's width or
  // height): where in the frame its continuation at v comes from.
  double fold(double v, int n) const {
    if (v >= 0.0 && v <= n - 1.0) return v;  // inside: the common case, no fmod
    if (!std::isfinite(v)) return v > 0 ? n - 1 : 0;
    if (border_ == BorderMode::Clamp || n == 1) return std::min(std::max(v, 0.0), n - 1.0);
    // Mirror about the outer pixel edges (-0.5 and n - 0.5): period 2n.
    const double period = 2.0 * n;
    double u = std::fmod(v + 0.5, period);
    if (u < 0) u += period;
    if (u > n) u = period - u;
    return std::min(std::max(u - 0.5, 0.0), n - 1.0);
  }

  // Asks the processor to start loading the pixels sample(x, y) will read (the sky's blend
  // reads nothing more); no effect on any result.
  void prefetch(double x, double y) const {
    x = fold(x, img_.cols);
    y = fold(y, img_.rows);
    const int x0 = clampi(static_cast<int>(std::floor(x)), img_.cols);
    const int y0 = static_cast<int>(std::floor(y));
    __builtin_prefetch(img_.ptr<std::uint8_t>(clampi(y0, img_.rows)) + 3 * x0);
    __builtin_prefetch(img_.ptr<std::uint8_t>(clampi(y0 + 1, img_.rows)) + 3 * x0);
  }

  glm::dvec3 pixel(int x, int y) const {
    const auto* p = img_.ptr<std::uint8_t>(y) + 3 * x;
    return glm::dvec3(p[0], p[1], p[2]) * (1.0 / 255.0);
  }

 private:
  // The frame and its border-mode continuation, bilinear.
  glm::dvec3 sample_frame(double x, double y) const {
    x = fold(x, img_.cols);
    y = fold(y, img_.rows);
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    const double fx = x - x0, fy = y - y0;
    const int xa = clampi(x0, img_.cols), xb = clampi(x0 + 1, img_.cols);
    const int ya = clampi(y0, img_.rows), yb = clampi(y0 + 1, img_.rows);
    const auto* ra = img_.ptr<std::uint8_t>(ya);
    const auto* rb = img_.ptr<std::uint8_t>(yb);
    glm::dvec3 out;
    for (int c = 0; c < 3; ++c) {
      const double top = ra[3 * xa + c] + fx * (ra[3 * xb + c] - ra[3 * xa + c]);
      const double bottom = rb[3 * xa + c] + fx * (rb[3 * xb + c] - rb[3 * xa + c]);
      out[c] = (top + fy * (bottom - top)) * (1.0 / 255.0);
    }
    return out;
  }

  static int clampi(int v, int n) { return v < 0 ? 0 : (v >= n ? n - 1 : v); }

  const cv::Mat& img_;
  BorderMode border_;
  glm::dvec3 sky_{0.0};
  double sky_fade_px_ = 0;
};

}  // namespace raindrop

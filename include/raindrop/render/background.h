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

  // The image may be the frame widened by `margin` pixels on every side, the margin being the
  // border mode's continuation of the frame (cv::BORDER_REFLECT for mirror, BORDER_REPLICATE for
  // clamp), as the thin-lens camera widens it so that drops just outside still spread into it.
  // Coordinates stay the image's; what lies beyond the image, and the sky above the frame, are
  // then continued from the frame itself, so a ray sees the same thing whatever the margin.
  void set_margin(int margin) { margin_ = std::max(0, std::min(margin, (std::min(img_.cols, img_.rows) - 1) / 2)); }

  // Inside the frame (not its margin).
  bool inside(double x, double y) const {
    return x >= margin_ - 0.5 && y >= margin_ - 0.5 && x <= img_.cols - margin_ - 0.5 && y <= img_.rows - margin_ - 0.5;
  }

  // Above the frame, the view fades from the border mode's continuation into `rgb` over
  // `fade_px` rows (the sky effect); fade_px <= 0 turns it off.
  void set_sky(const glm::dvec3& rgb, double fade_px) {
    sky_ = rgb;
    sky_fade_px_ = fade_px;
  }

  // RGB in [0, 1]. Finite for any finite input; non-finite coordinates give the nearest
  // corner's colour.
  // Inlined: it runs once per traced ray (docs/RESULTS.md 4.53: the trace 1.01-1.05x faster).
  __attribute__((always_inline)) glm::dvec3 sample(double x, double y) const {
    const glm::dvec3 c = sample_frame(x, y);
    const double w = sky_weight(y);
    return w > 0 ? c + w * (sky_ - c) : c;
  }

  // How much of the sky is seen at row y, from 0 (the frame's continuation) to 1: it starts at
  // the frame's top edge.
  double sky_weight(double y) const {
    const double top = margin_ - 0.5;
    if (sky_fade_px_ <= 0 || !(y < top)) return 0.0;
    return std::isfinite(y) ? std::min(1.0, (top - y) / sky_fade_px_) : 1.0;
  }

  // Maps a coordinate into [0, n - 1] according to the border mode (n: the image's width or
  // height): where in the image its continuation at v comes from.
  double fold(double v, int n) const {
    if (v >= 0.0 && v <= n - 1.0) return v;  // inside: the common case, no fmod (a margin holds the same continuation)
    const int m = margin_, inner = n - 2 * margin_;
    if (!std::isfinite(v)) return v > 0 ? m + inner - 1 : m;  // the frame's own last or first pixel
    // Clamp: the edge pixel, the frame's and its margin's alike.
    if (border_ == BorderMode::Clamp || inner <= 1) return std::min(std::max(v, 0.0), n - 1.0);
    // Mirror about the frame's outer pixel edges (m - 0.5 and m + inner - 0.5): period 2 inner.
    const double period = 2.0 * inner;
    double u = std::fmod(v - m + 0.5, period);
    if (u < 0) u += period;
    if (u > inner) u = period - u;
    return m + std::min(std::max(u - 0.5, 0.0), inner - 1.0);
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
  __attribute__((always_inline)) glm::dvec3 sample_frame(double x, double y) const {
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
  int margin_ = 0;
  glm::dvec3 sky_{0.0};
  double sky_fade_px_ = 0;
};

}  // namespace raindrop

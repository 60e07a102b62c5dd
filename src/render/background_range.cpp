#include "raindrop/render/background_range.h"

#include <algorithm>
#include <cmath>

namespace raindrop {

BackgroundRange::BackgroundRange(const cv::Mat& rgb8, const BackgroundSampler& sampler) : sampler_(sampler) {
  CV_Assert(rgb8.type() == CV_8UC3);
  lo_.push_back(rgb8);
  hi_.push_back(rgb8);
  // Level L + 1 from level L: min and max over 2 x 2 blocks (the last row or column of an
  // odd size stands alone). Stop when one block covers the frame.
  while (lo_.back().cols > 1 || lo_.back().rows > 1) {
    const cv::Mat &lo = lo_.back(), &hi = hi_.back();
    cv::Mat nlo((lo.rows + 1) / 2, (lo.cols + 1) / 2, CV_8UC3), nhi(nlo.size(), CV_8UC3);
    for (int y = 0; y < nlo.rows; ++y) {
      for (int x = 0; x < nlo.cols; ++x) {
        cv::Vec3b a = lo.at<cv::Vec3b>(2 * y, 2 * x), b = hi.at<cv::Vec3b>(2 * y, 2 * x);
        for (int dy = 0; dy < 2; ++dy) {
          for (int dx = 0; dx < 2; ++dx) {
            const int yy = std::min(2 * y + dy, lo.rows - 1), xx = std::min(2 * x + dx, lo.cols - 1);
            const cv::Vec3b &p = lo.at<cv::Vec3b>(yy, xx), &q = hi.at<cv::Vec3b>(yy, xx);
            for (int c = 0; c < 3; ++c) {
              a[c] = std::min(a[c], p[c]);
              b[c] = std::max(b[c], q[c]);
            }
          }
        }
        nlo.at<cv::Vec3b>(y, x) = a;
        nhi.at<cv::Vec3b>(y, x) = b;
      }
    }
    lo_.push_back(nlo);
    hi_.push_back(nhi);
  }
}

glm::dvec3 BackgroundRange::range(double x, double y, double size) const {
  // The sampler's bilinear samples over the square read the frame pixels from
  // floor(v - size / 2) to floor(v + size / 2) + 1 along each axis (after folding the centre
  // into the frame: folding moves no point further from it). Level L's blocks are the first
  // power of two at least as wide as the square, so that span meets a few of them.
  const double s = std::max(size, 1.0);
  const int level = std::min(static_cast<int>(std::ceil(std::log2(s))), static_cast<int>(lo_.size()) - 1);
  const double fx = sampler_.fold(x, lo_[0].cols), fy = sampler_.fold(y, lo_[0].rows);
  const cv::Mat &lo = lo_[level], &hi = hi_[level];
  auto cell = [&](double v, int n) { return std::clamp(static_cast<int>(std::floor(v)), 0, n - 1) >> level; };
  const int x0 = cell(fx - 0.5 * s, lo_[0].cols), x1 = cell(fx + 0.5 * s + 1.0, lo_[0].cols);
  const int y0 = cell(fy - 0.5 * s, lo_[0].rows), y1 = cell(fy + 0.5 * s + 1.0, lo_[0].rows);
  glm::dvec3 out(0.0);
  for (int c = 0; c < 3; ++c) {
    int a = 255, b = 0;
    for (int yy = y0; yy <= y1; ++yy) {
      for (int xx = x0; xx <= x1; ++xx) {
        a = std::min<int>(a, lo.at<cv::Vec3b>(yy, xx)[c]);
        b = std::max<int>(b, hi.at<cv::Vec3b>(yy, xx)[c]);
      }
    }
    out[c] = (b - a) / 255.0;
  }
  // Above the frame the view fades into the flat sky: the frame's variation shrinks by the
  // sky's share, and the fade itself varies across the footprint by at most its change of
  // share (times a colour difference of at most 1).
  const double w_near = sampler_.sky_weight(y + 0.5 * s), w_far = sampler_.sky_weight(y - 0.5 * s);
  return (1.0 - w_near) * out + glm::dvec3(w_far - w_near);
}

}  // namespace raindrop

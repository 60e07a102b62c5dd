#include "raindrop/remove/working_scale.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace raindrop::removal {

double auto_working_scale(cv::Size size, int working_size) {
  const int long_side = std::max(size.width, size.height);
  if (long_side <= working_size || working_size < 1) return 1.0;
  return static_cast<double>(working_size) / long_side;
}

cv::Size scaled_size(cv::Size size, double scale) {
  const auto side = [scale](int n) { return std::max(1, static_cast<int>(std::lround(n * scale))); };
  return {side(size.width), side(size.height)};
}

namespace {

// One axis of bilinear upsampling from n to N samples with pixel centres aligned (the
// mapping of cv::resize's INTER_LINEAR, edges replicated): full index i reads small samples
// lo[i] and lo[i] + step[i] with weight w[i] on the second.
struct Taps {
  std::vector<int> lo, step;
  std::vector<float> w;
};

Taps axis_taps(int n, int N, int from, int count) {
  Taps t;
  t.lo.resize(count);
  t.step.resize(count);
  t.w.resize(count);
  const double ratio = static_cast<double>(n) / N;
  for (int i = 0; i < count; ++i) {
    const double src = std::clamp((from + i + 0.5) * ratio - 0.5, 0.0, n - 1.0);
    const int lo = std::min(static_cast<int>(src), n - 1);
    t.lo[i] = lo;
    t.step[i] = lo + 1 < n ? 1 : 0;
    t.w[i] = static_cast<float>(src - lo);
  }
  return t;
}

}  // namespace

// Each pixel depends on its own position only (axis_taps), so a region is exactly that part of
// the whole upsampled image. Float weights throughout: cv::warpAffine's 1/32-pixel
// interpolation table was off by up to 4 levels of 8 bits on sharp edges.
cv::Mat upsample_region(const cv::Mat& small, cv::Size full, const cv::Rect& region) {
  const int nc = small.channels(), rows = region.height;
  const Taps ty = axis_taps(small.rows, full.height, region.y, rows), tx = axis_taps(small.cols, full.width, region.x, region.width);
  cv::Mat out(rows, region.width, small.type());
  std::vector<float> line(static_cast<size_t>(small.cols) * nc);
  for (int y = 0; y < rows; ++y) {
    const float* a = small.ptr<float>(ty.lo[y]);
    const float* b = small.ptr<float>(ty.lo[y] + ty.step[y]);
    const float wy = ty.w[y];
    for (size_t k = 0; k < line.size(); ++k) line[k] = a[k] + wy * (b[k] - a[k]);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < region.width; ++x) {
      const float* p = line.data() + static_cast<size_t>(tx.lo[x]) * nc;
      const float* q = p + static_cast<size_t>(tx.step[x]) * nc;
      for (int c = 0; c < nc; ++c) o[x * nc + c] = p[c] + tx.w[x] * (q[c] - p[c]);
    }
  }
  return out;
}

cv::Rect upsampled_reach(const cv::Mat& small, cv::Size full, const cv::Rect& region) {
  CV_Assert(small.type() == CV_32F);
  if (region.empty()) return {};
  const Taps ty = axis_taps(small.rows, full.height, region.y, region.height);
  // Small rows read by the region's rows (the taps grow with the index).
  const int r0 = ty.lo.front(), r1 = ty.lo.back() + ty.step.back();
  int c0 = small.cols, c1 = -1;
  for (int r = r0; r <= r1; ++r) {
    const float* row = small.ptr<float>(r);
    int x = 0;
    while (x < small.cols && row[x] == 0.0f) ++x;
    if (x == small.cols) continue;
    int last = small.cols - 1;
    while (row[last] == 0.0f) --last;
    c0 = std::min(c0, x), c1 = std::max(c1, last);
  }
  if (c1 < 0) return {};
  // Full columns whose taps read a small column in [c0, c1].
  const Taps tx = axis_taps(small.cols, full.width, region.x, region.width);
  int x0 = 0, x1 = region.width - 1;
  while (x0 < region.width && tx.lo[x0] + tx.step[x0] < c0) ++x0;
  while (x1 >= x0 && tx.lo[x1] > c1) --x1;
  if (x0 > x1) return {};
  return {region.x + x0, region.y, x1 - x0 + 1, region.height};
}

cv::Mat blend_upsampled(const cv::Mat& in_region, const cv::Rect& region, cv::Size full, const cv::Mat& output_small,
                        const cv::Mat& mask_small, cv::Mat& alpha) {
  CV_Assert(in_region.size() == region.size());
  alpha = upsample_region(mask_small, full, region);
  const cv::Mat up = upsample_region(output_small, full, region);
  cv::Mat out = in_region.clone();
  for (int y = 0; y < out.rows; ++y) {
    const float* a = alpha.ptr<float>(y);
    const float* u = up.ptr<float>(y);
    const float* in = in_region.ptr<float>(y);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < out.cols; ++x) {
      if (a[x] <= 0.0f) continue;
      for (int k = 0; k < 3; ++k) o[3 * x + k] = in[3 * x + k] + a[x] * (u[3 * x + k] - in[3 * x + k]);
    }
  }
  return out;
}

}  // namespace raindrop::removal

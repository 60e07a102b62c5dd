#include "raindrop/render/sky.h"

#include <algorithm>
#include <array>
#include <cstdint>

#include <glm/common.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

namespace raindrop {
namespace {

int luma(const cv::Vec3b& p) { return (299 * p[0] + 587 * p[1] + 114 * p[2]) / 1000; }

using Histogram = std::array<std::int64_t, 256>;

}  // namespace

glm::dvec3 estimate_sky_rgb(const cv::Mat& rgb8, double gain) {
  CV_Assert(rgb8.type() == CV_8UC3 && !rgb8.empty());
  const int rows = std::max(1, rgb8.rows / 3);
  // Luma histogram of the top third, then the mean colour of the pixels at or above its
  // 90th percentile. Both passes over row bands on all threads (a serial scan of a 2048x1024
  // frame's top third was about 1% of a layered render); the sums are of integers, so their
  // order does not change them.
  const Histogram hist = tbb::parallel_reduce(
      tbb::blocked_range<int>(0, rows, 32), Histogram{},
      [&](const tbb::blocked_range<int>& r, Histogram h) {
        for (int y = r.begin(); y < r.end(); ++y) {
          const auto* row = rgb8.ptr<cv::Vec3b>(y);
          for (int x = 0; x < rgb8.cols; ++x) ++h[luma(row[x])];
        }
        return h;
      },
      [](Histogram a, const Histogram& b) {
        for (int i = 0; i < 256; ++i) a[i] += b[i];
        return a;
      });
  const std::int64_t total = static_cast<std::int64_t>(rows) * rgb8.cols;
  std::int64_t above = 0;
  int cut = 255;
  for (; cut > 0; --cut) {
    above += hist[cut];
    if (above * 10 >= total) break;
  }
  using Sums = std::array<std::int64_t, 4>;  // R, G, B, count
  const Sums sums = tbb::parallel_reduce(
      tbb::blocked_range<int>(0, rows, 32), Sums{},
      [&](const tbb::blocked_range<int>& r, Sums s) {
        for (int y = r.begin(); y < r.end(); ++y) {
          const auto* row = rgb8.ptr<cv::Vec3b>(y);
          for (int x = 0; x < rgb8.cols; ++x) {
            if (luma(row[x]) < cut) continue;
            s[0] += row[x][0], s[1] += row[x][1], s[2] += row[x][2], ++s[3];
          }
        }
        return s;
      },
      [](Sums a, const Sums& b) {
        for (int i = 0; i < 4; ++i) a[i] += b[i];
        return a;
      });
  const glm::dvec3 sum(static_cast<double>(sums[0]), static_cast<double>(sums[1]), static_cast<double>(sums[2]));
  const glm::dvec3 sky = sum / (255.0 * static_cast<double>(std::max<std::int64_t>(1, sums[3]))) * gain;
  return glm::min(sky, glm::dvec3(1.0));
}

}  // namespace raindrop

#include "raindrop/render/sky.h"

#include <algorithm>
#include <array>

#include <glm/common.hpp>

namespace raindrop {

glm::dvec3 estimate_sky_rgb(const cv::Mat& rgb8, double gain) {
  CV_Assert(rgb8.type() == CV_8UC3 && !rgb8.empty());
  const int rows = std::max(1, rgb8.rows / 3);
  // Luma histogram of the top third, then the mean colour of the pixels at or above its
  // 90th percentile.
  std::array<long, 256> hist{};
  auto luma = [](const cv::Vec3b& p) { return (299 * p[0] + 587 * p[1] + 114 * p[2]) / 1000; };
  for (int y = 0; y < rows; ++y) {
    const auto* row = rgb8.ptr<cv::Vec3b>(y);
    for (int x = 0; x < rgb8.cols; ++x) ++hist[luma(row[x])];
  }
  const long total = static_cast<long>(rows) * rgb8.cols;
  long above = 0;
  int cut = 255;
  for (; cut > 0; --cut) {
    above += hist[cut];
    if (above * 10 >= total) break;
  }
  glm::dvec3 sum(0.0);
  long n = 0;
  for (int y = 0; y < rows; ++y) {
    const auto* row = rgb8.ptr<cv::Vec3b>(y);
    for (int x = 0; x < rgb8.cols; ++x) {
      if (luma(row[x]) < cut) continue;
      sum += glm::dvec3(row[x][0], row[x][1], row[x][2]);
      ++n;
    }
  }
  const glm::dvec3 sky = sum / (255.0 * std::max(1L, n)) * gain;
  return glm::min(sky, glm::dvec3(1.0));
}

}  // namespace raindrop

#include "raindrop/remove/large_drops.h"

#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace raindrop::removal {

bool coarse_pass_fits(cv::Size coarse) {
  return coarse.width >= 2 * kLargeDropDiameter && coarse.height >= 2 * kLargeDropDiameter;
}

cv::Mat large_drop_mask(const cv::Mat& mask, int* count) {
  CV_Assert(mask.type() == CV_8UC1);
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask != 0, labels, stats, centroids, 8, CV_32S);
  const double min_area = M_PI * 0.25 * kLargeDropDiameter * kLargeDropDiameter;
  std::vector<unsigned char> keep(n, 0);
  int kept = 0;
  for (int i = 1; i < n; ++i) {
    if (stats.at<int>(i, cv::CC_STAT_AREA) >= min_area) {
      keep[i] = 255;
      ++kept;
    }
  }
  cv::Mat out(mask.size(), CV_8U);
  for (int y = 0; y < mask.rows; ++y) {
    const int* l = labels.ptr<int>(y);
    unsigned char* o = out.ptr<unsigned char>(y);
    for (int x = 0; x < mask.cols; ++x) o[x] = keep[l[x]];
  }
  if (count) *count = kept;
  return out;
}

}  // namespace raindrop::removal

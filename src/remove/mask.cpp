#include "raindrop/remove/mask.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"
#include "raindrop/remove/model.h"

namespace raindrop::removal {

void threshold_mask(const cv::Mat& prob, double threshold, cv::Mat dst) {
  CV_Assert(prob.type() == CV_32FC1 && dst.type() == CV_8UC1 && prob.size() == dst.size());
  // numpy compares float32 P with np.float32(threshold): the threshold is rounded to float
  // first, so 0.3 means 0.30000001192..., not the double 0.3.
  const float t = static_cast<float>(threshold);
  for (int y = 0; y < prob.rows; ++y) {
    const float* p = prob.ptr<float>(y);
    unsigned char* m = dst.ptr<unsigned char>(y);
    for (int x = 0; x < prob.cols; ++x) m[x] = p[x] > t ? 1 : 0;
  }
}

cv::Mat dilate_mask(const cv::Mat& mask, int k) {
  CV_Assert(mask.type() == CV_8UC1);
  if (k < 1) throw Error("dilation size must be >= 1, got " + std::to_string(k));
  if (k == 1) return mask.clone();
  cv::Mat out;
  cv::dilate(mask, out, cv::getStructuringElement(cv::MORPH_ELLIPSE, {k, k}));
  return out;
}

int dilation_for_area(double area, int k, double growth) {
  if (!(growth > 0) || !(area > 0)) return k;
  const double wanted = growth * 2.0 * std::sqrt(area / M_PI);
  if (wanted >= kMaxDilation) return kMaxDilation;  // kMaxDilation is odd
  const int odd = 2 * static_cast<int>(std::lround((wanted - 1.0) / 2.0)) + 1;
  return std::max(k, odd);
}

cv::Mat dilate_mask_by_size(const cv::Mat& mask, int k, double growth) {
  cv::Mat out = dilate_mask(mask, k);
  if (!(growth > 0)) return out;
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  for (int i = 1; i < n; ++i) {
    const int ki = dilation_for_area(stats.at<int>(i, cv::CC_STAT_AREA), k, growth);
    if (ki == k) continue;  // already in `out`
    // The component alone, in its bounding box grown by the kernel's reach, dilated there:
    // a larger ellipse holds the smaller one, so OR-ing it in only adds pixels.
    const int r = ki / 2;
    const cv::Rect box(stats.at<int>(i, cv::CC_STAT_LEFT), stats.at<int>(i, cv::CC_STAT_TOP),
                       stats.at<int>(i, cv::CC_STAT_WIDTH), stats.at<int>(i, cv::CC_STAT_HEIGHT));
    const cv::Rect roi = cv::Rect(box.x - r, box.y - r, box.width + 2 * r, box.height + 2 * r) &
                         cv::Rect(0, 0, mask.cols, mask.rows);
    cv::Mat alone = labels(roi) == i;  // 0/255
    cv::Mat grown;
    cv::dilate(alone, grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, {ki, ki}), cv::Point(-1, -1), 1,
               cv::BORDER_CONSTANT, cv::Scalar(0));
    out(roi).setTo(1, grown);
  }
  return out;
}

}  // namespace raindrop::removal

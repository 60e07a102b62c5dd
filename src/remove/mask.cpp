#include "raindrop/remove/mask.h"

#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"

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

}  // namespace raindrop::removal

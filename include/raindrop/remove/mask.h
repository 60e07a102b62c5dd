#pragma once
// The binary raindrop mask between the RDN and the blend (docs/CONTRACTS.md section 2,
// steps 3-4): M0 = P > threshold (strictly, compared in float32, as the Python reference
// does), then M = dilation of M0 with OpenCV's k x k elliptical structuring element.
#include <opencv2/core.hpp>

namespace raindrop::removal {

// prob: CV_32FC1; dst: CV_8UC1 of the same size, 1 where prob > float(threshold), else 0
// (NaN probabilities give 0). dst may be a view into a larger mask.
void threshold_mask(const cv::Mat& prob, double threshold, cv::Mat dst);

// CV_8UC1 0/1 -> CV_8UC1 0/1, dilated with getStructuringElement(MORPH_ELLIPSE, {k, k}) and
// OpenCV's default anchor and border (pixels outside the image never count). k = 1: copy.
cv::Mat dilate_mask(const cv::Mat& mask, int k);

// The dilation size a drop of `area` mask pixels gets when the dilation grows with the drop:
// the odd size nearest growth x its equivalent diameter 2 sqrt(area / pi), never below k nor
// above kMaxDilation. growth 0: k.
int dilation_for_area(double area, int k, double growth);

// dilate_mask with a size per drop: each 8-connected component of `mask` is dilated by
// dilation_for_area(its area, k, growth), and the results are joined. Every component that
// gets k gives exactly dilate_mask(mask, k)'s pixels, so growth 0 is dilate_mask.
cv::Mat dilate_mask_by_size(const cv::Mat& mask, int k, double growth);

}  // namespace raindrop::removal

#include "raindrop/remove/fine_drops.h"

#include <algorithm>
#include <vector>

#include "raindrop/remove/surround_fill.h"

namespace raindrop::removal {
namespace {

// Planes of h x w floats inside `data` (3 of them, one after the other), as OpenCV matrices.
std::vector<cv::Mat> plane_views(float* data, int h, int w) {
  const size_t plane = static_cast<size_t>(h) * w;
  return {cv::Mat(h, w, CV_32F, data), cv::Mat(h, w, CV_32F, data + plane), cv::Mat(h, w, CV_32F, data + 2 * plane)};
}

}  // namespace

double fine_drop_scale(double scale) {
  const double fine = std::min(1.0, scale * kFineDropScaleFactor);
  return fine > scale ? fine : 0.0;
}

cv::Mat fill_fine_drops(const cv::Mat& rgb, const cv::Mat& mask, int max_area, double max_mad, cv::Mat* weight,
                        int* parts) {
  CV_Assert(rgb.type() == CV_32FC3 && mask.type() == CV_8UC1 && mask.size() == rgb.size());
  const int h = rgb.rows, w = rgb.cols;
  // surround_fill.h works on planar RGB: split into views of one buffer, merged back after.
  std::vector<float> planar(3 * static_cast<size_t>(h) * w);
  std::vector<cv::Mat> planes = plane_views(planar.data(), h, w);
  cv::split(rgb, planes);
  CV_Assert(planes[0].ptr<float>() == planar.data());  // written in place, not reallocated
  std::vector<float> filled = planar;
  cv::Mat chosen;
  cv::Mat parts_mask = mask;  // a header: with rim 0 (no growth into rims here) nothing is written
  *parts = fill_small_drops_from_surround(planar.data(), parts_mask, max_area, max_mad, filled, &chosen, 0);
  chosen.convertTo(*weight, CV_32F, 1.0 / 255.0);
  if (*parts == 0) return rgb.clone();
  cv::Mat out;
  cv::merge(plane_views(filled.data(), h, w), out);
  return out;
}

}  // namespace raindrop::removal

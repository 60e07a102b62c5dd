#include "raindrop/remove/fine_drops.h"

#include <algorithm>
#include <vector>

#include "raindrop/remove/surround_fill.h"

namespace raindrop::removal {

double fine_drop_scale(double scale) {
  const double fine = std::min(1.0, scale * kFineDropScaleFactor);
  return fine > scale ? fine : 0.0;
}

cv::Mat fill_fine_drops(const cv::Mat& rgb, const cv::Mat& mask, int max_area, double max_mad, cv::Mat* weight,
                        int* parts) {
  CV_Assert(rgb.type() == CV_32FC3 && mask.type() == CV_8UC1 && mask.size() == rgb.size());
  const int h = rgb.rows, w = rgb.cols;
  const size_t plane = static_cast<size_t>(h) * w;
  // surround_fill.h works on planar RGB.
  std::vector<float> planar(3 * plane);
  for (int y = 0; y < h; ++y) {
    const float* row = rgb.ptr<float>(y);
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) planar[c * plane + static_cast<size_t>(y) * w + x] = row[3 * x + c];
  }
  std::vector<float> filled = planar;
  cv::Mat chosen;
  *parts = fill_small_drops_from_surround(planar.data(), mask, max_area, max_mad, filled, &chosen);
  chosen.convertTo(*weight, CV_32F, 1.0 / 255.0);
  if (*parts == 0) return rgb.clone();
  planar.clear();
  planar.shrink_to_fit();
  cv::Mat out(h, w, CV_32FC3);
  for (int y = 0; y < h; ++y) {
    float* row = out.ptr<float>(y);
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) row[3 * x + c] = filled[c * plane + static_cast<size_t>(y) * w + x];
  }
  return out;
}

}  // namespace raindrop::removal

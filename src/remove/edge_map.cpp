#include "raindrop/remove/edge_map.h"

#include <cmath>

namespace raindrop::removal {

cv::Mat edge_map(const cv::Mat& rgb) {
  CV_Assert(rgb.type() == CV_32FC3);
  const int h = rgb.rows, w = rgb.cols;
  cv::Mat e(h, w, CV_32F);
  for (int y = 0; y < h; ++y) {
    const float* row = rgb.ptr<float>(y);
    const float* up = rgb.ptr<float>(y > 0 ? y - 1 : y);
    const float* down = rgb.ptr<float>(y + 1 < h ? y + 1 : y);
    float* out = e.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      const int xl = x > 0 ? x - 1 : x, xr = x + 1 < w ? x + 1 : x;
      float d[3];
      for (int c = 0; c < 3; ++c) {
        const float v = row[3 * x + c];
        const float right = std::fabs(v - row[3 * xr + c]);
        const float left = std::fabs(v - row[3 * xl + c]);
        const float below = std::fabs(v - down[3 * x + c]);
        const float above = std::fabs(v - up[3 * x + c]);
        d[c] = ((right + left) + below) + above;
      }
      out[x] = ((d[0] + d[1]) + d[2]) * 0.25f;
    }
  }
  return e;
}

}  // namespace raindrop::removal

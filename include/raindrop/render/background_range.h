#pragma once
// How much the background varies over a square footprint: the smallest and largest value of
// each channel over blocks of 2, 4, 8, ... frame pixels, for the `auto` supersampling rule
// (effect_policy.h). A drop shows the street strongly minified: one drop pixel's footprint on
// the background plane covers many frame pixels, and one ray samples one point of it. Where
// the footprint varies by less than the budget, any number of rays averages to within it of
// that one sample, and more rays change nothing that shows.
#include <vector>

#include <glm/vec3.hpp>
#include <opencv2/core.hpp>

#include "raindrop/render/background.h"

namespace raindrop {

class BackgroundRange {
 public:
  // `rgb8`: the frame (CV_8UC3) `sampler` samples; its border mode and sky are followed.
  BackgroundRange(const cv::Mat& rgb8, const BackgroundSampler& sampler);

  // Per channel, in [0, 1]: an upper bound on max - min of what the sampler returns over the
  // square `size` frame pixels wide centred at (x, y) (continuous pixel coordinates).
  glm::dvec3 range(double x, double y, double size) const;

 private:
  const BackgroundSampler& sampler_;
  std::vector<cv::Mat> lo_, hi_;  // CV_8UC3; level L: min and max over 2^L x 2^L blocks
};

}  // namespace raindrop

#pragma once
// Backgrounds the program draws itself, so that the default run needs no data set.
#include <opencv2/core.hpp>

namespace raindrop {

// Black-and-white checkerboard with a coloured grid: refraction and the inversion inside each
// drop are easiest to see on it.
cv::Mat demo_checkerboard(int width, int height);

// A stylised street: sky gradient, buildings with windows, road with lane markings. The
// layout is fixed (no randomness), so the demo is reproducible.
cv::Mat demo_street(int width, int height);

}  // namespace raindrop

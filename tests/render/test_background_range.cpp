// BackgroundRange (the auto supersampling rule's measure of a footprint): the range it gives
// bounds how far apart any two of the sampler's bilinear samples over the square can be,
// inside the frame, beyond its edges (mirror and clamp) and above it, fading into the sky.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "raindrop/render/background_range.h"

using namespace raindrop;

TEST(BackgroundRange, BoundsEverySampleOverTheSquare) {
  for (BorderMode border : {BorderMode::Mirror, BorderMode::Clamp}) {
    for (const cv::Size size : {cv::Size(37, 23), cv::Size(64, 32), cv::Size(101, 77)}) {
      cv::Mat img(size, CV_8UC3);
      cv::randu(img, 0, 256);
      BackgroundSampler sampler(img, border);
      sampler.set_sky({0.9, 0.8, 0.7}, 10);
      const BackgroundRange range(img, sampler);
      cv::RNG rng(size.width);
      for (int t = 0; t < 3000; ++t) {
        const double x = rng.uniform(-40.0, size.width + 40.0), y = rng.uniform(-40.0, size.height + 40.0);
        const double side = std::exp(rng.uniform(-1.0, 4.5));
        const glm::dvec3 bound = range.range(x, y, side);
        const glm::dvec3 centre = sampler.sample(x, y);
        for (int k = 0; k < 8; ++k) {
          const double qx = x + side * rng.uniform(-0.5, 0.5), qy = y + side * rng.uniform(-0.5, 0.5);
          const glm::dvec3 q = sampler.sample(qx, qy);
          for (int c = 0; c < 3; ++c)
            ASSERT_LE(std::abs(q[c] - centre[c]), bound[c] + 1e-9)
                << to_string(border) << " " << size << " at (" << x << ", " << y << "), side " << side << ", sample ("
                << qx << ", " << qy << ")";
        }
      }
    }
  }
}

// A flat frame has no range anywhere; one step of 100 levels shows only in squares that reach it.
TEST(BackgroundRange, FlatIsZeroAndAStepShowsWhereItIsReached) {
  cv::Mat img(64, 64, CV_8UC3, cv::Scalar(50, 60, 70));
  img.colRange(40, 64).setTo(cv::Scalar(150, 60, 70));
  const BackgroundSampler sampler(img, BorderMode::Mirror);
  const BackgroundRange range(img, sampler);
  EXPECT_EQ(range.range(10, 30, 8).x, 0);
  EXPECT_NEAR(range.range(36, 30, 8).x, 100 / 255.0, 1e-12);
  EXPECT_EQ(range.range(36, 30, 8).y, 0);
}

// The fine pass for small drops (raindrop/remove/fine_drops.h): its scale, and that of a mask
// it fills only the small parts over smooth surroundings, with their surroundings' colour,
// and leaves every other pixel as it was. (TrainedModels.FineDrops* runs it end to end.)
#include <random>

#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include "raindrop/remove/fine_drops.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

TEST(FineDrops, TheScaleIsOneAndAHalfTimesTheWorkingScaleAtMostTheImagesOwn) {
  EXPECT_DOUBLE_EQ(fine_drop_scale(0.4), 0.4 * 1.5);
  EXPECT_DOUBLE_EQ(fine_drop_scale(0.2), 0.2 * 1.5);
  EXPECT_DOUBLE_EQ(fine_drop_scale(0.8), 1.0);
  EXPECT_DOUBLE_EQ(fine_drop_scale(2.0 / 3.0), 1.0);
  // The networks saw every pixel already: no finer scale, no pass.
  EXPECT_EQ(fine_drop_scale(1.0), 0.0);
}

// Left half flat, right half random texture; a dark 4x4 drop in each, both in the mask, and a
// third, large one on the flat side. Only the small flat-side drop is filled: with the flat
// colour, weight 1 on its pixels and 0 everywhere else, every other pixel as it was.
TEST(FineDrops, OnlySmallPartsOverSmoothSurroundingsAreFilledWithThem) {
  const int h = 64, w = 128;
  const cv::Vec3f flat(0.6f, 0.5f, 0.4f);
  cv::Mat rgb(h, w, CV_32FC3, cv::Scalar(flat[0], flat[1], flat[2]));
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int y = 0; y < h; ++y)
    for (int x = w / 2; x < w; ++x) rgb.at<cv::Vec3f>(y, x) = cv::Vec3f(u(rng), u(rng), u(rng));
  cv::Mat mask(h, w, CV_8U, cv::Scalar(0));
  const cv::Rect smooth(10, 10, 6, 6), textured(90, 20, 6, 6), large(20, 30, 20, 20);
  for (const cv::Rect& r : {smooth, textured, large}) {
    rgb(r).setTo(cv::Scalar(0.05, 0.05, 0.05));
    mask(r).setTo(255);
  }
  cv::Mat weight;
  int parts = -1;
  const cv::Mat out = fill_fine_drops(rgb, mask, 100, 4.0, &weight, &parts);
  ASSERT_EQ(parts, 1);
  ASSERT_EQ(out.type(), CV_32FC3);
  ASSERT_EQ(weight.type(), CV_32F);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const bool filled = smooth.contains({x, y});
      ASSERT_EQ(weight.at<float>(y, x), filled ? 1.0f : 0.0f) << x << "," << y;
      const cv::Vec3f o = out.at<cv::Vec3f>(y, x), i = rgb.at<cv::Vec3f>(y, x);
      for (int c = 0; c < 3; ++c) {
        if (filled)
          ASSERT_NEAR(o[c], flat[c], 1e-5f) << x << "," << y;
        else
          ASSERT_EQ(o[c], i[c]) << x << "," << y;
      }
    }
  }
}

TEST(FineDrops, NothingToFillGivesTheInputAndNoWeight) {
  cv::Mat rgb(20, 30, CV_32FC3, cv::Scalar(0.3, 0.3, 0.3));
  cv::Mat weight;
  int parts = -1;
  const cv::Mat out = fill_fine_drops(rgb, cv::Mat(20, 30, CV_8U, cv::Scalar(0)), 150, 4.0, &weight, &parts);
  EXPECT_EQ(parts, 0);
  EXPECT_EQ(cv::countNonZero(weight), 0);
  EXPECT_EQ(cv::norm(out, rgb, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace removetest

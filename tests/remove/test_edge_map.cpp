// edge_map.h: the edge map the networks take beside the image, against the contract formula.
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "raindrop/remove/edge_map.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

cv::Mat random_rgb_float(int w, int h, int seed) {
  cv::Mat m(h, w, CV_32FC3);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::UNIFORM, 0.0, 1.0);
  return m;
}

TEST(EdgeMap, MatchesTheContractFormulaBitForBit) {
  for (const cv::Size s : {cv::Size(1, 1), cv::Size(2, 3), cv::Size(7, 5), cv::Size(33, 17)}) {
    const cv::Mat img = random_rgb_float(s.width, s.height, s.area());
    const cv::Mat e = edge_map(img);
    ASSERT_EQ(e.type(), CV_32FC1);
    ASSERT_EQ(e.size(), img.size());
    auto at = [&](int y, int x, int c) {
      y = std::clamp(y, 0, s.height - 1);
      x = std::clamp(x, 0, s.width - 1);
      return img.at<cv::Vec3f>(y, x)[c];
    };
    for (int y = 0; y < s.height; ++y) {
      for (int x = 0; x < s.width; ++x) {
        float d[3];
        for (int c = 0; c < 3; ++c) {
          const float v = at(y, x, c);
          d[c] = ((std::fabs(v - at(y, x + 1, c)) + std::fabs(v - at(y, x - 1, c))) + std::fabs(v - at(y + 1, x, c))) +
                 std::fabs(v - at(y - 1, x, c));
        }
        const float want = ((d[0] + d[1]) + d[2]) * 0.25f;
        ASSERT_EQ(e.at<float>(y, x), want) << "at " << x << "," << y << " of " << s;
      }
    }
  }
}

TEST(EdgeMap, KnownValues) {
  // A single white pixel on black: 4 neighbours differ by 1 in 3 channels -> 3; each
  // neighbour differs from it in one direction -> 3/4.
  cv::Mat img(5, 5, CV_32FC3, cv::Scalar::all(0));
  img.at<cv::Vec3f>(2, 2) = cv::Vec3f(1, 1, 1);
  const cv::Mat e = edge_map(img);
  EXPECT_FLOAT_EQ(e.at<float>(2, 2), 3.0f);
  EXPECT_FLOAT_EQ(e.at<float>(1, 2), 0.75f);
  EXPECT_FLOAT_EQ(e.at<float>(2, 3), 0.75f);
  EXPECT_FLOAT_EQ(e.at<float>(1, 1), 0.0f);
  // Uniform image: no edges anywhere, the border included (replicate rule).
  const cv::Mat flat = edge_map(cv::Mat(4, 6, CV_32FC3, cv::Scalar(0.2, 0.5, 0.9)));
  EXPECT_EQ(cv::countNonZero(flat), 0);
}

}  // namespace
}  // namespace removetest

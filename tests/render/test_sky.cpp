// The sky's colour estimate (sky.h): the mean of the brightest tenth of the top third's pixels.
// Its two passes run on all threads; their sums are of integers, so the estimate is the same,
// to the bit, as one pass after another on one thread (written out here), whatever the
// threads and the frame's size.
#include <algorithm>
#include <array>
#include <cstring>

#include <gtest/gtest.h>
#include <glm/common.hpp>
#include <tbb/task_arena.h>

#include "raindrop/render/sky.h"

using namespace raindrop;

namespace {

glm::dvec3 one_pass_after_another(const cv::Mat& rgb8, double gain) {
  const int rows = std::max(1, rgb8.rows / 3);
  auto luma = [](const cv::Vec3b& p) { return (299 * p[0] + 587 * p[1] + 114 * p[2]) / 1000; };
  std::array<long, 256> hist{};
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < rgb8.cols; ++x) ++hist[luma(rgb8.at<cv::Vec3b>(y, x))];
  const long total = static_cast<long>(rows) * rgb8.cols;
  long above = 0;
  int cut = 255;
  for (; cut > 0; --cut) {
    above += hist[cut];
    if (above * 10 >= total) break;
  }
  glm::dvec3 sum(0.0);
  long n = 0;
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < rgb8.cols; ++x) {
      const cv::Vec3b p = rgb8.at<cv::Vec3b>(y, x);
      if (luma(p) < cut) continue;
      sum += glm::dvec3(p[0], p[1], p[2]);
      ++n;
    }
  }
  return glm::min(sum / (255.0 * std::max(1L, n)) * gain, glm::dvec3(1.0));
}

bool same_bits(const glm::dvec3& a, const glm::dvec3& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

}  // namespace

TEST(Sky, TheEstimateIsTheOneThreadSumsToTheBit) {
  cv::RNG rng(5);
  int compared = 0;
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(7, 2), cv::Size(97, 61), cv::Size(640, 480), cv::Size(2048, 1024)}) {
    cv::Mat img(size, CV_8UC3);
    rng.fill(img, cv::RNG::UNIFORM, 0, 256);
    // A bright band, so that the brightest tenth is a region, not noise.
    img(cv::Rect(0, 0, size.width, std::max(1, size.height / 10))).setTo(cv::Scalar(200, 220, 250));
    for (double gain : {1.0, 1.7}) {
      const glm::dvec3 want = one_pass_after_another(img, gain);
      for (int threads : {1, 2}) {
        glm::dvec3 got;
        tbb::task_arena(threads).execute([&] { got = estimate_sky_rgb(img, gain); });
        EXPECT_TRUE(same_bits(got, want)) << size << " gain " << gain << " threads " << threads << ": " << got.x
                                          << " " << got.y << " " << got.z << " against " << want.x << " " << want.y
                                          << " " << want.z;
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, 20);
  // The band's colour where it is the brightest tenth; clamped to 1 with a large gain.
  cv::Mat band(300, 400, CV_8UC3, cv::Scalar(10, 10, 10));
  band(cv::Rect(0, 0, 400, 30)).setTo(cv::Scalar(200, 220, 250));
  const glm::dvec3 sky = estimate_sky_rgb(band, 1.0);
  EXPECT_DOUBLE_EQ(sky.x, 200 / 255.0);
  EXPECT_DOUBLE_EQ(sky.z, 250 / 255.0);
  EXPECT_DOUBLE_EQ(estimate_sky_rgb(band, 10.0).z, 1.0);
}

// sensor.h: the camera's noise and JPEG on the rainy image. The noise has the drawn sigma and
// no bias, depends only on the sample seed, and JPEG leaves its 8x8 block edges.
#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"
#include "raindrop/render/scene_config.h"
#include "raindrop/render/sensor.h"

namespace raindrop {
namespace {

cv::Mat grey(int w, int h, int level) { return cv::Mat(h, w, CV_8UC3, cv::Scalar::all(level)); }

// A smooth image (a diagonal ramp): no edges of its own, so block edges show.
cv::Mat ramp(int w, int h) {
  cv::Mat m(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) m.at<cv::Vec3b>(y, x) = cv::Vec3b(40 + (x + y) * 150 / (w + h), 90, 200 - y * 100 / h);
  return m;
}

// Mean absolute step between neighbouring columns across 8-px block boundaries (x = 8k - 1 |
// 8k), over the mean step between the other neighbouring columns.
double blockiness(const cv::Mat& rgb) {
  cv::Mat g;
  cv::cvtColor(rgb, g, cv::COLOR_RGB2GRAY);
  double at = 0, off = 0;
  long n_at = 0, n_off = 0;
  for (int y = 0; y < g.rows; ++y)
    for (int x = 1; x < g.cols; ++x) {
      const double d = std::abs(g.at<unsigned char>(y, x) - g.at<unsigned char>(y, x - 1));
      if (x % 8 == 0) {
        at += d;
        ++n_at;
      } else {
        off += d;
        ++n_off;
      }
    }
  return (at / n_at) / (off / n_off + 1e-9);
}

TEST(Sensor, NoiseHasTheDrawnSigmaAndNoBias) {
  for (const double sigma : {1.0, 4.0}) {
    cv::Mat img = grey(256, 256, 128);
    apply_sensor(img, {sigma, 0}, 42);
    cv::Mat diff;
    img.convertTo(diff, CV_64F);
    diff -= cv::Scalar::all(128.0);
    cv::Scalar mean, sd;
    cv::meanStdDev(diff.reshape(1), mean, sd);
    // Rounding to whole levels adds 1/12 of a level squared to the variance.
    EXPECT_NEAR(sd[0], std::sqrt(sigma * sigma + 1.0 / 12.0), 0.03 * sigma) << "sigma " << sigma;
    EXPECT_NEAR(mean[0], 0.0, 0.02) << "sigma " << sigma;
  }
}

TEST(Sensor, NoiseDependsOnTheSampleSeedOnly) {
  cv::Mat a = grey(64, 48, 100), b = a.clone(), c = a.clone();
  apply_sensor(a, {3.0, 0}, 7);
  apply_sensor(b, {3.0, 0}, 7);
  apply_sensor(c, {3.0, 0}, 8);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_INF), 0.0);
  // Values stay in range at the ends of the scale (clipped, as a quantiser does).
  for (const int level : {0, 255}) {
    cv::Mat e = grey(32, 32, level);
    apply_sensor(e, {10.0, 0}, 1);
    double lo = 0, hi = 0;
    cv::minMaxLoc(e.reshape(1), &lo, &hi);
    EXPECT_GE(lo, 0);
    EXPECT_LE(hi, 255);
  }
}

TEST(Sensor, JpegLeavesItsBlockEdges) {
  const cv::Mat clean = ramp(256, 128);
  cv::Mat noisy = clean.clone();
  apply_sensor(noisy, {2.0, 0}, 3);
  cv::Mat low = noisy.clone(), high = noisy.clone(), smooth = clean.clone();
  apply_sensor(low, {0.0, 20}, 3);
  apply_sensor(high, {0.0, 100}, 3);
  apply_sensor(smooth, {0.0, 100}, 3);
  EXPECT_LT(blockiness(noisy), 1.1);
  EXPECT_GT(blockiness(low), 1.3) << "quality 20 should show 8x8 blocks";
  // At quality 100 a smooth image comes back almost exactly (noise loses some of its colour to
  // the chroma subsampling), and a low quality loses more.
  EXPECT_GT(cv::PSNR(smooth, clean), 40.0);
  EXPECT_LT(cv::PSNR(low, noisy), cv::PSNR(high, noisy));
  EXPECT_EQ(low.size(), noisy.size());
  EXPECT_EQ(low.type(), CV_8UC3);
}

TEST(Sensor, DrawsStayInTheScenesRanges) {
  SceneConfig off;
  EXPECT_FALSE(sample_sensor(off, 5).any()) << "no sensor effect: nothing drawn";
  SceneConfig on;
  on.sensor.enabled = true;
  on.sensor.noise_levels = {0.5, 2.5};
  on.sensor.jpeg_quality = {60, 90};
  bool varied = false;
  const SensorSample first = sample_sensor(on, 0);
  for (std::uint64_t seed = 0; seed < 200; ++seed) {
    const SensorSample s = sample_sensor(on, seed);
    EXPECT_GE(s.noise_sigma, 0.5);
    EXPECT_LE(s.noise_sigma, 2.5);
    EXPECT_GE(s.jpeg_quality, 60);
    EXPECT_LE(s.jpeg_quality, 90);
    varied = varied || s.jpeg_quality != first.jpeg_quality;
  }
  EXPECT_TRUE(varied);
  on.sensor.jpeg_quality = {0, 0};
  EXPECT_EQ(sample_sensor(on, 3).jpeg_quality, 0) << "[0, 0]: not compressed";
}

TEST(Sensor, SceneFilesNameItAndPrintItBack) {
  const SceneConfig c = parse_scene_json(
      R"({"effects": {"sensor": {"noise_levels": [1, 2], "jpeg_quality": [70, 95]}}})", "test");
  EXPECT_TRUE(c.sensor.enabled);
  EXPECT_EQ(c.sensor.jpeg_quality.lo, 70);
  const SceneConfig back = parse_scene_json(scene_to_json(c), "printed");
  EXPECT_TRUE(back.sensor.enabled);
  EXPECT_EQ(back.sensor.noise_levels.hi, 2);
  EXPECT_EQ(back.sensor.jpeg_quality.hi, 95);
  EXPECT_FALSE(parse_scene_json(R"({"effects": {}})", "test").sensor.enabled);
  for (const char* bad : {R"({"effects": {"sensor": {"jpeg_quality": [0, 50]}}})",
                          R"({"effects": {"sensor": {"jpeg_quality": [50, 101]}}})",
                          R"({"effects": {"sensor": {"jpeg_quality": [50.5, 60]}}})",
                          R"({"effects": {"sensor": {"noise_levels": [-1, 2]}}})",
                          R"({"effects": {"sensor": {"noise": 2}}})", R"({"effects": {"sensor": "auto"}})"}) {
    EXPECT_THROW(parse_scene_json(bad, "test"), Error) << bad;
  }
}

}  // namespace
}  // namespace raindrop

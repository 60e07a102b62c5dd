// End to end: the scene effect "sensor" (sensor.h) adds the camera's noise and JPEG to the
// rainy image only: the clean image and the mask are byte for byte those of the same scene
// without it, the drops are the same, and the manifest records what was drawn.
#include "cli_test_util.h"

namespace clitest {
namespace {

class RenderSensor : public RainyOnlyEffect {
 protected:
  RenderSensor() : RainyOnlyEffect("sensor") {}

  // Mean absolute difference of the two folders' rainy images outside the drops.
  double rainy_change_outside(const std::string& a, const std::string& b, const std::string& id) {
    const auto x = read_image(tmp / a / "rainy" / (id + ".png")), y = read_image(tmp / b / "rainy" / (id + ".png"));
    const auto mask = read_image(tmp / a / "mask" / (id + ".png"));
    EXPECT_TRUE(x && y && mask);
    if (!x || !y || !mask) return -1;
    cv::Mat diff;
    cv::absdiff(x->pixels, y->pixels, diff);
    const cv::Mat outside = mask->pixels == 0;
    EXPECT_GT(cv::countNonZero(outside), 0);
    return cv::mean(diff, outside)[0];
  }
};

TEST_F(RenderSensor, OnlyTheRainyImageChanges) {
  const json plain = render("plain", "");
  const json noise = render("noise", R"({"noise_levels": [2, 3]})");
  const json jpeg = render("jpeg", R"({"noise_levels": 0, "jpeg_quality": [60, 80]})");
  ASSERT_FALSE(plain.is_null() || noise.is_null() || jpeg.is_null());
  const std::string id = plain.at("id");
  EXPECT_FALSE(plain.contains("sensor"));
  expect_only_rainy_changed(plain, noise, "noise");
  expect_only_rainy_changed(plain, jpeg, "jpeg");
  // Noise: drawn in range, not compressed, and everywhere: outside the drops the rainy image
  // differs from the plain render by about 0.8 sigma on average (the mean of |N(0, sigma)|).
  const double sigma = noise.at("sensor").at("noise_sigma").get<double>();
  EXPECT_GE(sigma, 2.0);
  EXPECT_LE(sigma, 3.0);
  EXPECT_EQ(noise.at("sensor").at("jpeg_quality").get<int>(), 0);
  EXPECT_NEAR(rainy_change_outside("plain", "noise", id), 0.8 * sigma, 0.25 * sigma);
  // JPEG: drawn in range; the rainy image changes outside the drops too.
  const int quality = jpeg.at("sensor").at("jpeg_quality").get<int>();
  EXPECT_GE(quality, 60);
  EXPECT_LE(quality, 80);
  EXPECT_GT(rainy_change_outside("plain", "jpeg", id), 0.2);
}

}  // namespace
}  // namespace clitest

// End to end: the scene effect "sensor" (sensor.h) adds the camera's noise and JPEG to the
// rainy image only: the clean image and the mask are byte for byte those of the same scene
// without it, the drops are the same, and the manifest records what was drawn.
#include "cli_test_util.h"

namespace clitest {
namespace {

class RenderSensor : public ::testing::Test {
 protected:
  void SetUp() override { write_image(tmp / "street.png", make_background(256, 128, 2)); }

  // Renders street.png with the paper's imaging model and `sensor` (a JSON object, or "" for
  // none) into folder `name`; returns its one manifest record.
  json render(const std::string& name, const std::string& sensor) {
    const std::string effects = R"("blur": {})" + (sensor.empty() ? "" : R"(, "sensor": )" + sensor);
    write_file(tmp / (name + ".json"),
               R"({"name": "sensor-test", "glass_distance_cm": 20, "drop_count": 20, "effects": {)" + effects + "}}");
    const auto r = run_render({"-i", "street.png", "--out", name, "--scene", name + ".json", "--seed", "5", "-j", "1", "-q"},
                              tmp.path());
    EXPECT_EQ(r.code, 0) << r.describe();
    const auto records = read_manifest(tmp / name);
    EXPECT_EQ(records.size(), 1u);
    return records.empty() ? json() : records[0];
  }

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

  TempDir tmp;
};

TEST_F(RenderSensor, OnlyTheRainyImageChanges) {
  const json plain = render("plain", "");
  const json noise = render("noise", R"({"noise_levels": [2, 3]})");
  const json jpeg = render("jpeg", R"({"noise_levels": 0, "jpeg_quality": [60, 80]})");
  ASSERT_FALSE(plain.is_null() || noise.is_null() || jpeg.is_null());
  const std::string id = plain.at("id");
  EXPECT_FALSE(plain.contains("sensor"));
  for (const std::string other : {"noise", "jpeg"}) {
    SCOPED_TRACE(other);
    const json& rec = other == "noise" ? noise : jpeg;
    EXPECT_EQ(read_file(tmp / "plain/clean" / (id + ".png")), read_file(tmp / other / "clean" / (id + ".png")));
    EXPECT_EQ(read_file(tmp / "plain/mask" / (id + ".png")), read_file(tmp / other / "mask" / (id + ".png")));
    EXPECT_EQ(plain.at("drops"), rec.at("drops")) << "turning the sensor on must not change the scene's draws";
    EXPECT_NE(std::find(rec.at("effects").begin(), rec.at("effects").end(), "sensor"), rec.at("effects").end());
    EXPECT_EQ(rec.at("sensor").at("applies_to"), "rainy");
  }
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

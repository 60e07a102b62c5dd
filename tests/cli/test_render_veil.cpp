// End to end: the scene effect "veil" (veil.h) hazes the rainy image only: the clean image and
// the mask are byte for byte those of the same scene without it, the drops are the same, the
// manifest records the draw, and a veil too thin to move a pixel by half a level is skipped
// (the rainy image then is the plain render's, byte for byte).
#include <cmath>

#include "cli_test_util.h"

namespace clitest {
namespace {

class RenderVeil : public RainyOnlyEffect {
 protected:
  RenderVeil() : RainyOnlyEffect("veil") {}

  // Standard deviation of the green channel outside the drops of folder `mask_of`.
  double contrast_outside(const std::string& folder, const std::string& mask_of, const std::string& id) {
    const auto x = read_image(tmp / folder / "rainy" / (id + ".png"));
    const auto mask = read_image(tmp / mask_of / "mask" / (id + ".png"));
    EXPECT_TRUE(x && mask);
    if (!x || !mask) return -1;
    std::vector<cv::Mat> channels;
    cv::split(x->pixels, channels);
    cv::Scalar mean, sd;
    cv::meanStdDev(channels[1], mean, sd, mask->pixels == 0);
    return sd[0];
  }
};

TEST_F(RenderVeil, OnlyTheRainyImageChangesAndLosesContrast) {
  const json plain = render("plain", "");
  const json veiled = render("veiled", R"({"optical_depth": [0.2, 0.3], "spread_deg": [4, 6]})");
  const json thin = render("thin", R"({"optical_depth": [0, 0.0001], "spread_deg": [4, 6]})");
  ASSERT_FALSE(plain.is_null() || veiled.is_null() || thin.is_null());
  const std::string id = plain.at("id");
  EXPECT_FALSE(plain.contains("veil"));
  expect_only_rainy_changed(plain, veiled, "veiled");
  expect_only_rainy_changed(plain, thin, "thin");
  // The draw, as recorded: in range, s = 1 - exp(-depth), sigma = fx tan(spread).
  const json& v = veiled.at("veil");
  const double depth = v.at("optical_depth"), spread = v.at("spread_deg"), fx = veiled.at("camera").at("fx");
  EXPECT_GE(depth, 0.2);
  EXPECT_LE(depth, 0.3);
  EXPECT_NEAR(v.at("scattered_fraction").get<double>(), 1 - std::exp(-depth), 1e-12);
  EXPECT_NEAR(v.at("sigma_px").get<double>(), fx * std::tan(spread * M_PI / 180), 1e-9);
  EXPECT_TRUE(v.at("on").get<bool>());
  // Contrast outside the drops falls by roughly the scattered fraction (in 8-bit codes, not
  // linear light, and the lobe is not much wider than the background's structure: loosely).
  const double before = contrast_outside("plain", "plain", id), after = contrast_outside("veiled", "plain", id);
  const double s = v.at("scattered_fraction");
  EXPECT_LT(after, (1 - 0.4 * s) * before) << before << " -> " << after;
  EXPECT_GT(after, (1 - 1.5 * s) * before) << before << " -> " << after;
  // Too thin to see: skipped, said so, and the rainy image is the plain one.
  EXPECT_FALSE(thin.at("veil").at("on").get<bool>());
  EXPECT_EQ(read_file(tmp / "plain/rainy" / (id + ".png")), read_file(tmp / "thin/rainy" / (id + ".png")));
}

}  // namespace
}  // namespace clitest

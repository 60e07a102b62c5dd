// End to end: the scene effect "trails" (trails.h) through raindrop-render. The manifest lists
// the drops as without trails, in their order, then the trails' caps, each naming its drop;
// only drops that slid changed, and only in size; the mask grows by the trails.
#include <opencv2/core.hpp>

#include "cli_test_util.h"

namespace clitest {
namespace {

class RenderTrails : public RainyOnlyEffect {
 protected:
  RenderTrails() : RainyOnlyEffect("trails") {}
};

TEST_F(RenderTrails, TheManifestNamesEachCapsDropAndTheMaskGrows) {
  const json plain = render("plain", "");
  // Little hysteresis: most of the scene's drops slide.
  const json trails = render("trails", R"({"hysteresis": 0.02, "spacing": 0.8})");
  ASSERT_FALSE(plain.is_null() || trails.is_null());
  const json &before = plain.at("drops"), &after = trails.at("drops");
  ASSERT_GT(after.size(), before.size());
  EXPECT_NE(std::find(trails.at("effects").begin(), trails.at("effects").end(), "trails"), trails.at("effects").end());
  int slid = 0;
  for (size_t i = 0; i < before.size(); ++i) {
    EXPECT_FALSE(after[i].contains("trail_of"));
    EXPECT_EQ(after[i].at("center_cm"), before[i].at("center_cm"));
    EXPECT_EQ(after[i].at("contact_angle_deg"), before[i].at("contact_angle_deg"));
    const double a = after[i].at("footprint_radius_cm"), b = before[i].at("footprint_radius_cm");
    EXPECT_LE(a, b);
    slid += a < b;
  }
  std::vector<bool> has_trail(before.size(), false);
  for (size_t i = before.size(); i < after.size(); ++i) {
    const int parent = after[i].at("trail_of");
    ASSERT_GE(parent, 0);
    ASSERT_LT(parent, static_cast<int>(before.size()));
    has_trail[parent] = true;
  }
  // A drop shrank exactly when it has a trail.
  for (size_t i = 0; i < before.size(); ++i)
    EXPECT_EQ(has_trail[i], after[i].at("footprint_radius_cm").get<double>() < before[i].at("footprint_radius_cm").get<double>()) << i;
  EXPECT_GT(slid, 0);
  const std::string id = plain.at("id");
  const auto m0 = read_image(tmp / "plain/mask" / (id + ".png")), m1 = read_image(tmp / "trails/mask" / (id + ".png"));
  ASSERT_TRUE(m0 && m1);
  EXPECT_GT(cv::countNonZero(m1->pixels), cv::countNonZero(m0->pixels));
}

}  // namespace
}  // namespace clitest

// End-to-end: a scene that leaves dispersion, gravity and supersampling to its physics
// ("auto", docs/SCENES.md) records in each manifest line what was simulated and why, for the
// frame and for every drop, and the drops' recorded shapes are those rendered.
#include "cli_test_util.h"

namespace clitest {
namespace {

TEST(RenderEffectsAuto, ManifestSaysWhatWasSimulatedAndWhy) {
  TempDir tmp;
  write_image(tmp / "street.png", make_background(256, 128, 0));
  // Drops from a tenth of a pixel to a dozen pixels across: auto keeps some effects, skips others.
  write_file(tmp / "scene.json", R"({
    "name": "auto-test", "glass_distance_cm": 10, "tilt_deg": 60, "drop_count": 40,
    "footprint_radius_cm": [0.001, 0.25], "size_distribution": "log-uniform", "min_gap_cm": 0.005,
    "effects": {"dispersion": "auto", "gravity": {"auto": true, "elongation": [1.1, 1.3]}},
    "quality": {"samples_per_pixel": 4, "supersample": "auto"}})");
  const auto r = run_render({"-i", "street.png", "--out", "out", "--scene", "scene.json", "-j", "1", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto records = read_manifest(tmp / "out");
  ASSERT_EQ(records.size(), 1u);
  const json& rec = records[0];
  EXPECT_EQ(rec.at("effects"), json({"refraction", "dark_band", "dispersion-auto", "gravity-auto"}));
  const json& why = rec.at("effects_auto");
  int on[2] = {0, 0}, off[2] = {0, 0};
  const char* names[2] = {"dispersion", "gravity"};
  for (int e = 0; e < 2; ++e) {
    SCOPED_TRACE(names[e]);
    const json& d = why.at(names[e]);
    EXPECT_FALSE(d.at("why").get<std::string>().empty());
    EXPECT_EQ(d.at("drops_on").get<int>() + d.at("drops_off").get<int>(), static_cast<int>(rec.at("drops").size()));
    for (const json& drop : rec.at("drops")) {
      const bool simulated = drop.at(names[e]).at("on").get<bool>();
      (simulated ? on : off)[e] += 1;
      // "on" means the change would reach the budget (2 levels).
      EXPECT_EQ(simulated, drop.at(names[e]).at("levels").get<double>() >= 2.0);
    }
    EXPECT_EQ(d.at("drops_on").get<int>(), on[e]);
    EXPECT_EQ(d.at("on").get<bool>(), on[e] > 0);
  }
  EXPECT_GT(on[0], 0);
  EXPECT_GT(off[0], 0);
  EXPECT_GT(off[1], 0);
  // A drop whose gravity was skipped is recorded (and was rendered) as a spherical cap.
  for (const json& drop : rec.at("drops")) {
    if (drop.at("gravity").at("on").get<bool>()) continue;
    EXPECT_EQ(drop.at("elongation").get<double>(), 1.0);
    EXPECT_EQ(drop.at("flattening").get<double>(), 1.0);
  }
  const json& ss = why.at("supersample");
  EXPECT_GT(ss.at("pixels").get<long>(), 0);
  EXPECT_NE(ss.at("why").get<std::string>().find("4 samples"), std::string::npos) << ss.dump();
}

// A scene without "auto" writes no effects_auto (its manifest is as it always was).
TEST(RenderEffectsAuto, ExplicitScenesWriteNoEffectsAuto) {
  TempDir tmp;
  write_image(tmp / "street.png", make_background(128, 64, 1));
  const auto r = run_render({"-i", "street.png", "--out", "out", "--scene", "full-physics", "-j", "1", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto records = read_manifest(tmp / "out");
  ASSERT_EQ(records.size(), 1u);
  EXPECT_FALSE(records[0].contains("effects_auto"));
  EXPECT_FALSE(records[0].at("drops").at(0).contains("dispersion"));
}

}  // namespace
}  // namespace clitest

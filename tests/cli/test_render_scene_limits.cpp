// End-to-end: scene files that would make raindrop-render run out of memory or time, or that
// the JSON parser cannot hold, are refused up front with one line naming the file, exit code 1,
// and nothing written.
#include <chrono>
#include <cmath>

#include "cli_test_util.h"

namespace clitest {
namespace {

// Renders good.png with the scene file holding `scene_json`; returns the run.
RunResult render_with_scene(const TempDir& tmp, const std::string& scene_json) {
  write_image(tmp / "good.png", make_background(96, 64, 0));
  write_file(tmp / "scene.json", scene_json);
  return run_render({"-i", "good.png", "--out", "out", "--scene", "scene.json", "-j", "1"}, tmp.path());
}

// "mesh-4096-flat" passed validation and allocated until the machine killed the run.
TEST(RenderSceneLimit, MeshSegmentsAreBounded) {
  TempDir tmp;
  const auto r = render_with_scene(tmp, R"({"name": "fine", "quality": {"geometry": "mesh-4096-flat"}})");
  expect_clean_failure(r, tmp / "out", "scene.json");
  EXPECT_NE(r.err.find("mesh-4096-flat"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "out"));
}

// Within the segment bound, segments x drops is bounded too (about 4.5 MB a drop at 256).
TEST(RenderSceneLimit, MeshMemoryIsBounded) {
  TempDir tmp;
  const auto r = render_with_scene(
      tmp, R"({"name": "many", "drop_count": [100, 500], "quality": {"geometry": "mesh-256-smooth"}})");
  expect_clean_failure(r, tmp / "out", "scene.json");
  EXPECT_NE(r.err.find("GB"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "out"));
}

// 1e309 is valid JSON but no double: the parser's out_of_range was printed without the file.
TEST(RenderSceneLimit, NumberTooLargeNamesTheFile) {
  TempDir tmp;
  const auto r = render_with_scene(tmp, R"({"name": "huge", "glass_distance_cm": 1e309})");
  expect_clean_failure(r, tmp / "out", "scene.json");
  EXPECT_NE(r.err.find("1e309"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "out"));
}

// 5000 drops passed validation and made placement and rendering crawl.
TEST(RenderSceneLimit, DropCountIsBounded) {
  TempDir tmp;
  const auto r = render_with_scene(tmp, R"({"name": "crowd", "drop_count": 5000, "allow_overlap": true})");
  expect_clean_failure(r, tmp / "out", "scene.json");
  EXPECT_NE(r.err.find("drop_count"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "out"));
}

// The most drops, large and overlapping, with the effects and edge supersampling of the
// full-physics preset, finish quickly: before overlaps were bounded every drop piled on the
// others (this run took 6 s, and 50 s with the whole full-physics preset; now under 1 s).
TEST(RenderSceneLimit, ManyOverlappingDropsFinishQuickly) {
  TempDir tmp;
  write_image(tmp / "good.png", make_background(128, 64, 0));
  write_file(tmp / "scene.json", R"({"name": "pile", "drop_count": 1000, "allow_overlap": true,
      "sphere_radius_cm": [10, 50], "quality": {"samples_per_pixel": 4},
      "effects": {"blur": {"method": "disk-aa"}, "fresnel": {}, "dispersion": {}, "gravity": {}}})");
  const auto start = std::chrono::steady_clock::now();
  const auto r = run_render({"-i", "good.png", "--out", "out", "--scene", "scene.json", "-j", "1", "-q"}, tmp.path());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_LT(seconds, 20.0) << "1000 overlapping drops on 128x64 took " << seconds << " s";
  const auto records = read_manifest(tmp / "out");
  ASSERT_EQ(records.size(), 1u);
  std::vector<std::pair<double, double>> centres;
  std::vector<double> radii;
  for (const auto& d : records[0].at("drops")) {
    centres.emplace_back(d.at("center_cm")[0].get<double>(), d.at("center_cm")[1].get<double>());
    radii.push_back(d.at("footprint_radius_cm").get<double>() * d.value("elongation", 1.0));
  }
  ASSERT_FALSE(centres.empty());
  // The manifest lists the drops in the order they were placed: each overlaps at most 4 of
  // the drops before it (so no point is under more than 5).
  int most = 0;
  for (size_t i = 0; i < centres.size(); ++i) {
    int overlaps = 0;
    for (size_t j = 0; j < i; ++j) {
      const double dx = centres[i].first - centres[j].first, dy = centres[i].second - centres[j].second;
      if (std::sqrt(dx * dx + dy * dy) < radii[i] + radii[j] - 1e-9) ++overlaps;
    }
    most = std::max(most, overlaps);
  }
  EXPECT_GT(most, 0) << "the drops should overlap";
  EXPECT_LE(most, 4);
}

}  // namespace
}  // namespace clitest

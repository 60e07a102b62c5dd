// End-to-end: scene files that would make raindrop-render run out of memory or time, or that
// the JSON parser cannot hold, are refused up front with one line naming the file, exit code 1,
// and nothing written.
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

}  // namespace
}  // namespace clitest

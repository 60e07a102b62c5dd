// End to end: a camera focused on the glass (camera.focus_distance_cm) writes the street out of
// focus as the clean image, each variant its own; outside the mask the rainy image is that clean
// image; the drops are those of the same scene focused on the background; the manifest says so.
#include "cli_test_util.h"

namespace clitest {
namespace {

// street.png in `tmp` rendered into the folder `name` with the scene {"name": name, <fields>}
// (written as name.json) and `flags` beside the usual ones; its manifest.
std::vector<json> render_scene(const TempDir& tmp, const std::string& name, const std::string& fields,
                               std::vector<std::string> flags) {
  write_file(tmp / (name + ".json"), R"({"name": ")" + name + R"(", )" + fields + "}");
  std::vector<std::string> args = {"-i", "street.png", "--out", name, "--scene", name + ".json", "-j", "2", "-q"};
  args.insert(args.end(), flags.begin(), flags.end());
  const auto r = run_render(args, tmp.path());
  EXPECT_EQ(r.code, 0) << r.describe();
  return read_manifest(tmp / name);
}

TEST(RenderFocus, FocusOnTheGlassDefocusesTheCleanImageOfEachVariant) {
  TempDir tmp;
  const cv::Mat street = make_background(256, 128, 2);
  write_image(tmp / "street.png", street);
  auto scene = [&](const std::string& name, const std::string& focus) {
    return render_scene(tmp, name,
                        R"("glass_distance_cm": [8, 12], "drop_count": 30, "footprint_radius_cm": [0.05, 0.2],
                           "tilt_deg": 80, "camera": {"f_number": [1.8, 2.8], "focal_length_mm": 5,
                           "focus_distance_cm": )" + focus + "}",
                        {"--variants", "2", "--seed", "3"});
  };
  const auto glass = scene("glass", R"("glass")"), background = scene("background", R"("background")");
  ASSERT_EQ(glass.size(), 2u);
  ASSERT_EQ(background.size(), 2u);
  std::vector<std::string> cleans;
  for (size_t i = 0; i < 2; ++i) {
    const json& g = glass[i];
    const std::string id = g.at("id");
    SCOPED_TRACE(id);
    EXPECT_EQ(g.at("drops").size(), background[i].at("drops").size());
    for (size_t k = 0; k < g.at("drops").size(); ++k)
      EXPECT_EQ(g.at("drops")[k].at("center_cm"), background[i].at("drops")[k].at("center_cm"));
    EXPECT_TRUE(g.at("lens").at("background_defocused").get<bool>());
    EXPECT_GT(g.at("lens").at("background_coc_px").get<double>(), 2.0);
    EXPECT_DOUBLE_EQ(g.at("lens").at("focus_distance_cm").get<double>(), g.at("scene").at("glass_distance_cm").get<double>());
    EXPECT_FALSE(background[i].at("lens").at("background_defocused").get<bool>());
    // The clean image is the street out of focus, not the input; the background-focused one is.
    const auto clean = read_image(tmp / "glass/clean" / (id + ".png"));
    const auto sharp = read_image(tmp / "background/clean" / (id + ".png"));
    const auto rainy = read_image(tmp / "glass/rainy" / (id + ".png"));
    const auto mask = read_image(tmp / "glass/mask" / (id + ".png"));
    const auto alpha = read_image(tmp / "glass/alpha" / (id + ".png"));
    ASSERT_TRUE(clean && sharp && rainy && mask && alpha);
    EXPECT_EQ(cv::norm(sharp->pixels, street, cv::NORM_INF), 0);
    EXPECT_GT(cv::norm(clean->pixels, street, cv::NORM_L1) / street.total(), 1.0);
    // Wherever no ray met a drop (alpha 0; the drops in focus are traced through the aperture,
    // so their coverage is a fraction at the outline) the rainy image is the clean one.
    cv::Mat outside_rainy, outside_clean;
    rainy->pixels.copyTo(outside_rainy, alpha->pixels == 0);
    clean->pixels.copyTo(outside_clean, alpha->pixels == 0);
    EXPECT_EQ(cv::norm(outside_rainy, outside_clean, cv::NORM_INF), 0);
    // The drops in focus were traced through the aperture: the manifest counts them, and their
    // outlines are antialiased by the lens (coverage strictly between 0 and 1).
    EXPECT_GT(g.at("lens").at("drops_traced_through_aperture").get<int>(), 0);
    EXPECT_GT(cv::countNonZero((alpha->pixels > 0) & (alpha->pixels < 65535)), 0);
    EXPECT_GT(cv::countNonZero(mask->pixels), 0);
    cleans.push_back(read_file(tmp / "glass/clean" / (id + ".png")));
  }
  // Each variant draws its own lens, so its own street blur.
  EXPECT_NE(cleans[0], cleans[1]);
}

// The aperture reference focused on the glass traces the street's defocus itself: the manifest
// says so, its clean image is the layered path's street within sampling noise, and wherever no ray
// met a drop (alpha 0) the rainy image is that clean image.
TEST(RenderFocus, TheApertureReferenceTracesTheStreetOutOfFocus) {
  TempDir tmp;
  const cv::Mat street = make_background(160, 96, 5);
  write_image(tmp / "street.png", street);
  auto render = [&](const std::string& name, const std::string& method) {
    return render_scene(tmp, name,
                        R"("glass_distance_cm": 10, "drop_count": 12, "footprint_radius_cm": [0.05, 0.15],
                           "tilt_deg": 80, "camera": {"f_number": 2, "focal_length_mm": 5, "focus_distance_cm": "glass",
                           "defocus": ")" + method + R"(", "aperture_samples": 256})",
                        {"--seed", "4"});
  };
  const auto reference = render("reference", "aperture"), layered = render("layered", "layered");
  ASSERT_EQ(reference.size(), 1u);
  const json& lens = reference[0].at("lens");
  EXPECT_EQ(lens.at("defocus"), "aperture");
  EXPECT_TRUE(lens.at("background_defocused").get<bool>());
  EXPECT_GT(lens.at("background_coc_px").get<double>(), 3.0);
  const std::string id = reference[0].at("id");
  const auto clean = read_image(tmp / "reference/clean" / (id + ".png"));
  const auto fast_clean = read_image(tmp / "layered/clean" / (id + ".png"));
  const auto rainy = read_image(tmp / "reference/rainy" / (id + ".png"));
  const auto alpha = read_image(tmp / "reference/alpha" / (id + ".png"));
  ASSERT_TRUE(clean && fast_clean && rainy && alpha);
  EXPECT_GT(cv::norm(clean->pixels, street, cv::NORM_L1) / street.total(), 1.0);
  EXPECT_LT(cv::norm(clean->pixels, fast_clean->pixels, cv::NORM_L1) / street.total() / 3, 1.0);
  cv::Mat outside_rainy, outside_clean;
  rainy->pixels.copyTo(outside_rainy, alpha->pixels == 0);
  clean->pixels.copyTo(outside_clean, alpha->pixels == 0);
  EXPECT_EQ(cv::norm(outside_rainy, outside_clean, cv::NORM_INF), 0);
  EXPECT_GT(cv::countNonZero(alpha->pixels), 0);
}

}  // namespace
}  // namespace clitest

// Scene files, presets, sampling and framing.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>

#include <unistd.h>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include "raindrop/common/error.h"
#include "raindrop/render/blur.h"
#include "raindrop/render/framing.h"
#include "raindrop/render/manifest.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

TEST(SceneFile, PaperPresetHasThePapersRanges) {
  const SceneConfig c = scene_preset("paper");
  EXPECT_EQ(c.glass_distance_cm.lo, 20);
  EXPECT_EQ(c.glass_distance_cm.hi, 40);
  EXPECT_EQ(c.background_distance_cm.lo, 800);
  EXPECT_EQ(c.background_distance_cm.hi, 1500);
  EXPECT_EQ(c.tilt_deg.lo, 30);
  EXPECT_EQ(c.contact_angle_deg.hi, 45);
  EXPECT_EQ(c.drop_count.lo, 50);
  EXPECT_EQ(c.drop_count.hi, 70);
  EXPECT_EQ(c.size_param, DropSizeParam::SphereRadius);
  EXPECT_EQ(c.drop_size_cm.lo, 0.8);
  EXPECT_EQ(c.drop_size_cm.hi, 1.5);
  EXPECT_DOUBLE_EQ(c.refractive_index, 1.333);
  EXPECT_EQ(c.effect_names(), (std::vector<std::string>{"refraction", "dark_band", "blur"}));
}

TEST(SceneFile, EveryPresetRoundTripsThroughJson) {
  for (const auto& name : scene_preset_names()) {
    const SceneConfig c = scene_preset(name);
    const std::string text = scene_to_json(c);
    EXPECT_EQ(scene_to_json(parse_scene_json(text, "round trip")), text) << name;
  }
}

TEST(SceneFile, EffectsNotNamedAreOff) {
  const SceneConfig c = parse_scene_json(R"({"effects": {"fresnel": {}}})", "t");
  EXPECT_FALSE(c.blur.enabled);
  EXPECT_TRUE(c.fresnel.enabled);
  EXPECT_FALSE(c.dispersion.enabled);
  EXPECT_FALSE(c.gravity.enabled);
}

TEST(SceneFile, MistakesAreReportedWithTheKey) {
  const std::pair<const char*, const char*> cases[] = {
      {R"({"tilt": [30, 45]})", "unknown key 'tilt'"},
      {R"({"effects": {"blurr": {}}})", "unknown key 'blurr'"},
      {R"({"effects": {"blur": {"diameter": 3}}})", "unknown key 'diameter'"},
      {R"({"tilt_deg": [45, 30]})", "'tilt_deg'"},
      {R"({"tilt_deg": [5, 30]})", "'tilt_deg'"},
      {R"({"drop_count": [1.5, 3]})", "whole numbers"},
      {R"({"sphere_radius_cm": 1, "footprint_radius_cm": 1})", "not both"},
      {R"({"quality": {"samples_per_pixel": 3}})", "square number"},
      {R"({"quality": {"geometry": "mesh-2-smooth"}})", "geometry"},
      {R"({"quality": {"border": "wrap"}})", "'border'"},
      {R"({"dark_band": "grey"})", "'dark_band'"},
      {R"({"tilt_deg": [30, 45],})", "not valid JSON"},
      {R"([1, 2])", "JSON object"},
      {R"({"effects": {"dispersion": "yes"}})", "effects.dispersion: must be a JSON object"},
      {R"({"effects": {"gravity": {"auto": "yes"}}})", "'auto' must be true or false"},
      {R"({"effects": {"fresnel": "auto"}})", "'fresnel' has no \"auto\""},
      {R"({"effects": {"blur": {"auto": true}}})", "unknown key 'auto'"},
      {R"({"quality": {"supersample": "some"}})", "'supersample'"},
      {R"({"coalesce": true})", "needs \"allow_overlap\": true"},
      // A key twice: JSON would keep the last and drop the first's settings without a word.
      {R"({"effects": {"blur": {}}, "drop_count": 5, "effects": {"fresnel": {}}})", "'effects' is given twice"},
      {R"({"effects": {"gravity": {"elongation": [1, 1.2], "elongation": [1, 1.5]}}})", "'elongation' is given twice"},
  };
  for (const auto& [text, needle] : cases) expect_scene_refused(text, needle);
  EXPECT_THROW(load_scene("no-such-preset-or-file"), Error);
  // The same key in different objects, or in objects side by side in a list, is no repeat.
  EXPECT_NO_THROW(parse_scene_json(R"({"effects": {"fresnel": {}}, "drops": [
      {"center_cm": [0, 0], "footprint_radius_cm": 0.2, "contact_angle_deg": 60},
      {"center_cm": [3, 0], "footprint_radius_cm": 0.2, "contact_angle_deg": 60}]})", "test"));
}

// "auto" leaves an effect to the scene's physics (effect_policy.h): as a string, or as a key
// beside the effect's other settings. It prints as the key, only where it is on, so scenes
// without it print as they always did; explicit settings mean what they meant.
TEST(SceneFile, EffectsMayBeAuto) {
  const SceneConfig c = parse_scene_json(
      R"({"effects": {"dispersion": "auto", "gravity": {"auto": true, "elongation": [1, 1.2]}},
          "quality": {"samples_per_pixel": 4, "supersample": "auto"}})", "t");
  EXPECT_TRUE(c.dispersion.enabled && c.dispersion.automatic);
  EXPECT_TRUE(c.gravity.enabled && c.gravity.automatic);
  EXPECT_EQ(c.gravity.elongation.hi, 1.2);
  EXPECT_EQ(c.supersample, Supersample::Auto);
  EXPECT_EQ(c.effect_names(), (std::vector<std::string>{"refraction", "dark_band", "dispersion-auto", "gravity-auto"}));
  const std::string text = scene_to_json(c);
  EXPECT_EQ(scene_to_json(parse_scene_json(text, "round trip")), text);
  EXPECT_NE(text.find("\"auto\": true"), std::string::npos);
  EXPECT_NE(text.find("\"supersample\": \"auto\""), std::string::npos);

  const SceneConfig off = parse_scene_json(R"({"effects": {"dispersion": {"auto": false}, "gravity": {}}})", "t");
  EXPECT_TRUE(off.dispersion.enabled);
  EXPECT_FALSE(off.dispersion.automatic);
  EXPECT_FALSE(off.gravity.automatic);
  EXPECT_EQ(off.supersample, Supersample::Edges);
  for (const auto& name : scene_preset_names()) EXPECT_EQ(scene_to_json(scene_preset(name)).find("auto"), std::string::npos) << name;
}

TEST(SceneFile, CommentsAreAllowed) {
  const SceneConfig c = parse_scene_json("// a comment\n{\"drop_count\": 3 /* fixed */}", "t");
  EXPECT_EQ(c.drop_count.lo, 3);
  EXPECT_EQ(c.drop_count.hi, 3);
}

TEST(SceneSampling, DeterministicPerSeedAndWithinTheRanges) {
  const SceneConfig c = scene_preset("full-physics");
  const Camera cam = camera(2048, 1024, 2262.52);
  Rng a(11), b(11), other(12);
  const SceneSample s1 = sample_scene(c, cam, a), s2 = sample_scene(c, cam, b), s3 = sample_scene(c, cam, other);
  ASSERT_EQ(s1.drops.size(), s2.drops.size());
  for (size_t i = 0; i < s1.drops.size(); ++i) {
    EXPECT_EQ(s1.drops[i].center, s2.drops[i].center);
    EXPECT_EQ(s1.drops[i].footprint_radius, s2.drops[i].footprint_radius);
  }
  EXPECT_NE(s1.drops[0].center, s3.drops[0].center);
  EXPECT_GE(s1.glass.distance, 20);
  EXPECT_LE(s1.glass.distance, 40);
  EXPECT_GE(s1.glass.tilt, 30 * kDegToRad);
  EXPECT_LE(s1.glass.tilt, 45 * kDegToRad);
  EXPECT_GE(s1.blur_diameter_px, 7);
  EXPECT_LE(s1.blur_diameter_px, 20);
  EXPECT_GE(static_cast<int>(s1.drops.size()), 50);
  EXPECT_LE(static_cast<int>(s1.drops.size()), 70);
  for (const auto& d : s1.drops) {
    EXPECT_GE(d.sphere_radius(), 0.8 - 1e-12);
    EXPECT_LE(d.sphere_radius(), 1.5 + 1e-12);
    EXPECT_GE(d.contact_angle, 30 * kDegToRad);
    EXPECT_LE(d.contact_angle, 45 * kDegToRad);
    EXPECT_GE(d.elongation, 1.0);
    EXPECT_LE(d.flattening, 1.0);
  }
}

TEST(SceneSampling, FootprintsDoNotOverlapAndDropsAreInView) {
  const SceneConfig c = scene_preset("paper");
  const Camera cam = camera(1024, 512, 1131);
  for (std::uint64_t seed = 0; seed < 20; ++seed) {
    Rng rng(seed);
    const SceneSample s = sample_scene(c, cam, rng);
    for (size_t i = 0; i < s.drops.size(); ++i) {
      const auto& a = s.drops[i];
      // Centre projects into the frame or within the margin.
      const glm::dvec2 p = cam.project(s.glass.point(a.center));
      EXPECT_GT(p.x, -cam.width * 0.5);
      EXPECT_LT(p.x, cam.width * 1.5);
      for (size_t j = i + 1; j < s.drops.size(); ++j) {
        const auto& b = s.drops[j];
        EXPECT_GE(glm::length(a.center - b.center), a.footprint_radius + b.footprint_radius) << seed;
      }
    }
  }
}

TEST(SceneSampling, DropCentresAreUniformPerAreaOfGlass) {
  // Upright glass: equal glass areas project to equal image areas, so the centres must also
  // be uniform in the image. Compare drop counts in the left/right and top/bottom halves.
  SceneConfig c = scene_preset("paper");
  c.tilt_deg = {90, 90};
  c.drop_size_cm = {0.01, 0.01};  // tiny: no rejections from overlap
  c.drop_count = {200, 200};
  const Camera cam = camera(400, 200, 400);
  int top = 0, left = 0, total = 0;
  for (std::uint64_t seed = 0; seed < 50; ++seed) {
    Rng rng(seed);
    for (const auto& d : sample_scene(c, cam, rng).drops) {
      ++total;
      top += d.center.y < 0;
      left += d.center.x < 0;
    }
  }
  EXPECT_NEAR(static_cast<double>(top) / total, 0.5, 0.02);
  EXPECT_NEAR(static_cast<double>(left) / total, 0.5, 0.02);
}

TEST(Framing, CameraFollowsCropAndResize) {
  cv::Mat img(1024, 2048, CV_8UC3, cv::Scalar(1, 2, 3));
  Camera cs;
  cs.fx = 2262.52;
  cs.fy = 2265.30;
  cs.cx = 1096.98;
  cs.cy = 513.137;
  const Frame f = make_frame(img, cs, cv::Size(512, 256));
  EXPECT_EQ(f.camera_origin, "cityscapes-json");
  EXPECT_NEAR(f.camera.fx, 2262.52 / 4, 1e-9);
  EXPECT_NEAR(f.camera.cx, (1096.98 + 0.5) / 4 - 0.5, 1e-9);
  // A point projects consistently before and after (pixel-centre rule).
  const glm::dvec3 p(1.3, -0.4, 7.0);
  Camera full = cs;
  full.width = 2048;
  full.height = 1024;
  EXPECT_NEAR(f.camera.project(p).x, (full.project(p).x + 0.5) / 4 - 0.5, 1e-9);
  // 4:3 input cropped to 2:1: the crop offset moves the principal point.
  const cv::Mat camvid(360, 480, CV_8UC3, cv::Scalar(0));
  const Frame g = make_frame(camvid, std::nullopt, cv::Size(480, 240));
  EXPECT_EQ(g.camera_origin, "default");
  EXPECT_EQ(g.clean.size(), cv::Size(480, 240));
  EXPECT_NEAR(g.camera.cy, 0.5 * (360 - 1) - 60, 1e-9);
  // An aspect ratio that leaves no window a pixel across is an error naming both sizes (it was
  // OpenCV's assertion from an empty resize), either way round; one a pixel across is a frame.
  for (const cv::Size size : {cv::Size(16384, 16), cv::Size(16, 16384)}) {
    try {
      make_frame(camvid, std::nullopt, size);
      ADD_FAILURE() << size;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("480x360 frame holds no window"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(make_frame(camvid, std::nullopt, cv::Size(960, 1)).clean.size(), cv::Size(960, 1));
}

TEST(Rendering, RainyEqualsCleanOutsideTheMaskAndThreadsDoNotMatter) {
  const SceneConfig c = scene_preset("full-physics");
  const Camera cam = camera(320, 160, 353);
  cv::Mat clean(cam.height, cam.width, CV_8UC3);
  cv::randu(clean, 0, 256);
  Rng rng(5);
  const SceneSample scene = sample_scene(c, cam, rng);
  RenderedFrame one, two;
  tbb::task_arena(1).execute([&] { one = render_frame(clean, cam, c, scene); });
  tbb::task_arena(2).execute([&] { two = render_frame(clean, cam, c, scene); });
  EXPECT_EQ(cv::norm(one.rainy, two.rainy, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(one.mask, two.mask, cv::NORM_INF), 0);
  cv::Mat outside;
  cv::bitwise_not(one.mask, outside);
  EXPECT_EQ(cv::norm(one.rainy, clean, cv::NORM_INF, outside), 0);
  EXPECT_GT(cv::norm(one.rainy, clean, cv::NORM_INF, one.mask), 0);
  // Binary mask.
  cv::Mat not_binary = (one.mask != 0) & (one.mask != 255);
  EXPECT_EQ(cv::countNonZero(not_binary), 0);
  EXPECT_GT(cv::countNonZero(one.mask), 0);
}

// The renderer blurs the drops with the scene's diameter (at the output resolution, as drawn
// from diameter_px_2048): its rainy pixels are the traced colours blurred by blur_drops at
// exactly scene.blur_diameter_px (whose kernel test_blur.cpp pins), rounded to 8 bits.
TEST(Rendering, DropsAreBlurredWithTheScenesDiameter) {
  SceneConfig c = scene_preset("paper");
  ASSERT_TRUE(c.blur.enabled);
  const Camera cam = camera(256, 128, 283);
  Rng rng(8);
  SceneSample scene = sample_scene(c, cam, rng);
  EXPECT_GE(scene.blur_diameter_px, 7 * 256 / 2048.0);  // the paper's 7-20 px at 2048
  EXPECT_LE(scene.blur_diameter_px, 20 * 256 / 2048.0);
  scene.blur_diameter_px = 6.3;  // wide enough that 10% more or less shows in 8 bits
  cv::Mat clean(cam.height, cam.width, CV_8UC3);
  cv::randu(clean, 0, 256);
  const RenderedFrame f = render_frame(clean, cam, c, scene);
  std::vector<Drop> drops;
  for (const auto& d : scene.drops) drops.emplace_back(d, scene.glass);
  const DropAccel accel(drops, c.geometry);
  auto blurred_at = [&](double d) {
    TraceResult t = trace_drops(clean, cam, c, scene, accel);
    blur_drops(clean, t.label, t.color, d, c.blur.method);
    cv::Mat out = clean.clone();
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x)
        if (t.label.at<int>(y, x) >= 0)
          for (int k = 0; k < 3; ++k)
            out.at<cv::Vec3b>(y, x)[k] = static_cast<std::uint8_t>(
                std::floor(std::clamp(t.color.at<cv::Vec3f>(y, x)[k], 0.0f, 1.0f) * 255.0f + 0.5f));
    return out;
  };
  ASSERT_GT(cv::countNonZero(f.mask), 1000);
  EXPECT_LE(cv::norm(f.rainy, blurred_at(6.3), cv::NORM_INF), 1);
  for (double other : {5.7, 6.9}) {
    cv::Mat diff;
    cv::absdiff(f.rainy, blurred_at(other), diff);
    EXPECT_GT(cv::countNonZero(diff.reshape(1) > 1), 100) << "diameter " << other << " gives the same image";
  }
}

TEST(Manifest, ATruncatedLastLineIsIgnoredAndABadMiddleLineIsAnError) {
  const auto dir = std::filesystem::temp_directory_path() / ("raindrop_manifest_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto file = dir / "manifest.jsonl";
  const std::string good = R"({"id":"a","rainy":"rainy/a.png","clean":"clean/a.png","mask":"mask/a.png","job":"j"})";
  {
    std::ofstream(file) << good << "\n" << R"({"id":"b","rainy":"rai)";
  }
  const auto entries = read_manifest(file);
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries.at("a").job, "j");
  {
    std::ofstream(file) << R"({"id":"b","rai)" << "\n" << good << "\n";
  }
  EXPECT_THROW(read_manifest(file), Error);
  // A run resumed after one cut short appends after the cut record, never onto it (that made it
  // a bad middle line: the folder could not be read again).
  {
    std::ofstream(file, std::ios::trunc) << good << "\n" << R"({"id":"b","rai)";
  }
  {
    ManifestWriter w(file);
    const std::string c = R"({"id":"c","rainy":"rainy/c.png","clean":"clean/c.png","mask":"mask/c.png","job":"j"})";
    w.append("c", c);
  }
  const auto resumed = read_manifest(file);
  ASSERT_EQ(resumed.size(), 2u);
  EXPECT_EQ(resumed.count("a") + resumed.count("c"), 2u);
  std::filesystem::remove_all(dir);
}

// ---------------------------------------------------------------------------------------
// Drops the scene file places itself ("drops").

TEST(SceneFile, PlacedDropsParseAndRoundTrip) {
  const SceneConfig c = parse_scene_json(R"({
    "drop_count": 0,
    "drops": [
      {"center_px": [100.5, 60], "footprint_radius_cm": 0.4, "contact_angle_deg": 35},
      {"center_cm": [-2, 1.5], "sphere_radius_cm": 1.0, "contact_angle_deg": 60}
    ]})", "test");
  ASSERT_EQ(c.drops.size(), 2u);
  EXPECT_TRUE(c.drops[0].at_pixel);
  EXPECT_EQ(c.drops[0].x, 100.5);
  EXPECT_EQ(c.drops[0].y, 60);
  EXPECT_EQ(c.drops[0].size_param, DropSizeParam::FootprintRadius);
  EXPECT_EQ(c.drops[0].contact_angle_deg, 35);
  EXPECT_FALSE(c.drops[1].at_pixel);
  EXPECT_EQ(c.drops[1].size_param, DropSizeParam::SphereRadius);
  EXPECT_EQ(c.drops[1].size_cm, 1.0);
  const SceneConfig again = parse_scene_json(scene_to_json(c), "printed");  // --print-scene keeps them
  ASSERT_EQ(again.drops.size(), 2u);
  EXPECT_EQ(again.drops[1].x, -2);
  EXPECT_EQ(again.drops[1].contact_angle_deg, 60);
}

TEST(SceneFile, PlacedDropsRefuseWhatIsUnclear) {
  const std::string ok = R"("footprint_radius_cm": 0.4, "contact_angle_deg": 35)";
  for (const std::string& bad : std::vector<std::string>{
           R"({"drops": {"center_px": [1, 2]}})",                                                   // not a list
        R"({"drops": [{)" + ok + "}]}",                                                          // no centre
        R"({"drops": [{"center_px": [1, 2], "center_cm": [0, 0], )" + ok + "}]}",                // two centres
        R"({"drops": [{"center_px": [1], )" + ok + "}]}",                                        // not [x, y]
        R"({"drops": [{"center_px": [1, 2], "contact_angle_deg": 35}]})",                        // no size
        R"({"drops": [{"center_px": [1, 2], "footprint_radius_cm": 0.4}]})",                     // no angle
        R"({"drops": [{"center_px": [1, 2], "footprint_radius_cm": 0.4, "contact_angle_deg": 95}]})",
        R"({"drops": [{"center_px": [1, 2], "colour": 1, )" + ok + "}]}"}) {                     // unknown key
    try {
      parse_scene_json(bad, "bad.json");
      ADD_FAILURE() << "accepted: " << bad;
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("bad.json"), std::string::npos) << msg;
      EXPECT_NE(msg.find("drops"), std::string::npos) << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    }
  }
}

TEST(Scene, APlacedDropSitsWhereTheSceneSaysAndRandomOnesKeepClear) {
  SceneConfig c = scene_preset("paper");
  c.drop_count = {60, 60};
  PlacedDrop at_px;
  at_px.x = 301.25;
  at_px.y = 97.5;
  at_px.size_cm = 1.2;
  at_px.contact_angle_deg = 33;
  PlacedDrop on_glass = at_px;
  on_glass.at_pixel = false;
  on_glass.x = -3.5;
  on_glass.y = 2.25;
  on_glass.size_param = DropSizeParam::SphereRadius;
  c.drops = {at_px, on_glass};
  const Camera cam = camera(512, 256, 600);
  for (int seed = 0; seed < 5; ++seed) {
    Rng rng(seed);
    const SceneSample s = sample_scene(c, cam, rng);
    ASSERT_GE(s.drops.size(), 2u);
    EXPECT_EQ(s.drops_requested, 62);
    // The pixel the camera sees the first drop's centre at is the one asked for.
    const glm::dvec2 seen = cam.project(s.glass.point(s.drops[0].center));
    EXPECT_NEAR(seen.x, 301.25, 1e-9);
    EXPECT_NEAR(seen.y, 97.5, 1e-9);
    EXPECT_NEAR(s.drops[0].footprint_radius, 1.2, 1e-12);
    EXPECT_NEAR(s.drops[0].contact_angle, 33 * kDegToRad, 1e-12);
    EXPECT_EQ(s.drops[1].center, glm::dvec2(-3.5, 2.25));
    EXPECT_NEAR(s.drops[1].footprint_radius, 1.2 * std::sin(33 * kDegToRad), 1e-12);  // a = r sin(tau)
    for (size_t i = 2; i < s.drops.size(); ++i) {
      for (size_t k = 0; k < 2; ++k) {
        const double d = glm::length(s.drops[i].center - s.drops[k].center);
        EXPECT_GE(d, s.drops[i].footprint_radius + s.drops[k].footprint_radius + c.min_gap_cm - 1e-12)
            << "random drop " << i << " overlaps placed drop " << k << " (seed " << seed << ")";
      }
    }
  }
}

TEST(Scene, APlacedDropTheCameraCannotSeeOnTheGlassIsAnError) {
  SceneConfig c = scene_preset("paper");
  c.drop_count = {0, 0};
  c.tilt_deg = {15, 15};
  PlacedDrop p;
  p.y = 1e5;  // far below the frame: that ray runs away from the glass, which leans over the camera
  c.drops = {p};
  Rng rng(1);
  EXPECT_THROW(sample_scene(c, camera(512, 256, 600), rng), Error);
}

// A thin lens focused off the background (camera.focus_distance_cm): the street defocused by
// its own circle of confusion, drops at the plane of focus sharp, against closed-form thin-lens
// optics; focus on the background unchanged; the scene file's forms and refusals.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include <cstdio>
#include <vector>

#include "raindrop/common/demo.h"
#include "raindrop/common/rng.h"
#include "raindrop/render/background_defocus.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/scene_config.h"
#include "raindrop/render/srgb.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

constexpr double kT = 1000;  // background plane, cm

SceneConfig lens_config(SceneConfig::Focus focus) {
  SceneConfig c = lens_scene();
  c.lens.focus = focus;
  return c;
}

SceneSample sample(double glass_cm, double focus_cm, double f_number, double focal_mm) {
  SceneSample s = lens_sample(glass_cm, f_number, focal_mm, kT);
  s.focus_distance_cm = focus_cm;
  return s;
}

// A dark frame with one white pixel at its centre: a point of the street.
cv::Mat point_frame(const Camera& cam) {
  cv::Mat m(cam.height, cam.width, CV_8UC3, cv::Scalar::all(0));
  m.at<cv::Vec3b>((cam.height - 1) / 2, (cam.width - 1) / 2) = cv::Vec3b(255, 255, 255);
  return m;
}

int lit_run(const cv::Mat& rgb, int y) {
  int n = 0;
  for (int x = 0; x < rgb.cols; ++x) n += rgb.at<cv::Vec3b>(y, x)[0] > 0;
  return n;
}

}  // namespace

// A camera focused at F sees a point of the background plane T as its circle of confusion,
// aperture * fx * |1/T - 1/F| pixels across (computed here, not by the program). The clean image
// is the camera's view: the point spread into that disk, in both the clean and the rainy image.
// Convolved exactly, the lit run is the circle; on the renderer's grid (circles of 48 px and
// more) the disk's edge is smoothed over a grid step, so there the run at half the disk's
// brightness is the circle, within that step.
TEST(Focus, APointOfTheStreetSpreadsOverTheThinLensCircle) {
  const Camera cam = camera(161, 161, 300);
  for (double focus : {8.0, 15.0, 25.0}) {
    const double f_number = 1, focal_mm = 5;
    const double coc = focal_mm / 10 / f_number * cam.fx * std::abs(1 / kT - 1 / focus);
    ASSERT_GT(coc, 5);
    const cv::Mat exact = defocus_background(point_frame(cam), coc, BorderMode::Mirror, {}, BackgroundGrid::Exact);
    const int row = (cam.height - 1) / 2;
    EXPECT_NEAR(lit_run(exact, row), coc, 2.0) << "focus " << focus << " cm";
    EXPECT_NEAR(lit_run(exact.t(), row), coc, 2.0) << "focus " << focus << " cm, column";

    SceneSample s = sample(focus, focus, f_number, focal_mm);  // no drops
    const RenderedFrame f = render_frame(point_frame(cam), cam, lens_config(SceneConfig::Focus::Distance), s);
    ASSERT_FALSE(f.clean.empty()) << focus;
    EXPECT_TRUE(equal_bits(f.rainy, f.clean));
    const int centre = f.clean.at<cv::Vec3b>(row, row)[0];
    int half = 0;
    for (int x = 0; x < f.clean.cols; ++x) half += 2 * f.clean.at<cv::Vec3b>(row, x)[0] >= centre;
    EXPECT_NEAR(half, coc, 2.0 + background_grid_step(coc)) << "focus " << focus << " cm, grid";
    // The light is spread, not lost: the disk's linear-light sum is the point's.
    for (const cv::Mat& m : {exact, f.clean}) {
      double sum = 0;
      for (int y = 0; y < m.rows; ++y)
        for (int x = 0; x < m.cols; ++x) sum += srgb_to_linear(m.at<cv::Vec3b>(y, x)[1] / 255.0);
      EXPECT_NEAR(sum, 1.0, 0.05) << focus;
    }
  }
}

// The grid against the exact convolution on street frames (the demo street and Cityscapes-like
// noise of every scale): what the grid smooths is within half a level RMS and 4 levels at most.
TEST(Focus, TheGridStaysWithinHalfALevelOfTheExactBlur) {
  // Sizes that are not multiples of the grid steps: the borders are where a grid goes wrong.
  const Camera cam = camera(517, 263, 500);
  for (const cv::Mat& frame : {demo_street(cam.width, cam.height), random_frame(cam)}) {
    for (double coc : {8.0, 34.0, 60.0, 72.0, 120.0, 168.0}) {
      const cv::Mat grid = defocus_background(frame, coc, BorderMode::Mirror);
      const cv::Mat exact = defocus_background(frame, coc, BorderMode::Mirror, {}, BackgroundGrid::Exact);
      cv::Mat diff;
      cv::absdiff(grid, exact, diff);
      const double rmse = std::sqrt(cv::mean(diff.mul(diff))[0] / 1.0);
      double worst = 0;
      cv::minMaxLoc(diff.reshape(1), nullptr, &worst);
      std::printf("grid step %d, circle %.1f px: RMSE %.3f, max %.0f levels\n", background_grid_step(coc), coc, rmse, worst);
      EXPECT_LE(rmse, 0.5) << coc;
      EXPECT_LE(worst, 4) << coc;
    }
  }
}

// Focus on the background (the default, or a distance equal to it) leaves the street as it is:
// no clean image of its own, the rainy image byte for byte the background-focused one.
TEST(Focus, FocusOnTheBackgroundIsTheDefaultRender) {
  const Camera cam = camera(160, 96, 150);
  const cv::Mat clean = random_frame(cam);
  SceneSample s = sample(5, 0, 2, 5);
  s.drops = {cap(0, 0, 0.3, 40), cap(0.8, 0.2, 0.15, 60)};
  const RenderedFrame by_default = render_frame(clean, cam, lens_config(SceneConfig::Focus::Background), s);
  ASSERT_TRUE(by_default.defocused);
  EXPECT_TRUE(by_default.clean.empty());
  s.focus_distance_cm = kT;
  const RenderedFrame at_t = render_frame(clean, cam, lens_config(SceneConfig::Focus::Distance), s);
  EXPECT_TRUE(at_t.clean.empty());
  EXPECT_TRUE(equal_bits(at_t.rainy, by_default.rainy));
  EXPECT_TRUE(equal_bits(at_t.alpha, by_default.alpha));
}

// Focused on the glass, a drop there is sharp (its circle under half a pixel: the pinhole's
// outline, 2 fx a / z wide) while the street behind it is spread; outside the drop's coverage the
// rainy image is the defocused street. The drop's circle is 0, but the aperture's parallax
// shows inside it (defocus.h): it is traced through the aperture, not spread as a layer.
TEST(Focus, ADropOnTheFocusedGlassIsSharpAndTheStreetIsNot) {
  const Camera cam = camera(201, 121, 250);
  const double z = 10, a = 0.3;
  SceneSample s = sample(z, z, 2, 5);
  s.drops = {cap(0, 0, a, 45)};
  const cv::Mat input = random_frame(cam);
  const RenderedFrame f = render_frame(input, cam, lens_config(SceneConfig::Focus::Glass), s);
  EXPECT_TRUE(f.lens_sampled);
  ASSERT_EQ(f.coc_px.size(), 1u);
  EXPECT_EQ(f.coc_px[0], 0.0);  // its layer is not spread
  ASSERT_FALSE(f.clean.empty());
  EXPECT_FALSE(equal_bits(f.clean, input));
  const int row = (cam.height - 1) / 2;
  int run = 0;
  for (int x = 0; x < cam.width; ++x) run += f.mask.at<std::uint8_t>(row, x) != 0;
  EXPECT_NEAR(run, 2 * cam.fx * a / z, 1.5);
  cv::Mat outside_rainy, outside_clean;
  f.rainy.copyTo(outside_rainy, f.alpha == 0);
  f.clean.copyTo(outside_clean, f.alpha == 0);
  EXPECT_TRUE(equal_bits(outside_rainy, outside_clean));
  // The same drop a little off the plane of focus is defocused by its own circle.
  s.glass = upright_glass(6);
  const RenderedFrame off = render_frame(input, cam, lens_config(SceneConfig::Focus::Distance), s);
  EXPECT_TRUE(off.defocused);
  ASSERT_EQ(off.coc_px.size(), 1u);
  EXPECT_NEAR(off.coc_px[0], 5.0 / 10 / 2 * cam.fx * (1.0 / 6 - 1.0 / z), 1e-9);  // aperture 5 mm / 2
}

// The aperture reference with focus off the background traces the street's defocus itself: a
// point of the street spreads, in linear light, over a disk whose diameter is the thin-lens circle
// computed here (a uniform disk of diameter D has mean squared radius D^2 / 8; square pixels add
// 1/6 px^2, under the tolerance), nothing reaches past it, and its light is conserved; with no
// drop the rainy image is the clean one.
TEST(Focus, TheReferenceSpreadsAPointOfTheStreetOverTheThinLensCircle) {
  const Camera cam = camera(81, 81, 300);
  for (double focus : {8.0, 15.0, 25.0}) {
    const double coc = 5.0 / 10 / 1 * cam.fx * std::abs(1 / kT - 1 / focus);
    SceneConfig c = lens_config(SceneConfig::Focus::Distance);
    c.lens.method = DefocusMethod::Aperture;
    // Each ray sees one pixel of the street (square pixels of constant light), so the white pixel's
    // light reaches a pixel of the disk in whole rays: 1024 rays keep the sum within a few percent.
    c.lens.aperture_samples = 1024;
    const RenderedFrame f = render_frame(point_frame(cam), cam, c, sample(focus, focus, 1, 5));
    ASSERT_FALSE(f.clean.empty()) << focus;
    EXPECT_TRUE(equal_bits(f.rainy, f.clean));
    const double centre = 0.5 * (cam.width - 1);
    double sum = 0, r2 = 0, beyond = 0;
    for (int y = 0; y < f.clean.rows; ++y) {
      for (int x = 0; x < f.clean.cols; ++x) {
        const double light = srgb_to_linear(f.clean.at<cv::Vec3b>(y, x)[1] / 255.0);
        const double r = std::hypot(x - centre, y - centre);
        sum += light;
        r2 += light * r * r;
        if (r > 0.5 * coc + 1.5) beyond += light;
      }
    }
    const double diameter = std::sqrt(8 * r2 / sum);
    std::printf("focus %.0f cm: circle %.2f px, traced %.2f px, light %.3f\n", focus, coc, diameter, sum);
    EXPECT_NEAR(diameter, coc, 0.05 * coc + 0.5) << focus;
    EXPECT_NEAR(sum, 1.0, 0.08) << focus;
    EXPECT_EQ(beyond, 0.0) << focus;
  }
}

// The reference's street against the fast path's convolution (defocus_background, exact): the
// same disk, one sampled by 256 rays per pixel, the other summed over every pixel.
TEST(Focus, TheReferencesStreetIsTheFastPathsWithinSamplingNoise) {
  const Camera cam = camera(160, 96, 150);
  const cv::Mat street = demo_street(cam.width, cam.height);
  for (double focus : {6.0, 12.0}) {
    SceneConfig c = lens_config(SceneConfig::Focus::Distance);
    c.lens.method = DefocusMethod::Aperture;
    c.lens.aperture_samples = 256;
    const SceneSample s = sample(focus, focus, 1, 5);
    const double coc = s.background_coc_px(cam.fx);
    const RenderedFrame f = render_frame(street, cam, c, s);
    ASSERT_FALSE(f.clean.empty());
    const cv::Mat fast = defocus_background(street, coc, BorderMode::Mirror, {}, BackgroundGrid::Exact);
    cv::Mat diff;
    cv::absdiff(f.clean, fast, diff);
    diff.convertTo(diff, CV_64F);
    const cv::Mat sq = diff.mul(diff);
    const double rmse = std::sqrt(cv::mean(sq.reshape(1))[0]);
    double worst = 0;
    cv::minMaxLoc(diff.reshape(1), nullptr, &worst);
    std::printf("circle %.1f px: reference against the fast path's street RMSE %.2f, max %.0f levels\n", coc, rmse, worst);
    EXPECT_LE(rmse, 1.0) << coc;
    EXPECT_LE(worst, 8) << coc;
  }
}

// Focused on the glass, the reference keeps a drop there sharp (its coverage a step, as wide as
// the pinhole's outline) over its own traced street, which the rainy image is wherever no ray
// met the drop.
TEST(Focus, TheReferenceKeepsADropOnTheFocusedGlassSharp) {
  const Camera cam = camera(121, 81, 250);
  const double z = 10, a = 0.3;
  SceneSample s = sample(z, z, 2, 5);
  s.drops = {cap(0, 0, a, 45)};
  SceneConfig c = lens_config(SceneConfig::Focus::Glass);
  c.lens.method = DefocusMethod::Aperture;
  c.lens.aperture_samples = 64;
  const RenderedFrame f = render_frame(random_frame(cam), cam, c, s);
  ASSERT_TRUE(f.defocused);
  ASSERT_FALSE(f.clean.empty());
  const int row = (cam.height - 1) / 2;
  int run = 0, partial = 0;
  for (int x = 0; x < cam.width; ++x) {
    const float alpha = f.alpha.at<float>(row, x);
    run += alpha >= 0.5f;
    partial += alpha > 0.01f && alpha < 0.99f;
  }
  EXPECT_NEAR(run, 2 * cam.fx * a / z, 1.5);
  EXPECT_LE(partial, 4);  // the outline's two edge pixels on each side at most
  cv::Mat outside_rainy, outside_clean;
  f.rainy.copyTo(outside_rainy, f.alpha == 0);
  f.clean.copyTo(outside_clean, f.alpha == 0);
  EXPECT_TRUE(equal_bits(outside_rainy, outside_clean));
}

// The background blur keeps a uniform frame uniform (weights sum to one, borders continued) and
// leaves a frame alone under half a pixel.
TEST(Focus, BackgroundBlurKeepsFlatFramesAndSkipsTinyCircles) {
  const cv::Mat flat(40, 60, CV_8UC3, cv::Scalar(17, 130, 240));
  for (double coc : {1.0, 7.5, 33.0, 500.0}) EXPECT_TRUE(equal_bits(defocus_background(flat, coc, BorderMode::Mirror), flat)) << coc;
  const Camera cam = camera(60, 40, 50);
  const cv::Mat frame = random_frame(cam);
  EXPECT_TRUE(equal_bits(defocus_background(frame, 0.4, BorderMode::Clamp), frame));
}

TEST(Focus, SceneFileForms) {
  const std::string head = R"({"name": "t", "camera": {"f_number": 2, "focus_distance_cm": )";
  EXPECT_EQ(parse_scene_json(head + R"("glass"}})", "t").lens.focus, SceneConfig::Focus::Glass);
  EXPECT_EQ(parse_scene_json(head + R"("background"}})", "t").lens.focus, SceneConfig::Focus::Background);
  const SceneConfig ranged = parse_scene_json(head + "[20, 40]}}", "t");
  EXPECT_EQ(ranged.lens.focus, SceneConfig::Focus::Distance);
  // Printed and parsed back: the same config.
  for (const char* form : {R"("glass")", "[20, 40]", R"("background")"}) {
    const SceneConfig c = parse_scene_json(head + form + "}}", "t");
    EXPECT_EQ(scene_to_json(parse_scene_json(scene_to_json(c), "again")), scene_to_json(c)) << form;
  }
  // Focused on the background, a scene prints (and fingerprints its jobs: a resumed job compares
  // them) as before the key existed.
  for (const std::string& name : scene_preset_names()) {
    if (scene_preset(name).lens.focus == SceneConfig::Focus::Background) {
      EXPECT_EQ(scene_to_json(scene_preset(name)).find("focus_distance_cm"), std::string::npos) << name;
    }
  }
  expect_scene_refused(head + R"("street"}})", "focus_distance_cm");
  expect_scene_refused(head + "[0.1, 5]}}", "focus_distance_cm");
  // The aperture reference traces any focus.
  EXPECT_EQ(parse_scene_json(head + R"("glass", "defocus": "aperture"}})", "t").lens.method, DefocusMethod::Aperture);
  // glass-droplets is focused on its glass.
  EXPECT_EQ(scene_preset("glass-droplets").lens.focus, SceneConfig::Focus::Glass);
  // Drops in focus: through the aperture unless the scene asks for the lens' centre alone.
  EXPECT_TRUE(parse_scene_json(head + R"("glass"}})", "t").lens.trace_in_focus);
  const SceneConfig centre = parse_scene_json(head + R"("glass", "drops_in_focus": "centre"}})", "t");
  EXPECT_FALSE(centre.lens.trace_in_focus);
  EXPECT_EQ(scene_to_json(parse_scene_json(scene_to_json(centre), "again")), scene_to_json(centre));
  expect_scene_refused(head + R"("glass", "drops_in_focus": "pinhole"}})", "drops_in_focus");
}

// The plane of focus is drawn after everything else: the same seed places the same drops with
// and without it, and a drawn distance lies in its range; on the glass it is the glass's N.
TEST(Focus, FocusIsDrawnLast) {
  const Camera cam = camera(256, 128, 280);
  SceneConfig base = scene_preset("windshield-sharp");
  SceneConfig ranged = base, glass = base;
  ranged.lens.focus = SceneConfig::Focus::Distance;
  ranged.lens.focus_distance_cm = {20, 40};
  glass.lens.focus = SceneConfig::Focus::Glass;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    Rng r0(seed), r1(seed), r2(seed);
    const SceneSample a = sample_scene(base, cam, r0), b = sample_scene(ranged, cam, r1), c = sample_scene(glass, cam, r2);
    ASSERT_EQ(a.drops.size(), b.drops.size());
    for (size_t i = 0; i < a.drops.size(); ++i) EXPECT_EQ(a.drops[i].center, b.drops[i].center);
    EXPECT_EQ(a.f_number, b.f_number);
    EXPECT_EQ(a.focus_distance_cm, 0.0);
    EXPECT_GE(b.focus_distance_cm, 20);
    EXPECT_LE(b.focus_distance_cm, 40);
    EXPECT_EQ(c.focus_distance_cm, c.glass.distance);
  }
}

// A clipped lamp in a street out of focus blooms through the highlights' lift as it does behind
// a defocused drop (highlights.h), and the frame says the lift ran, which the manifest and the
// veil read, also where no drop is spread (focus on the glass keeps them sharp).
TEST(Focus, AClippedLampInTheDefocusedStreetIsLifted) {
  const Camera cam = camera(121, 121, 300);
  cv::Mat lamp(cam.height, cam.width, CV_8UC3, cv::Scalar::all(20));
  lamp(cv::Rect(57, 57, 7, 7)).setTo(cv::Scalar::all(255));
  SceneConfig with = lens_config(SceneConfig::Focus::Glass), without = with;
  with.highlights.enabled = true;
  SceneSample s = sample(10, 10, 1.4, 5);
  s.highlights.threshold = static_cast<float>(srgb_to_linear(with.highlights.threshold));
  s.highlights.gain = 8;
  const RenderedFrame lifted = render_frame(lamp, cam, with, s);
  const RenderedFrame plain = render_frame(lamp, cam, without, s);
  ASSERT_FALSE(lifted.clean.empty());
  EXPECT_TRUE(lifted.highlights_lifted);
  EXPECT_FALSE(plain.highlights_lifted);
  // The lamp's light, 8 times what is stored, spreads brighter over its circle (10.6 px).
  const cv::Rect around(50, 50, 21, 21);
  std::printf("around the lamp: %.1f lifted, %.1f plain\n", cv::mean(lifted.clean(around))[0], cv::mean(plain.clean(around))[0]);
  EXPECT_GT(cv::mean(lifted.clean(around))[0], cv::mean(plain.clean(around))[0] + 20);
  // Dimmed below the threshold, nothing is lifted and the frames are the same.
  cv::Mat dim = lamp * (200.0 / 255.0);
  const RenderedFrame dim_lifted = render_frame(dim, cam, with, s);
  EXPECT_FALSE(dim_lifted.highlights_lifted);
  EXPECT_TRUE(equal_bits(dim_lifted.clean, render_frame(dim, cam, without, s).clean));
}

// glass-plate (scenes/glass-plate.json) draws what its comment and the README promise, at the
// size of the photographs it imitates (720x480, the default camera's 48-degree field): over
// 100 drops placed (120-300 asked; the gap between drops leaves some out on a crowded plate),
// each sample's drops blurred by a median circle of 5 to 40 px, 10 to 20 px for the median
// sample (soft, yet still drops), and between a quarter and 95% of the frame covered. 16
// samples.
TEST(Focus, GlassPlateDrawsADenseCarpetOfSoftDrops) {
  const Camera cam = camera(720, 480, 795.4);
  const SceneConfig c = scene_preset("glass-plate");
  const cv::Mat street = demo_street(cam.width, cam.height);
  std::vector<double> circles;
  double least_cover = 1, most_cover = 0;
  for (std::uint64_t seed = 1; seed <= 16; ++seed) {
    Rng rng(seed);
    const SceneSample s = sample_scene(c, cam, rng);
    EXPECT_GE(s.drops.size(), 100u) << "seed " << seed;
    std::vector<double> own;
    for (const DropShape& d : s.drops) own.push_back(s.drop_coc_px(d, cam.fx));
    std::sort(own.begin(), own.end());
    circles.push_back(own[own.size() / 2]);  // the sample's median circle
    const RenderedFrame f = render_frame(street, cam, c, s);
    least_cover = std::min(least_cover, f.coverage());
    most_cover = std::max(most_cover, f.coverage());
  }
  std::sort(circles.begin(), circles.end());
  const double p05 = circles[0], p50 = circles[8], p95 = circles[15];
  std::printf("samples' median circles %.1f (least), %.1f (median), %.1f (most) px; coverage %.2f-%.2f\n", p05, p50,
              p95, least_cover, most_cover);
  EXPECT_GE(p50, 10.0);
  EXPECT_LE(p50, 20.0);
  EXPECT_GE(p05, 5.0);
  EXPECT_LE(p95, 40.0);
  EXPECT_GE(least_cover, 0.25);
  EXPECT_LE(most_cover, 0.95);
}

// Effects chosen by the scene's physics ("auto", effect_policy.h): the criteria against
// closed-form cases and traced rays, and what skipping costs against the full simulation.
#include <algorithm>
#include <cmath>
#include <functional>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "raindrop/common/rng.h"
#include "raindrop/common/demo.h"
#include "raindrop/render/effect_policy.h"
#include "raindrop/render/optics.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/tracer.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

// The tolerance auto is held to where it skipped something, in 8-bit levels.
constexpr double kToleranceRmse = 0.5, kToleranceMax = 4.0;

// The red and blue indices of the dispersion effect (620 and 460 nm) and green's.
glm::dvec3 rgb_indices() {
  SceneConfig c;
  c.dispersion.enabled = true;
  return c.channel_indices();
}

// The exit direction's angle, in the plane of incidence, of the camera ray through the base
// point at `v` cm downhill from the drop's centre, traced through the drop with index n; NaN
// in the dark band.
double exit_angle(const GlassPlane& glass, const DropAccel& accel, double v, double n) {
  const glm::dvec3 base = glass.point({0.0, v});
  const DropPath p = trace_through_drops({0, 0, 0}, base, n, TirMode::Black, false, accel, glass);
  if (!p.hit || p.dark) return NAN;
  return std::atan2(p.dir.y, p.dir.z);
}

// The largest shift, in cm on the glass, between the red and the blue image of a drop
// along the plane of incidence, from traced rays: at each base point, the red ray's exit
// angle is found again on the blue curve, and the dark band's edges are compared.
double traced_spread_cm(const GlassPlane& glass, const DropShape& shape, double n_red, double n_blue) {
  std::vector<Drop> drops{Drop(shape, glass)};
  const DropAccel accel(drops, GeometryOptions::parse("exact"));
  const double a = shape.footprint_radius;
  constexpr int kN = 4000;
  std::vector<double> v(kN + 1), red(kN + 1), blue(kN + 1);
  for (int i = 0; i <= kN; ++i) {
    v[i] = a * (0.999 * (2.0 * i / kN - 1.0));
    red[i] = exit_angle(glass, accel, v[i], n_red);
    blue[i] = exit_angle(glass, accel, v[i], n_blue);
  }
  double worst = 0;
  for (int i = 1; i < kN; ++i) {
    if (std::isnan(red[i]) != std::isnan(blue[i])) worst = std::max(worst, v[i + 1] - v[i]);  // an edge pixel's width
    if (std::isnan(red[i]) || std::isnan(blue[i]) || std::isnan(blue[i - 1]) || std::isnan(blue[i + 1])) continue;
    const double slope = (blue[i + 1] - blue[i - 1]) / (v[i + 1] - v[i - 1]);
    if (std::abs(slope) > 0) worst = std::max(worst, std::abs(red[i] - blue[i]) / std::abs(slope));
  }
  // The dark band's edges: where each index first and last goes dark.
  auto edges = [&](const std::vector<double>& angle) {
    std::vector<double> e;
    for (int i = 1; i <= kN; ++i)
      if (std::isnan(angle[i]) != std::isnan(angle[i - 1])) e.push_back(0.5 * (v[i] + v[i - 1]));
    return e;
  };
  const auto er = edges(red), eb = edges(blue);
  if (er.size() == eb.size())
    for (size_t i = 0; i < er.size(); ++i) worst = std::max(worst, std::abs(er[i] - eb[i]));
  return worst;
}

}  // namespace

TEST(EffectPolicy, ShiftLevelsFollowTheEdgeSlopeAndTheDropsArea) {
  // No blur: a pixel is the unit square, a shift of s px of a full-contrast edge changes it by 255 s.
  EXPECT_NEAR(shift_levels(0.01, 20, 0), 2.55, 1e-9);
  // A disk blur b px wide: the edge's slope is 4 / (pi b) of its contrast per pixel.
  EXPECT_NEAR(shift_levels(0.1, 20, 8), 255 * 0.1 * 8 / (M_PI * 16), 1e-9);
  // A drop smaller than the blur: only its diameter of edge lies inside the disk ...
  EXPECT_NEAR(shift_levels(0.1, 1, 8), 255 * 0.1 * 2 / (M_PI * 16), 1e-9);
  // ... and however far its content moves, no more than its area changes.
  EXPECT_NEAR(shift_levels(10, 0.2, 0), 255 * M_PI * 0.04, 1e-9);
  EXPECT_EQ(shift_levels(0, 5, 3), 0);
  // A shift wider than a pixel changes it by its full contrast, no more.
  EXPECT_EQ(shift_levels(3, 20, 0), 255);
}

TEST(EffectPolicy, DispersionSpreadMatchesTracedRays) {
  const glm::dvec3 n = rgb_indices();
  // Upright glass (the camera looks square on) and glass tilted to 45 and 30 degrees; caps
  // without and with a dark band (contact angles below and above the critical angle).
  for (double tilt_deg : {90.0, 45.0, 30.0}) {
    for (double tau_deg : {30.0, 45.0, 70.0, 85.0}) {
      SCOPED_TRACE("tilt " + std::to_string(tilt_deg) + ", contact angle " + std::to_string(tau_deg));
      const GlassPlane glass{30.0, tilt_deg * kDegToRad};
      const DropShape shape = cap(0, 0, 0.5, tau_deg);
      const double traced = traced_spread_cm(glass, shape, n.x, n.z);
      const double incidence = std::acos(std::abs(glm::dot(glm::normalize(glass.point({0, 0})), glass.normal())));
      // With 1 px per cm, the formula's pixels are the glass' centimetres.
      const double formula = dispersion_spread_px(shape.sphere_radius(), shape.contact_angle, incidence, n.y, n.z - n.x);
      EXPECT_GT(traced, 0);
      // Within the few per cent of the camera rays' divergence across the drop (the formula
      // takes the incidence at the centre) and of the sampling.
      EXPECT_NEAR(formula / traced, 1.0, 0.1) << "traced " << traced << " cm, formula " << formula;
    }
  }
}

TEST(EffectPolicy, GravityShiftVanishesForTheSphereAndGrowsWithTheDeformation) {
  EXPECT_EQ(gravity_shift_px(10, 1.0, 1.0), 0);
  EXPECT_NEAR(gravity_shift_px(10, 1.0, 0.6), 4.0, 1e-12);
  EXPECT_NEAR(gravity_shift_px(10, 1.3, 1.0), 10 * (1.3 - 1 / 1.3), 1e-12);
  EXPECT_GT(gravity_shift_px(10, 1.3, 0.6), gravity_shift_px(10, 1.3, 1.0));
}

namespace {

// Scenes spanning the regimes auto decides in: drops from a twentieth of a pixel to 17 px in
// radius at 256 x 128 (log-uniform footprints of 0.005-0.3 cm on glass 5-40 cm away),
// contact angles 20-80 degrees, glass from upright to tilted 30 degrees; `kind` 0 without
// blur, 1 with the paper's disk blur, 2 through a thin lens. Every effect named, the ones
// auto decides forced on, and every drop pixel sampled 64 times: close to the converged
// image, against which the criteria are stated.
SceneConfig varied_scene(int kind) {
  SceneConfig c = scene_preset("paper");
  c.glass_distance_cm = {5, 40};
  c.tilt_deg = {30, 90};
  c.drop_count = {10, 30};
  c.size_param = DropSizeParam::FootprintRadius;
  c.drop_size_cm = {0.005, 0.3};
  c.size_distribution = SizeDistribution::LogUniform;
  c.contact_angle_deg = {20, 80};
  c.min_gap_cm = 0.005;
  c.fresnel.enabled = c.dispersion.enabled = c.gravity.enabled = true;
  c.blur.enabled = kind == 1;
  if (kind == 2) {
    c.lens.enabled = true;
    c.lens.f_number = {1.8, 8};
    c.lens.focal_length_mm = {4, 8};
  }
  c.samples_per_pixel = 64;
  c.supersample = Supersample::All;
  return c;
}

// The pixels the picked drops may change: a disk around each footprint's centre reaching past
// the cap's image (at most its radius plus its height, under its radius) and the blur.
cv::Mat drop_disks(const Camera& cam, const SceneSample& scene, const EffectPlan& plan,
                   const std::function<bool(const DropEffects&)>& pick) {
  cv::Mat disks(cam.height, cam.width, CV_8U, cv::Scalar(0));
  for (size_t i = 0; i < scene.drops.size(); ++i) {
    const DropEffects& d = plan.drops[i];
    if (!pick(d)) continue;
    const glm::dvec2 c = cam.project(scene.glass.point(scene.drops[i].center));
    cv::circle(disks, cv::Point(static_cast<int>(std::lround(c.x)), static_cast<int>(std::lround(c.y))),
               static_cast<int>(std::ceil(2 * d.radius_px + d.blur_px / 2 + 2)), 255, -1);
  }
  return disks;
}

// Pixels inside a drop in either render ("inside the drops"): the mask, or any coverage of
// the lens.
cv::Mat covered(const RenderedFrame& a, const RenderedFrame& b) {
  auto one = [](const RenderedFrame& f) { return cv::Mat(f.alpha.empty() ? f.mask > 0 : f.alpha > 1.0f / 255); };
  return one(a) | one(b);
}

struct LevelError {
  double rmse = 0, max = 0;
  double sq = 0, n = 0;
  void add(const cv::Mat& a, const cv::Mat& b, const cv::Mat& region) {
    for (int y = 0; y < a.rows; ++y)
      for (int x = 0; x < a.cols; ++x) {
        if (!region.at<std::uint8_t>(y, x)) continue;
        for (int c = 0; c < 3; ++c) {
          const double d = std::abs(double(a.at<cv::Vec3b>(y, x)[c]) - b.at<cv::Vec3b>(y, x)[c]);
          sq += d * d;
          n += 1;
          max = std::max(max, d);
        }
      }
    rmse = n > 0 ? std::sqrt(sq / n) : 0;
  }
};

}  // namespace

// Every drop where auto skipped dispersion or gravity, on 36 scenes: against the full
// simulation, RMSE under 0.5 and no channel off by 4 levels or more in its pixels. And the
// test is not empty: auto skips dispersion on many drops, gravity on some.
TEST(EffectsAuto, SkippedDispersionAndGravityStayWithinTolerance) {
  const Camera cam = camera(256, 128, 283);
  const cv::Mat clean = demo_street(cam.width, cam.height);
  int drops = 0, no_dispersion = 0, no_gravity = 0;
  LevelError all, full1_error, auto1_error;
  for (int seed = 0; seed < 36; ++seed) {
    SCOPED_TRACE("scene " + std::to_string(seed));
    const SceneConfig full = varied_scene(seed % 3);
    SceneConfig automatic = full;
    automatic.dispersion.automatic = automatic.gravity.automatic = true;
    Rng rng(seed);
    const SceneSample scene = sample_scene(full, cam, rng);
    const RenderedFrame f = render_frame(clean, cam, full, scene);
    const RenderedFrame a = render_frame(clean, cam, automatic, scene);
    ASSERT_EQ(a.effects.drops.size(), scene.drops.size());
    const cv::Mat disks = drop_disks(cam, scene, a.effects, [](const DropEffects& d) { return !d.dispersion || !d.gravity; });
    LevelError e;
    e.add(a.rainy, f.rainy, disks & covered(a, f));
    all.add(a.rainy, f.rainy, disks & covered(a, f));
    EXPECT_LT(e.max, kToleranceMax);
    // Away from those drops the two renders are the same, byte for byte.
    EXPECT_EQ(cv::norm(a.rainy, f.rainy, cv::NORM_INF, disks == 0), 0);
    // At one sample per pixel the inside of a drop aliases: the render is further from the
    // converged image than the effects skipped, and skipping them adds nothing that shows.
    SceneConfig full1 = full, automatic1 = automatic;
    full1.samples_per_pixel = automatic1.samples_per_pixel = 1;
    full1_error.add(render_frame(clean, cam, full1, scene).rainy, f.rainy, disks & covered(a, f));
    auto1_error.add(render_frame(clean, cam, automatic1, scene).rainy, f.rainy, disks & covered(a, f));
    drops += static_cast<int>(scene.drops.size());
    for (const DropEffects& d : a.effects.drops) {
      no_dispersion += !d.dispersion;
      no_gravity += !d.gravity;
    }
  }
  // The RMSE over all of them (a frame's skipped drops may hold a single pixel).
  EXPECT_LT(all.rmse, kToleranceRmse);
  std::printf("skipped: dispersion on %d, gravity on %d of %d drops; %.0f pixel values, RMSE %.3f, max %.0f\n",
              no_dispersion, no_gravity, drops, all.n, all.rmse, all.max);
  std::printf("at 1 spp against the converged full render: full RMSE %.2f, auto RMSE %.2f\n", full1_error.rmse,
              auto1_error.rmse);
  EXPECT_GT(full1_error.rmse, all.rmse);
  EXPECT_LT(auto1_error.rmse, full1_error.rmse + kToleranceRmse);
  EXPECT_GT(no_dispersion, drops / 3) << "auto skipped dispersion on too few drops for the test to tell";
  EXPECT_GT(no_gravity, drops / 10) << "auto skipped gravity on too few drops for the test to tell";
}

namespace {

// One drop of radius about 7 px at the frame's centre, on upright glass 20 cm away, seen
// without blur: big enough that auto keeps every effect.
struct OneDrop {
  Camera cam = camera(256, 128, 283);
  cv::Mat clean = demo_street(256, 128);
  SceneConfig config;
  SceneSample scene;
  OneDrop(double footprint_cm, double contact_angle_deg) {
    config.blur.enabled = false;
    config.dispersion.enabled = config.gravity.enabled = true;
    config.samples_per_pixel = 64;
    config.supersample = Supersample::All;
    scene.glass = GlassPlane{20, 60 * kDegToRad};
    scene.background_distance_cm = 1000;
    scene.drops = {cap(0, 0, footprint_cm, contact_angle_deg)};
    scene.drops[0].elongation = 1.2;
    scene.drops[0].flattening = 0.8;
  }
  SceneConfig automatic() const {
    SceneConfig c = config;
    c.dispersion.automatic = c.gravity.automatic = true;
    return c;
  }
};

}  // namespace

// The criteria are not just "always on": where auto keeps an effect, skipping it would break
// the tolerance the skipped drops are held to.
TEST(EffectsAuto, AnEffectAutoKeepsWouldShowIfSkipped) {
  const OneDrop d(0.5, 60);
  const RenderedFrame full = render_frame(d.clean, d.cam, d.config, d.scene);
  const RenderedFrame a = render_frame(d.clean, d.cam, d.automatic(), d.scene);
  ASSERT_EQ(a.effects.drops.size(), 1u);
  EXPECT_TRUE(a.effects.drops[0].dispersion) << a.effects.drops[0].dispersion_levels << " levels";
  EXPECT_TRUE(a.effects.drops[0].gravity) << a.effects.drops[0].gravity_levels << " levels";
  EXPECT_EQ(cv::norm(a.rainy, full.rainy, cv::NORM_INF), 0);

  // Dispersion skipped: every channel with the green index.
  SceneConfig no_dispersion = d.config;
  no_dispersion.dispersion.enabled = false;
  no_dispersion.refractive_index = d.config.channel_indices().y;
  const RenderedFrame nd = render_frame(d.clean, d.cam, no_dispersion, d.scene);
  // Gravity skipped: the spherical cap of the same footprint.
  SceneSample sphere = d.scene;
  sphere.drops[0].elongation = sphere.drops[0].flattening = 1;
  const RenderedFrame ng = render_frame(d.clean, d.cam, d.config, sphere);
  const cv::Mat region = covered(full, nd) | covered(full, ng);
  for (const RenderedFrame* skipped : {&nd, &ng}) {
    LevelError e;
    e.add(skipped->rainy, full.rainy, region);
    EXPECT_GT(e.rmse, kToleranceRmse) << (skipped == &nd ? "dispersion" : "gravity");
    EXPECT_GT(e.max, kToleranceMax) << (skipped == &nd ? "dispersion" : "gravity");
  }
}

// When no drop of a frame needs dispersion, the frame runs the kernel without it, every
// channel with the green index: the render is that of the scene without dispersion at that
// index, byte for byte. When every drop needs it, the render is the full one, byte for byte.
TEST(EffectsAuto, DispersionEverywhereOrNowhereIsExact) {
  const OneDrop tiny(0.005, 60);  // a fifth of a pixel across
  SceneConfig automatic = tiny.automatic();
  const RenderedFrame a = render_frame(tiny.clean, tiny.cam, automatic, tiny.scene);
  ASSERT_FALSE(a.effects.dispersion_anywhere(automatic));
  SceneConfig green = tiny.config;
  green.dispersion.enabled = false;
  green.refractive_index = tiny.config.channel_indices().y;
  SceneSample sphere = tiny.scene;
  sphere.drops[0].elongation = sphere.drops[0].flattening = 1;
  ASSERT_FALSE(a.effects.drops[0].gravity);
  EXPECT_EQ(cv::norm(a.rainy, render_frame(tiny.clean, tiny.cam, green, sphere).rainy, cv::NORM_INF), 0);

  // The paper's drops at 512 x 256 without blur: every one needs both effects.
  SceneConfig full = scene_preset("paper");
  full.blur.enabled = false;
  full.dispersion.enabled = full.gravity.enabled = true;
  SceneConfig every = full;
  every.dispersion.automatic = every.gravity.automatic = true;
  const Camera cam = camera(512, 256, 566);
  const cv::Mat clean = demo_street(cam.width, cam.height);
  Rng rng(3);
  const SceneSample scene = sample_scene(full, cam, rng);
  const RenderedFrame e = render_frame(clean, cam, every, scene);
  for (const DropEffects& d : e.effects.drops) EXPECT_TRUE(d.dispersion && d.gravity);
  EXPECT_EQ(cv::norm(e.rainy, render_frame(clean, cam, full, scene).rainy, cv::NORM_INF), 0);
}

namespace {

// Traces `scene` with `samples` per pixel and supersampling `where`.
TraceResult trace_with(const cv::Mat& clean, const Camera& cam, SceneConfig c, const SceneSample& scene,
                       int samples, Supersample where) {
  c.samples_per_pixel = samples;
  c.supersample = where;
  std::vector<Drop> drops;
  for (const DropShape& d : scene.drops) drops.emplace_back(d, scene.glass);
  const DropAccel accel(drops, c.geometry);
  return trace_drops(clean, cam, c, scene, accel);
}

// A trace's colours in 8 bits, as the renderer writes them.
cv::Mat colour8(const TraceResult& t) {
  cv::Mat out;
  t.color.convertTo(out, CV_8UC3, 255.0);
  return out;
}

// Drop pixels whose colour is the same, in every channel, in two traces.
cv::Mat same_colour(const TraceResult& a, const TraceResult& b) {
  cv::Mat out(a.color.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x)
      out.at<std::uint8_t>(y, x) = a.label.at<int>(y, x) >= 0 && a.color.at<cv::Vec3f>(y, x) == b.color.at<cv::Vec3f>(y, x) ? 255 : 0;
  return out;
}

}  // namespace

// Auto supersampling keeps one sample only in pixels whose footprint on the background varies
// by less than the budget: there it is within the budget of every drop pixel sampled 4 times,
// on the paper's scenes at 256 x 128 over the demo street, sharp and blurred, and over flat
// tiles with sharp edges between them. The inside pixels it supersamples would break the
// tolerance if left at one sample.
TEST(EffectsAuto, SupersamplingIsSkippedOnlyWhereTheFootprintIsFlat) {
  const Camera cam = camera(256, 128, 283);
  int kept_one = 0;
  LevelError skipped, needed;
  for (int background = 0; background < 3; ++background) {
    cv::Mat clean = demo_street(cam.width, cam.height);
    if (background == 1) cv::GaussianBlur(clean, clean, cv::Size(), 3.0);
    if (background == 2) {
      for (int y = 0; y < cam.height; ++y)
        for (int x = 0; x < cam.width; ++x)
          clean.at<cv::Vec3b>(y, x) = cv::Vec3b(40 + 60 * (x / 64), 200 - 50 * (y / 32), 120 + 40 * ((x / 64 + y / 32) % 2));
    }
    for (int seed = 0; seed < 10; ++seed) {
      SceneConfig c = scene_preset("paper");
      c.blur.enabled = false;
      Rng rng(seed);
      const SceneSample scene = sample_scene(c, cam, rng);
      const TraceResult one = trace_with(clean, cam, c, scene, 1, Supersample::Edges);
      const TraceResult all = trace_with(clean, cam, c, scene, 4, Supersample::All);
      const TraceResult edges = trace_with(clean, cam, c, scene, 4, Supersample::Edges);
      const TraceResult automatic = trace_with(clean, cam, c, scene, 4, Supersample::Auto);
      kept_one += static_cast<int>(automatic.stats.smooth_pixels);
      // Left at one sample by auto: the colour is the single sample's. Supersampled by auto
      // but not at the edges: inside pixels that alias.
      skipped.add(colour8(automatic), colour8(all), same_colour(automatic, one));
      needed.add(colour8(edges), colour8(all), (one.label >= 0) & ~same_colour(automatic, edges));
    }
  }
  std::printf("supersampling auto: %d inside pixels kept one sample: RMSE %.3f, max %.0f against 4 spp everywhere; "
              "the aliasing ones at one sample: RMSE %.2f, max %.0f\n",
              kept_one, skipped.rmse, skipped.max, needed.rmse, needed.max);
  EXPECT_GT(kept_one, 0);
  EXPECT_LT(skipped.rmse, kToleranceRmse);
  EXPECT_LT(skipped.max, kAutoBudgetLevels + 1);  // the bound, plus rounding to 8 bits
  EXPECT_GT(needed.rmse, kToleranceRmse);
  EXPECT_GT(needed.max, kToleranceMax);
}

// On a flat background nothing inside a drop aliases: auto supersamples the edges, and inside
// only the few pixels where the map to the background folds (towards the dark band), and the
// render is within rounding of every drop pixel supersampled.
TEST(EffectsAuto, OnAFlatBackgroundInsidePixelsKeepOneSample) {
  OneDrop d(0.5, 40);
  d.clean = cv::Mat(d.cam.height, d.cam.width, CV_8UC3, cv::Scalar(90, 120, 150));
  d.scene.drops[0].elongation = d.scene.drops[0].flattening = 1;
  const TraceResult automatic = trace_with(d.clean, d.cam, d.config, d.scene, 4, Supersample::Auto);
  const TraceResult all = trace_with(d.clean, d.cam, d.config, d.scene, 4, Supersample::All);
  EXPECT_GT(automatic.stats.smooth_pixels, 0);
  EXPECT_LT(automatic.stats.aliasing_pixels, automatic.stats.smooth_pixels / 5)
      << automatic.stats.aliasing_pixels << " supersampled, " << automatic.stats.smooth_pixels << " kept one";
  LevelError e;
  e.add(colour8(automatic), colour8(all), automatic.label >= 0);
  EXPECT_LE(e.max, 1);
}

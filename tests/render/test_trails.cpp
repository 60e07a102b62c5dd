// Trails (trails.h): the water volume against the drop's surface, Furmidge's sliding balance
// in closed form, conservation of water between a drop and its trail, the trail's place on
// the glass, and the mask a head-on trail renders.
#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "raindrop/common/rng.h"
#include "raindrop/render/drop.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/trails.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

// Volume of a circular cap per footprint radius cubed: V = k(tau) a^3.
double cap_coefficient(double tau) {
  const double c = std::cos(tau), s = std::sin(tau);
  return M_PI * (1 - c) * (1 - c) * (2 + c) / (3 * s * s * s);
}

// The footprint radius from which a circular cap slides: V sin(psi) = 2 a Delta l_c^2.
double critical_radius(double tau, double tilt, double hysteresis) {
  return std::sqrt(2 * hysteresis * kCapillaryLengthSquaredCm2 / (std::sin(tilt) * cap_coefficient(tau)));
}

SceneConfig with_trails(const char* preset) {
  SceneConfig c = scene_preset(preset);
  c.trails.enabled = true;
  return c;
}

}  // namespace

TEST(Trails, VolumeIsTheWaterUnderTheSurface) {
  // drop_volume against the water thickness integrated over a grid of rays along the normal,
  // for a circular cap and for a lobed, stretched and flattened one.
  const double N = 30;
  DropShape round = cap(0, 0, 0.4, 70);
  DropShape odd = cap(0, 0, 0.4, 45);
  odd.outline = Outline({0.1, -0.04, 0.05}, {0.03, 0.06, 0.0});
  odd.elongation = 1.25;
  odd.flattening = 0.8;
  for (const DropShape& shape : {round, odd}) {
    const Drop drop(shape, upright_glass(N));
    const glm::dvec2 half = shape.footprint_semi_axes();
    constexpr int kGrid = 300;
    const double du = 2 * half.x / kGrid, dv = 2 * half.y / kGrid;
    double volume = 0;
    for (int i = 0; i < kGrid; ++i) {
      for (int j = 0; j < kGrid; ++j) {
        const glm::dvec3 origin{-half.x + (i + 0.5) * du, -half.y + (j + 0.5) * dv, N - 1.0}, dir{0, 0, 1};
        const auto in = drop.intersect(origin, dir, 0.0, 1e9);
        if (!in || in->surface != DropSurface::Base) continue;
        const auto out = drop.intersect(origin + in->t * dir, dir, 0.0, 1e9, DropSurface::Base);
        if (out) volume += out->t * du * dv;
      }
    }
    EXPECT_NEAR(volume / drop_volume(shape), 1.0, 5e-3);
  }
  // A hemisphere: 2/3 pi a^3.
  EXPECT_NEAR(drop_volume(cap(0, 0, 0.3, 90)), 2.0 / 3.0 * M_PI * 0.027, 1e-15);
}

TEST(Trails, DropsSlideFromFurmidgesCriticalRadius) {
  for (const double tau_deg : {20.0, 60.0, 90.0}) {
    for (const double tilt_deg : {10.0, 45.0, 90.0}) {
      for (const double hysteresis : {0.05, 0.2, 0.6}) {
        const double tau = tau_deg * kDegToRad, tilt = tilt_deg * kDegToRad;
        const double a = critical_radius(tau, tilt, hysteresis);
        EXPECT_TRUE(drop_slides(cap(0, 0, a * (1 + 1e-9), tau_deg), tilt, hysteresis)) << tau_deg << " " << tilt_deg;
        EXPECT_FALSE(drop_slides(cap(0, 0, a * (1 - 1e-9), tau_deg), tilt, hysteresis)) << tau_deg << " " << tilt_deg;
      }
    }
  }
  // The figure trails.h quotes: on upright glass with Delta 0.2 a 60-degree cap slides from
  // about 1.7 mm; a slope of 30 degrees holds drops sqrt(2) times wider; flat glass holds all.
  EXPECT_NEAR(critical_radius(60 * kDegToRad, M_PI / 2, 0.2), 0.17, 0.005);
  EXPECT_NEAR(critical_radius(60 * kDegToRad, 30 * kDegToRad, 0.2) / critical_radius(60 * kDegToRad, M_PI / 2, 0.2),
              std::sqrt(2.0), 1e-12);
  EXPECT_FALSE(drop_slides(cap(0, 0, 5.0, 90), 0.0, 0.01));
}

TEST(Trails, TheWaterOnTheGlassIsTheWaterDrawn) {
  // With and without trails from one seed: every drop keeps its place, centre and contact
  // angle; a drop that slid gave its trail exactly the water the trail holds, at most the
  // allowed fraction; the others are untouched.
  const Camera cam = camera(512, 256, 560);
  int slid = 0;
  for (const char* preset : {"paper", "windshield-day", "lens-cover-merged"}) {
    const SceneConfig on = with_trails(preset);
    SceneConfig off = on;
    off.trails.enabled = false;
    for (std::uint64_t seed = 1; seed <= 4; ++seed) {
      Rng a(seed), b(seed);
      const SceneSample s = sample_scene(on, cam, a), p = sample_scene(off, cam, b);
      ASSERT_GE(s.drops.size(), p.drops.size());
      std::map<int, double> trail_volume;
      for (size_t i = p.drops.size(); i < s.drops.size(); ++i) {
        ASSERT_GE(s.drops[i].trail_of, 0) << preset;
        ASSERT_LT(s.drops[i].trail_of, static_cast<int>(p.drops.size()));
        trail_volume[s.drops[i].trail_of] += drop_volume(s.drops[i]);
      }
      for (size_t i = 0; i < p.drops.size(); ++i) {
        const DropShape &d = s.drops[i], &before = p.drops[i];
        EXPECT_EQ(d.trail_of, -1);
        EXPECT_EQ(d.center, before.center);
        EXPECT_EQ(d.contact_angle, before.contact_angle);
        const auto t = trail_volume.find(static_cast<int>(i));
        if (t == trail_volume.end()) {
          EXPECT_EQ(d.footprint_radius, before.footprint_radius);
          continue;
        }
        ++slid;
        EXPECT_NEAR((drop_volume(d) + t->second) / drop_volume(before), 1.0, 1e-12) << preset << " drop " << i;
        EXPECT_LE(t->second, on.trails.max_volume_fraction * drop_volume(before) * (1 + 1e-12));
        EXPECT_LT(d.footprint_radius, before.footprint_radius);
      }
    }
  }
  EXPECT_GT(slid, 50);  // the check above ran on many trails
}

TEST(Trails, CapsRunStraightUphillFromTheRimWithTheirDrawnSpacing) {
  SceneConfig config = with_trails("paper");
  config.gravity.enabled = true;  // stretched drops: the rim is further uphill
  config.outline.enabled = true;  // and irregular
  config.trails.spacing = {0.6, 1.2};
  const Camera cam = camera(512, 256, 560);
  Rng rng(9);
  const SceneSample s = sample_scene(config, cam, rng);
  std::map<int, std::vector<const DropShape*>> trails;
  for (const DropShape& d : s.drops)
    if (d.trail_of >= 0) trails[d.trail_of].push_back(&d);
  ASSERT_GT(trails.size(), 10u);
  for (const auto& [parent_index, caps] : trails) {
    const DropShape& parent = s.drops[parent_index];
    const double rim = uphill_rim_distance(parent);
    // The rim point is on the drop's contact line: just inside it is water, just outside not.
    const Drop drop(parent, s.glass);
    const glm::dvec3 lift = 1e-9 * s.glass.normal();
    EXPECT_TRUE(drop.contains(s.glass.point(parent.center - glm::dvec2(0, rim * (1 - 1e-6))) + lift));
    EXPECT_FALSE(drop.contains(s.glass.point(parent.center - glm::dvec2(0, rim * (1 + 1e-6))) + lift));
    EXPECT_NEAR(caps.front()->center.y, parent.center.y - rim, 1e-12);
    double previous_v = caps.front()->center.y + 1;
    for (size_t k = 0; k < caps.size(); ++k) {
      const DropShape& c = *caps[k];
      EXPECT_EQ(c.center.x, parent.center.x);  // straight uphill: same position across
      EXPECT_LT(c.center.y, previous_v);
      EXPECT_GE(c.contact_angle, config.trails.contact_angle_deg.lo * kDegToRad - 1e-12);
      EXPECT_LE(c.contact_angle, config.trails.contact_angle_deg.hi * kDegToRad + 1e-12);
      EXPECT_TRUE(c.outline.circular());
      EXPECT_EQ(c.elongation, 1.0);
      if (k > 0) {
        const double spacing = (caps[k - 1]->center.y - c.center.y) /
                               (caps[k - 1]->footprint_radius + c.footprint_radius);
        EXPECT_GE(spacing, config.trails.spacing.lo - 1e-9);
        EXPECT_LE(spacing, config.trails.spacing.hi + 1e-9);
      }
      previous_v = c.center.y;
    }
    // The trail is no longer than the longest slide the scene allows, in the drop's radii as
    // drawn (it shrank by at most the volume fraction).
    const double drawn = parent.footprint_radius / std::cbrt(1 - config.trails.max_volume_fraction);
    EXPECT_LE(parent.center.y - rim - caps.back()->center.y, config.trails.length_radii.hi * drawn + 1e-12);
  }
}

TEST(Trails, HeadOnATrailRunsStraightUpFromItsDrop) {
  // Upright glass facing the camera: uphill is straight up the image. A joined trail (spacing
  // below 1) is one run of mask pixels up the drop's column, from the drop's lowest row to the
  // last cap's top, and nothing lies below the drop or beside the trail.
  const Camera cam = camera(300, 400, 500);
  const double N = 30;
  SceneConfig config = scene_preset("paper");
  config.blur.enabled = false;
  config.trails.enabled = true;
  config.trails.hysteresis = {0.2, 0.2};
  config.trails.length_radii = {4, 4};
  config.trails.width = {0.3, 0.3};
  config.trails.contact_angle_deg = {20, 20};
  config.trails.spacing = {0.8, 0.8};
  SceneSample scene;
  scene.glass = upright_glass(N);
  scene.background_distance_cm = 1000;
  scene.drops = {cap(0, 0.6, 0.5, 60)};  // well above the 0.17 cm critical radius
  Rng rng(1);
  add_trails(&scene.drops, config.trails, scene.glass.tilt, rng);
  ASSERT_GT(scene.drops.size(), 5u);
  const DropShape& drop = scene.drops[0];
  const DropShape& last = scene.drops.back();
  const cv::Mat clean(cam.height, cam.width, CV_8UC3, cv::Scalar(90, 120, 150));
  const cv::Mat mask = render_frame(clean, cam, config, scene).mask;
  const double px = cam.fx / N;  // pixels per cm on the glass
  const double bottom = cam.cy + px * (drop.center.y + drop.footprint_radius);
  const double top = cam.cy + px * (last.center.y - last.footprint_radius);
  const int column = static_cast<int>(std::lround(cam.cx));
  int first = -1, last_row = -1, runs = 0;
  for (int y = 0; y < cam.height; ++y) {
    if (!mask.at<uchar>(y, column)) continue;
    if (last_row != y - 1) ++runs;
    if (first < 0) first = y;
    last_row = y;
  }
  EXPECT_EQ(runs, 1);
  EXPECT_NEAR(first, top, 1.5);
  EXPECT_NEAR(last_row, bottom, 1.5);
  // Nothing outside the drop's circle and the trail's band.
  const double band = px * config.trails.width.hi * drop.footprint_radius / std::cbrt(1 - config.trails.max_volume_fraction);
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      if (!mask.at<uchar>(y, x)) continue;
      const double dx = x - cam.cx, dy = y - (cam.cy + px * drop.center.y);
      const bool in_drop = std::hypot(dx, dy) <= px * drop.footprint_radius + 1.5;
      const bool in_trail = std::abs(dx) <= band + 1.5 && y >= top - 1.5 && dy <= 0;
      EXPECT_TRUE(in_drop || in_trail) << x << "," << y;
      if (!(in_drop || in_trail)) return;
    }
  }
}

TEST(Trails, WhichDropsSlideDoesNotDependOnTheTrailsShapes) {
  // Every drop's hysteresis is drawn before any trail: other widths, spacings and lengths
  // change the trails, not which drops leave one.
  const Camera cam = camera(512, 256, 560);
  SceneConfig a = with_trails("lens-cover-merged"), b = a;
  b.trails.width = {0.2, 0.5};
  b.trails.spacing = {1.5, 2.5};
  b.trails.length_radii = {1, 3};
  auto parents = [&](const SceneConfig& config) {
    Rng rng(21);
    std::vector<int> out;
    for (const DropShape& d : sample_scene(config, cam, rng).drops)
      if (d.trail_of >= 0 && (out.empty() || out.back() != d.trail_of)) out.push_back(d.trail_of);
    return out;
  };
  const std::vector<int> pa = parents(a), pb = parents(b);
  EXPECT_GT(pa.size(), 5u);
  EXPECT_EQ(pa, pb);
}

TEST(Trails, PinnedDropsOrNoWaterToSpareLeaveTheSceneAsItWas) {
  // Trails are drawn after everything else: where no drop slides (the largest hysteresis pins
  // every drop of windshield-day) or none may leave water behind, the scene is the one without.
  const Camera cam = camera(512, 256, 560);
  const SceneConfig plain = scene_preset("windshield-day");
  SceneConfig pinned = with_trails("windshield-day");
  pinned.trails.hysteresis = {2, 2};
  SceneConfig dry = with_trails("windshield-day");
  dry.trails.max_volume_fraction = 0;
  for (const SceneConfig* config : {&pinned, &dry}) {
    Rng a(5), b(5);
    const SceneSample s = sample_scene(plain, cam, a), t = sample_scene(*config, cam, b);
    ASSERT_GT(s.drops.size(), 20u);
    if (config == &pinned) {
      for (const DropShape& d : s.drops) ASSERT_FALSE(drop_slides(d, s.glass.tilt, 2.0));
    } else {
      ASSERT_TRUE(std::any_of(s.drops.begin(), s.drops.end(),
                              [&](const DropShape& d) { return drop_slides(d, s.glass.tilt, config->trails.hysteresis.hi); }));
    }
    ASSERT_EQ(s.drops.size(), t.drops.size());
    for (size_t i = 0; i < s.drops.size(); ++i) {
      EXPECT_EQ(s.drops[i].center, t.drops[i].center);
      EXPECT_EQ(s.drops[i].footprint_radius, t.drops[i].footprint_radius);
    }
  }
}

TEST(Trails, SceneFilesNameTrailsAndRefuseBadOnes) {
  const SceneConfig c = parse_scene_json(
      R"({"effects": {"trails": {"hysteresis": [0.1, 0.2], "length_radii": [1, 3], "spacing": 0.9,
          "max_volume_fraction": 0.3}}})",
      "t.json");
  EXPECT_TRUE(c.trails.enabled);
  EXPECT_EQ(c.trails.hysteresis.hi, 0.2);
  EXPECT_EQ(c.trails.length_radii.lo, 1);
  EXPECT_EQ(c.trails.spacing.lo, 0.9);
  EXPECT_EQ(c.trails.max_volume_fraction, 0.3);
  EXPECT_EQ(c.trails.width.lo, SceneConfig{}.trails.width.lo);  // unnamed keys keep their defaults
  const SceneConfig back = parse_scene_json(scene_to_json(c), "back.json");
  EXPECT_TRUE(back.trails.enabled);
  for (const auto field : {&SceneConfig::Trails::hysteresis, &SceneConfig::Trails::length_radii, &SceneConfig::Trails::width,
                           &SceneConfig::Trails::contact_angle_deg, &SceneConfig::Trails::spacing}) {
    EXPECT_EQ((back.trails.*field).lo, (c.trails.*field).lo);
    EXPECT_EQ((back.trails.*field).hi, (c.trails.*field).hi);
  }
  EXPECT_EQ(back.trails.max_volume_fraction, c.trails.max_volume_fraction);
  EXPECT_EQ(scene_to_json(back), scene_to_json(c));
  const auto names = c.effect_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "trails"), names.end());
  EXPECT_FALSE(parse_scene_json(R"({"effects": {}})", "t.json").trails.enabled);
  expect_scene_refused(R"({"effects": {"trails": {"spacing": [0.1, 1]}}})", "spacing");
  expect_scene_refused(R"({"effects": {"trails": {"width": 0}}})", "width");
  expect_scene_refused(R"({"effects": {"trails": {"hysteresis": -0.1}}})", "hysteresis");
  expect_scene_refused(R"({"effects": {"trails": {"max_volume_fraction": 1}}})", "max_volume_fraction");
  expect_scene_refused(R"({"effects": {"trails": "auto"}})", "trails");
  expect_scene_refused(R"({"effects": {"trails": {"length": 3}}})", "length");
}

// A trail long enough to run up a tilted glass past the camera's plane: its caps there are
// nowhere in view, and their projections were NaN (the manifest's shift and spread as null).
// They are left out; every cap kept is in front of the camera, and the drops are drawn as
// without the cut. A mesh of caps counts against the scene's mesh limit.
TEST(Trails, CapsPastTheCamerasPlaneAreLeftOut) {
  SceneConfig config = parse_scene_json(
      R"({"glass_distance_cm": 20, "tilt_deg": 30, "drop_count": 20, "footprint_radius_cm": [1, 1.5],
          "effects": {"trails": {"length_radii": 50, "hysteresis": 0.1}}})",
      "t.json");
  const Camera cam = camera(256, 128, 300);
  size_t caps = 0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    Rng rng(seed);
    const SceneSample s = sample_scene(config, cam, rng);
    Rng plain_rng(seed);
    SceneConfig plain = config;
    plain.trails.enabled = false;
    const SceneSample without = sample_scene(plain, cam, plain_rng);
    ASSERT_LE(without.drops.size(), s.drops.size());
    for (size_t i = 0; i < s.drops.size(); ++i) {
      const DropShape& d = s.drops[i];
      EXPECT_GT(s.glass.point(d.center).z, d.footprint_radius * std::abs(std::cos(s.glass.tilt)))
          << "seed " << seed << " drop " << i;
      if (d.trail_of < 0) {
        EXPECT_EQ(d.center, without.drops[i].center);
      } else {
        ++caps;
      }
    }
  }
  EXPECT_GT(caps, 100u) << "the trails are there, short of the camera's plane";
  expect_scene_refused(R"({"drop_count": 100, "quality": {"geometry": "mesh-64-flat"},
      "effects": {"trails": {"hysteresis": 0, "length_radii": 50}}})", "trails' caps");
  EXPECT_NO_THROW(parse_scene_json(R"({"drop_count": 100, "quality": {"geometry": "mesh-64-flat"}})", "t.json"));
  // The caps' bound follows the trails' own settings: the paper's drops with default trails
  // (at most 39 caps a drop, about 12 in practice) fit a 64-segment mesh.
  EXPECT_NO_THROW(parse_scene_json(R"({"effects": {"blur": {}, "trails": {}}, "quality": {"geometry": "mesh-64-smooth"}})",
                                   "t.json"));
}

// A drop the scene places in glass coordinates behind the camera is an error naming it, as one
// placed at a pixel the camera does not see on the glass is.
TEST(Trails, APlacedDropBehindTheCameraIsAnError) {
  const SceneConfig config = parse_scene_json(
      R"({"glass_distance_cm": 1, "tilt_deg": 15, "drop_count": 0,
          "drops": [{"center_cm": [0, -10], "footprint_radius_cm": 0.5, "contact_angle_deg": 30}]})",
      "t.json");
  // Wholly in front of the camera though wider than the glass is near (upright glass: every
  // point of the footprint at the glass' depth): placed.
  Rng upright_rng(1);
  const SceneConfig upright = parse_scene_json(
      R"({"glass_distance_cm": 1.5, "tilt_deg": 90, "drop_count": 0,
          "drops": [{"center_cm": [0, 0], "footprint_radius_cm": 1.6, "contact_angle_deg": 30}]})",
      "t.json");
  EXPECT_EQ(sample_scene(upright, camera(256, 128, 300), upright_rng).drops.size(), 1u);
  Rng rng(1);
  try {
    sample_scene(config, camera(256, 128, 300), rng);
    ADD_FAILURE() << "a drop behind the camera was placed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("drops[0]"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not in front of the camera"), std::string::npos) << e.what();
  }
}

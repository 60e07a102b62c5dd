// Highlights (highlights.h): clipped pixels lifted back to the light they stood for before the
// lens spreads it. Checked against closed forms: light adds linearly, so a drop that sees a lamp
// `gain` times brighter than full scale adds `gain` times the light to every pixel its circle
// of confusion reaches; and a lamp seen past a dark drop by most of the aperture stays clipped.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"
#include "raindrop/common/rng.h"
#include "raindrop/render/defocus.h"
#include "raindrop/common/demo.h"
#include "raindrop/render/highlights.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/scene_config.h"
#include "raindrop/render/srgb.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

HighlightLift lift(double threshold_srgb, double gain) {
  HighlightLift h;
  h.threshold = static_cast<float>(srgb_to_linear(threshold_srgb));
  h.gain = static_cast<float>(gain);
  return h;
}

// One drop 5 cm in front of an f/1, 5 mm lens focused at 10 m: a circle of confusion of
// 0.5 cm x 200 px x (1/5 - 1/1000) = 19.9 px at fx 200, over a 16 px outline.
SceneSample one_drop_scene() {
  SceneSample s = lens_sample(5, 1, 5, 1000);
  s.drops = {cap(0, 0, 0.2, 40)};
  return s;
}

// A pinhole trace by hand: drop 0 covers a disc of `radius` px at the frame's centre, and every
// one of its pixels sees `seen` (sRGB, as the tracer stores it).
TraceResult disc_trace(const Camera& cam, int radius, float seen) {
  TraceResult t;
  t.label = cv::Mat(cam.height, cam.width, CV_32S, cv::Scalar(-1));
  t.color = cv::Mat(cam.height, cam.width, CV_32FC3, cv::Scalar::all(0));
  const int cx = cam.width / 2, cy = cam.height / 2;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      if ((x - cx) * (x - cx) + (y - cy) * (y - cy) > radius * radius) continue;
      t.label.at<int>(y, x) = 0;
      t.color.at<cv::Vec3f>(y, x) = cv::Vec3f(seen, seen, seen);
    }
  }
  t.drop_box = cv::Rect(cx - radius, cy - radius, 2 * radius + 1, 2 * radius + 1);
  return t;
}

}  // namespace

TEST(Highlights, TheLiftIsOneBelowTheThresholdAndTheGainAtFullScale) {
  const HighlightLift h = lift(0.9, 8);
  ASSERT_TRUE(h.active());
  const float t = h.threshold;
  EXPECT_FLOAT_EQ(t, static_cast<float>(srgb_to_linear(0.9)));
  EXPECT_EQ(h.factor(0.0f), 1.0f);
  EXPECT_EQ(h.factor(t), 1.0f);
  EXPECT_FLOAT_EQ(h.factor(1.0f), 8.0f);
  // Continuous at the threshold, and m x factor(m) increasing: a brighter stored pixel never
  // becomes a dimmer light.
  EXPECT_NEAR(h.factor(t + 1e-4f), 1.0f, 1e-5f);
  float last = 0;
  for (int i = 0; i <= 1000; ++i) {
    const float m = i / 1000.0f;
    const float lit = m * h.factor(m);
    EXPECT_GE(lit, last) << m;
    last = lit;
  }
  // The hue is kept: every channel gets the brightest channel's factor.
  float rgb[3] = {1.0f, 0.5f, 0.25f};
  h.apply(rgb);
  EXPECT_FLOAT_EQ(rgb[0], 8.0f);
  EXPECT_FLOAT_EQ(rgb[1], 4.0f);
  EXPECT_FLOAT_EQ(rgb[2], 2.0f);
  // unlift() inverts the lift (the camera's shoulder the mix is stored through), is the
  // identity below the threshold and saturates at the gain.
  for (int i = 0; i <= 1000; ++i) {
    const float m = i / 1000.0f;
    EXPECT_NEAR(h.unlift(m * h.factor(m)), m, 2e-6f) << m;
  }
  EXPECT_EQ(h.unlift(0.5f), 0.5f);
  EXPECT_EQ(h.unlift(8.0f), 1.0f);
  EXPECT_EQ(h.unlift(100.0f), 1.0f);
  float mixed[3] = {4.0f, 2.0f, 0.1f};
  h.restore(mixed);
  EXPECT_NEAR(mixed[0], h.unlift(4.0f), 1e-6f);
  EXPECT_NEAR(mixed[1] / mixed[0], 0.5f, 1e-6f);  // hue kept
  // Gain 1 is off.
  float same[3] = {1.0f, 1.0f, 1.0f};
  lift(0.9, 1).apply(same);
  EXPECT_EQ(same[0], 1.0f);
  EXPECT_FALSE(lift(0.9, 1).active());
}

// A drop that sees a clipped lamp, on a dark street, out of focus: where its spread coverage is
// A, the light is (1 - A) B + gain A, stored through the camera's shoulder (unlift: the identity
// up to the threshold); without the lift, (1 - A) B + A. So the faint bloom around the drop is
// `gain` times brighter, and where the light passes the threshold it rolls off towards full
// scale instead of being cut.
TEST(Highlights, ALampSeenThroughADefocusedDropBloomsByTheGain) {
  const Camera cam = camera(129, 129, 200);
  const cv::Mat dark(cam.height, cam.width, CV_8UC3, cv::Scalar::all(20));
  const double B = srgb8_to_linear_table()[20];
  const TraceResult traced = disc_trace(cam, 8, 1.0f);
  SceneSample plain = one_drop_scene(), lifted = plain;
  const double gain = 8;
  lifted.highlights = lift(0.9, gain);
  const std::vector<Drop> drops = drops_of(plain);
  ASSERT_NEAR(layer_blur_diameter(plain, drops[0], cam.fx, dark.size()), 19.9, 0.1);  // a wide fringe to measure
  const DefocusedFrame a = composite_layers(dark, traced, cam, plain, drops);
  const DefocusedFrame b = composite_layers(dark, traced, cam, lifted, drops);
  const DefocusedFrame exact = composite_layers_exact(dark, traced, cam, lifted, drops);
  EXPECT_EQ(cv::norm(a.coverage, b.coverage, cv::NORM_INF), 0);  // the lift moves light, not coverage
  int fringe = 0, shoulder = 0;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const double A = a.coverage.at<float>(y, x);
      if (A < 0.01) continue;
      const double light = (1 - A) * B + gain * A;
      const int want_plain = linear_to_srgb8((1 - A) * B + A);
      const int want_lifted = linear_to_srgb8(lifted.highlights.unlift(static_cast<float>(light)));
      EXPECT_NEAR(a.rainy.at<cv::Vec3b>(y, x)[1], want_plain, 1) << x << "," << y << " A " << A;
      EXPECT_NEAR(b.rainy.at<cv::Vec3b>(y, x)[1], want_lifted, 1) << x << "," << y << " A " << A;
      EXPECT_NEAR(exact.rainy.at<cv::Vec3b>(y, x)[1], b.rainy.at<cv::Vec3b>(y, x)[1], 1);
      if (light < lifted.highlights.threshold) {
        ++fringe;  // below the shoulder: exactly the linear sum
        EXPECT_NEAR(b.rainy.at<cv::Vec3b>(y, x)[1], linear_to_srgb8(light), 1);
      } else {
        ++shoulder;
        EXPECT_GT(b.rainy.at<cv::Vec3b>(y, x)[1], a.rainy.at<cv::Vec3b>(y, x)[1]);
      }
    }
  }
  EXPECT_GT(fringe, 100);  // enough of the faint bloom to tell the gain from no gain
  EXPECT_GT(shoulder, 100);
}

// Circles of 48-96 px are spread at every second or third pixel and interpolated between
// (defocus_rows.cpp), which would smear the rim of a lamp's bokeh: a small drop that sees a
// lifted lamp spreads it into a disk as bright as the light, edged within a few pixels. Such a
// layer is spread at every pixel, as the exact per-drop convolution does; the same drop seeing
// light below the lift is sampled, within the sampled circles' bounds.
TEST(Highlights, ALiftedLampsBokehKeepsItsRimWhereCirclesAreSampled) {
  const Camera cam = camera(257, 257, 640);
  const cv::Mat dark(cam.height, cam.width, CV_8UC3, cv::Scalar::all(20));
  SceneSample plain = one_drop_scene(), lifted = plain;
  lifted.highlights = lift(0.9, 16);
  const std::vector<Drop> drops = drops_of(plain);
  const double circle = layer_blur_diameter(plain, drops[0], cam.fx, dark.size());
  ASSERT_GT(circle, 60);  // a sampled circle
  ASSERT_LT(circle, 72);
  for (const SceneSample* scene : {&plain, &lifted}) {
    const TraceResult traced = disc_trace(cam, 5, 1.0f);
    const DefocusedFrame fast = composite_layers(dark, traced, cam, *scene, drops);
    const DefocusedFrame exact = composite_layers_exact(dark, traced, cam, *scene, drops);
    const char* what = scene == &lifted ? "lifted" : "plain";
    EXPECT_LE(cv::norm(fast.rainy, exact.rainy, cv::NORM_INF), 2) << what;
    EXPECT_LT(cv::norm(fast.coverage, exact.coverage, cv::NORM_INF), 3 / 255.0) << what;
  }
}

// A frame bright but not clipped (stored 240, above the threshold) behind a dark drop: the
// pixels the blur's faintest edge reaches keep their stored value, as those it does not reach
// do. (Stored with a hard clip after the mix instead of the camera's shoulder, every one of
// them jumped to 255 at the edge of the blur.)
TEST(Highlights, TheFaintEdgeOfABlurKeepsTheStoredValue) {
  const Camera cam = camera(129, 129, 200);
  const cv::Mat bright(cam.height, cam.width, CV_8UC3, cv::Scalar::all(240));
  const TraceResult traced = disc_trace(cam, 8, 0.2f);
  SceneSample lifted = one_drop_scene();
  lifted.highlights = lift(0.9, 16);
  const DefocusedFrame b = composite_layers(bright, traced, cam, lifted, drops_of(lifted));
  int faint = 0;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const float A = b.coverage.at<float>(y, x);
      if (!(A > 0) || A > 0.02f) continue;
      ++faint;
      EXPECT_NEAR(b.rainy.at<cv::Vec3b>(y, x)[0], 240, 1) << x << "," << y << " A " << A;
    }
  }
  EXPECT_GT(faint, 20);
}

// A bright sky seen past a dark drop by part of the aperture: the light (1 - A) gain + A R,
// stored through the shoulder, stays near full scale where most of the aperture sees the sky,
// where the stored values would have made a grey smudge.
TEST(Highlights, AClippedSkySeenPastADarkDropStaysClipped) {
  const Camera cam = camera(129, 129, 200);
  const cv::Mat sky(cam.height, cam.width, CV_8UC3, cv::Scalar::all(255));
  const float seen = 0.2f;  // the dark street the drop shows, inverted
  const TraceResult traced = disc_trace(cam, 8, seen);
  SceneSample plain = one_drop_scene(), lifted = plain;
  const double gain = 16;
  lifted.highlights = lift(0.9, gain);
  const std::vector<Drop> drops = drops_of(plain);
  const DefocusedFrame a = composite_layers(sky, traced, cam, plain, drops);
  const DefocusedFrame b = composite_layers(sky, traced, cam, lifted, drops);
  const double R = srgb_to_linear(seen);
  int darkened = 0, kept = 0;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const double A = std::min(1.0f, a.coverage.at<float>(y, x));
      if (A < 0.01) continue;
      EXPECT_NEAR(a.rainy.at<cv::Vec3b>(y, x)[0], linear_to_srgb8((1 - A) + A * R), 1);
      const float light = static_cast<float>((1 - A) * gain + A * R);
      EXPECT_NEAR(b.rainy.at<cv::Vec3b>(y, x)[0], linear_to_srgb8(lifted.highlights.unlift(light)), 1);
      darkened += a.rainy.at<cv::Vec3b>(y, x)[0] < 250;
      if (A < 0.5) kept += b.rainy.at<cv::Vec3b>(y, x)[0] >= 250;
    }
  }
  EXPECT_GT(darkened, 100);
  EXPECT_GT(kept, darkened / 2);
  // The exact per-drop form agrees.
  const DefocusedFrame exact = composite_layers_exact(sky, traced, cam, lifted, drops);
  EXPECT_LE(cv::norm(exact.rainy, b.rainy, cv::NORM_INF), 1);
}

// Turning the effect on changes no other draw of the sample (its gain is drawn last), and the
// gain stays in its range.
TEST(Highlights, TheGainIsDrawnLastAndWithinItsRange) {
  const Camera cam = camera(256, 128, 283);
  SceneConfig off = scene_preset("lens-cover"), on = off;
  off.highlights.enabled = false;
  on.highlights.enabled = true;
  on.highlights.gain = {4, 16};
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    Rng r1(seed), r2(seed);
    const SceneSample a = sample_scene(off, cam, r1), b = sample_scene(on, cam, r2);
    ASSERT_EQ(a.drops.size(), b.drops.size());
    for (size_t i = 0; i < a.drops.size(); ++i) {
      EXPECT_EQ(a.drops[i].center, b.drops[i].center);
      EXPECT_EQ(a.drops[i].footprint_radius, b.drops[i].footprint_radius);
      EXPECT_EQ(a.drops[i].contact_angle, b.drops[i].contact_angle);
      EXPECT_EQ(a.drops[i].elongation, b.drops[i].elongation);
      EXPECT_EQ(a.drops[i].flattening, b.drops[i].flattening);
    }
    EXPECT_EQ(a.glass.distance, b.glass.distance);
    EXPECT_EQ(a.glass.tilt, b.glass.tilt);
    EXPECT_EQ(a.background_distance_cm, b.background_distance_cm);
    EXPECT_EQ(a.f_number, b.f_number);
    EXPECT_EQ(a.focal_length_mm, b.focal_length_mm);
    EXPECT_FALSE(a.highlights.active());
    EXPECT_GE(b.highlights.gain, 4.0f);
    EXPECT_LE(b.highlights.gain, 16.0f);
  }
}

// Whole frames: a frame with nothing at the threshold renders byte for byte as without the
// effect (and says it was skipped); one with clipped pixels keeps its mask, coverage and every
// pixel no drop reaches, and its drops get brighter. Both the fast path and the aperture
// reference.
TEST(Highlights, FramesWithoutClippedPixelsSkipItAndOthersOnlyChangeWhereDropsAre) {
  const Camera cam = camera(192, 96, 212);
  const cv::Mat street = demo_street(cam.width, cam.height);
  cv::Mat dim;
  street.convertTo(dim, -1, 200.0 / 255.0);  // nothing above 200
  cv::Mat bright = street.clone();
  bright(cv::Rect(0, 0, cam.width, cam.height / 3)).setTo(cv::Scalar::all(255));  // a clipped sky
  for (DefocusMethod method : {DefocusMethod::Layered, DefocusMethod::Aperture}) {
    SceneConfig off = scene_preset("lens-cover");
    off.highlights.enabled = false;
    off.lens.method = method;
    off.lens.aperture_samples = 16;
    SceneConfig on = off;
    on.highlights.enabled = true;
    on.highlights.gain = {8, 8};
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
      Rng r1(seed), r2(seed);
      const SceneSample s_off = sample_scene(off, cam, r1), s_on = sample_scene(on, cam, r2);
      const std::string what = std::string(to_string(method)) + " seed " + std::to_string(seed);

      const RenderedFrame d0 = render_frame(dim, cam, off, s_off), d1 = render_frame(dim, cam, on, s_on);
      ASSERT_TRUE(d1.defocused) << what;
      EXPECT_FALSE(d1.highlights_lifted) << what;
      EXPECT_EQ(cv::norm(d0.rainy, d1.rainy, cv::NORM_INF), 0) << what;

      const RenderedFrame b0 = render_frame(bright, cam, off, s_off), b1 = render_frame(bright, cam, on, s_on);
      EXPECT_TRUE(b1.highlights_lifted) << what;
      EXPECT_EQ(cv::norm(b0.alpha, b1.alpha, cv::NORM_INF), 0) << what;
      EXPECT_EQ(cv::norm(b0.mask, b1.mask, cv::NORM_INF), 0) << what;
      const cv::Mat untouched = b1.alpha == 0;
      cv::Mat diff;
      cv::absdiff(b1.rainy, bright, diff);
      std::vector<cv::Mat> ch;
      cv::split(diff, ch);
      double outside = 0;
      cv::minMaxLoc(cv::max(cv::max(ch[0], ch[1]), ch[2]), nullptr, &outside, nullptr, nullptr, untouched);
      EXPECT_EQ(outside, 0) << what;
      // A pixel's brightest channel is nowhere darker (to a level of rounding): the light only
      // grew. (Its weaker channels may be a few levels darker: the camera's shoulder, restore(),
      // scales a mixed colour by its brightest channel, keeping its hue, so a lifted mix of a
      // clipped sky and a coloured drop is stored less saturated.) Brighter on average where the
      // drops are.
      auto brightest = [](const cv::Mat& rgb) {
        std::vector<cv::Mat> c;
        cv::split(rgb, c);
        cv::Mat m = cv::max(cv::max(c[0], c[1]), c[2]);
        m.convertTo(m, CV_16S);
        return m;
      };
      const cv::Mat darker = brightest(b0.rainy) - brightest(b1.rainy);
      double most_darker = 0;
      cv::minMaxLoc(darker, nullptr, &most_darker);
      EXPECT_LE(most_darker, 1) << what;
      const cv::Mat covered = b1.alpha > 0.01f;
      ASSERT_GT(cv::countNonZero(covered), 0) << what;
      EXPECT_GT(cv::mean(b1.rainy, covered)[0], cv::mean(b0.rainy, covered)[0] + 1) << what;
    }
  }
}

TEST(Highlights, SceneFilesParseRoundTripAndRefuseWhatCannotWork) {
  const char* with = R"({"camera": {}, "effects": {"highlights": {"threshold": 0.85, "gain": [2, 20]}}})";
  const SceneConfig c = parse_scene_json(with, "t");
  EXPECT_TRUE(c.highlights.enabled);
  EXPECT_DOUBLE_EQ(c.highlights.threshold, 0.85);
  EXPECT_DOUBLE_EQ(c.highlights.gain.lo, 2);
  EXPECT_DOUBLE_EQ(c.highlights.gain.hi, 20);
  const std::string text = scene_to_json(c);
  EXPECT_EQ(scene_to_json(parse_scene_json(text, "round trip")), text);
  const std::vector<std::string> names = c.effect_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "highlights"), names.end());
  EXPECT_FALSE(parse_scene_json(R"({"camera": {}})", "t").highlights.enabled);
  const std::pair<const char*, const char*> bad[] = {
      {R"({"effects": {"highlights": {}}})", "needs a 'camera'"},
      {R"({"camera": {}, "effects": {"highlights": {"gain": 0.5}}})", "'gain'"},
      {R"({"camera": {}, "effects": {"highlights": {"threshold": 1}}})", "'threshold'"},
      {R"({"camera": {}, "effects": {"highlights": {"threshold": 0.2}}})", "'threshold'"},
      {R"({"camera": {}, "effects": {"highlights": "auto"}})", "no \"auto\""},
      {R"({"camera": {}, "effects": {"highlights": {"lift": 2}}})", "unknown key 'lift'"},
  };
  for (const auto& [scene, needle] : bad) expect_scene_refused(scene, needle);
}

// The night preset on a dark street with lamps: every lamp a drop sees is lifted 16-64x, so
// the drops glow (brighter than without the lift, and than the street behind them) where the
// stored values would have made faint grey blobs; the lamps no drop covers stay as they were.
TEST(Highlights, TheNightPresetMakesLampsBehindDropsBloom) {
  const Camera cam = camera(384, 192, 424);
  cv::Mat night(cam.height, cam.width, CV_8UC3, cv::Scalar(10, 10, 14));
  for (int y = 20; y < 100; y += 10) {  // lit windows
    for (int x = 4; x < cam.width; x += 12) cv::rectangle(night, {x, y}, {x + 4, y + 5}, cv::Scalar(255, 220, 150), -1);
  }
  for (int x = 20; x < cam.width; x += 48) cv::circle(night, {x, 110}, 3, cv::Scalar::all(255), -1);  // street lamps
  for (int x = 40; x < cam.width; x += 96) cv::circle(night, {x, 140}, 2, cv::Scalar(255, 40, 40), -1);  // tail lights
  SceneConfig with = scene_preset("windshield-night"), without = with;
  ASSERT_TRUE(with.highlights.enabled);
  EXPECT_FALSE(with.sky.enabled);  // a dark sky above the frame
  without.highlights.enabled = false;
  double glow = 0, plain = 0, street = 0;
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    Rng r1(seed), r2(seed);
    const SceneSample s1 = sample_scene(with, cam, r1), s0 = sample_scene(without, cam, r2);
    EXPECT_GE(s1.highlights.gain, 16.0f);
    const RenderedFrame a = render_frame(night, cam, with, s1), b = render_frame(night, cam, without, s0);
    ASSERT_TRUE(a.highlights_lifted);
    const cv::Mat covered = a.alpha > 0.1f;
    ASSERT_GT(cv::countNonZero(covered), 0);
    glow += cv::mean(a.rainy, covered)[1] / 3;
    plain += cv::mean(b.rainy, covered)[1] / 3;
    street += cv::mean(night, covered)[1] / 3;
  }
  std::printf("night drops: %.1f levels with the lift, %.1f without, street behind them %.1f\n", glow, plain, street);
  EXPECT_GT(glow, plain + 10);
  EXPECT_GT(glow, street + 10);
}

// veil.h: the wet glass' veil. Closed forms: a uniform image is left as it is (the scattered
// light is redistributed, not lost), a pattern much finer than the lobe keeps (1 - s) of its
// contrast in linear light, the image's mean light is kept; the fast blur is held to the exact
// one, the skip rule to its half-level bound, and the lift to its glow.
#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"
#include "raindrop/render/scene_config.h"
#include "raindrop/render/srgb.h"
#include "raindrop/render/veil.h"
#include "support.h"

namespace raindrop {
namespace {

using test::expect_scene_refused;
using test::kDegToRad;

VeilSample veil_of(double s, double sigma_px) {
  VeilSample v;
  v.optical_depth = -std::log(1.0 - s);
  v.spread_deg = 1;  // recorded only; sigma_px is what the blur uses
  v.sigma_px = sigma_px;
  return v;
}

cv::Mat to_linear(const cv::Mat& rgb8) {
  const auto& table = srgb8_to_linear_table();
  cv::Mat out(rgb8.size(), CV_32FC3);
  for (int y = 0; y < rgb8.rows; ++y)
    for (int x = 0; x < 3 * rgb8.cols; ++x) out.ptr<float>(y)[x] = table[rgb8.ptr<unsigned char>(y)[x]];
  return out;
}

// A street-like test image: smooth gradients, hard edges, a few bright and dark blocks, and
// fine noise (seeded).
cv::Mat street_like(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> level(0, 255), pos(0, std::max(w, h));
  cv::Mat m(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      m.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<unsigned char>(40 + 150 * y / h),
                                        static_cast<unsigned char>(60 + 120 * x / w), 120);
  for (int i = 0; i < 25; ++i) {
    const cv::Point a(pos(rng) % w, pos(rng) % h), b(pos(rng) % w, pos(rng) % h);
    cv::rectangle(m, a, b, cv::Scalar(level(rng), level(rng), level(rng)), cv::FILLED);
  }
  cv::Mat noise(h, w, CV_8UC3);
  cv::randu(noise, 0, 12);
  cv::add(m, noise, m);
  return m;
}

TEST(Veil, LeavesAUniformImageAsItIs) {
  for (const int level : {0, 1, 37, 128, 254, 255}) {
    cv::Mat img(64, 96, CV_8UC3, cv::Scalar::all(level));
    const cv::Mat before = img.clone();
    apply_veil(img, veil_of(0.3, 20));
    EXPECT_EQ(cv::norm(img, before, cv::NORM_INF), 0) << "level " << level;
  }
}

TEST(Veil, FinePatternKeepsOneMinusSOfItsContrastInLinearLight) {
  // A 2-px checkerboard between two codes, sigma 24 px: the lobe averages it to its mean, so
  // each pixel moves (in linear light) to (1 - s) x + s mean.
  cv::Mat img(192, 256, CV_8UC3);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) img.at<cv::Vec3b>(y, x) = cv::Vec3b::all(((x + y) & 1) ? 230 : 40);
  const auto& table = srgb8_to_linear_table();
  const double hi = table[230], lo = table[40];
  for (const double s : {0.02, 0.1, 0.4}) {
    cv::Mat out = img.clone();
    apply_veil(out, veil_of(s, 24));
    const cv::Mat lin = to_linear(out);
    // Away from the borders, where the mirrored pattern is the pattern itself anyway.
    const double got_hi = lin.at<cv::Vec3f>(96, 129)[0], got_lo = lin.at<cv::Vec3f>(96, 128)[0];
    const double mean = 0.5 * (hi + lo);
    // Stored as 8 bits: within one code's width of the exact value.
    EXPECT_NEAR(got_hi, (1 - s) * hi + s * mean, 0.006) << "s " << s;
    EXPECT_NEAR(got_lo, (1 - s) * lo + s * mean, 0.0015) << "s " << s;
    EXPECT_NEAR((got_hi - got_lo) / (hi - lo), 1 - s, 0.01) << "s " << s;
  }
}

TEST(Veil, KeepsTheImageMeanLight) {
  const cv::Mat img = street_like(320, 160, 3);
  for (const double sigma : {3.0, 30.0}) {
    cv::Mat out = img.clone();
    apply_veil(out, veil_of(0.2, sigma));
    const double before = cv::mean(to_linear(img))[1], after = cv::mean(to_linear(out))[1];
    // Mirrored borders keep the mean only approximately; 1% of it.
    EXPECT_NEAR(after, before, 0.01 * before) << "sigma " << sigma;
    EXPECT_GT(cv::norm(out, img, cv::NORM_INF), 0) << "the veil changed nothing at sigma " << sigma;
  }
}

// The fast blur against the exact Gaussian, over random images, sizes, sigmas and fractions up
// to depth 1.5 (78% scattered): the tolerance the renderer holds every skipped or approximated
// effect to, RMSE under 0.5 and maximum under 4 levels of 8 bits.
TEST(Veil, FastBlurMatchesTheExactGaussian) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> sigma_of(8, 120), s_of(0.005, 0.78);
  double worst_rmse = 0, worst_max = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const int w = 128 + static_cast<int>(rng() % 300), h = 96 + static_cast<int>(rng() % 200);
    const cv::Mat img = street_like(w, h, static_cast<unsigned>(trial));
    const VeilSample v = veil_of(s_of(rng), sigma_of(rng));
    cv::Mat fast = img.clone(), exact = img.clone();
    apply_veil(fast, v, {}, VeilMethod::Fast);
    apply_veil(exact, v, {}, VeilMethod::Exact);
    cv::Mat diff;
    cv::absdiff(fast, exact, diff);
    diff.convertTo(diff, CV_64F);
    const cv::Mat sq = diff.mul(diff);
    const double rmse = std::sqrt(cv::mean(sq.reshape(1))[0]);
    double mx;
    cv::minMaxLoc(diff.reshape(1), nullptr, &mx);
    worst_rmse = std::max(worst_rmse, rmse);
    worst_max = std::max(worst_max, mx);
    EXPECT_LT(rmse, 0.3) << "trial " << trial << ": " << w << "x" << h << " sigma " << v.sigma_px << " s "
                         << v.scattered();
    EXPECT_LE(mx, 1) << "trial " << trial << ": " << w << "x" << h << " sigma " << v.sigma_px << " s "
                     << v.scattered();
  }
  // Frames a few cells wide (and a single pixel) under wide lobes: exact there, and quick.
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(2, 3), cv::Size(7, 1), cv::Size(3, 1000)}) {
    const cv::Mat img = street_like(std::max(size.width, 2), std::max(size.height, 2), 5)(cv::Rect(0, 0, size.width, size.height)).clone();
    cv::Mat fast = img.clone(), exact = img.clone();
    apply_veil(fast, veil_of(0.3, 300), {}, VeilMethod::Fast);
    apply_veil(exact, veil_of(0.3, 300), {}, VeilMethod::Exact);
    EXPECT_EQ(cv::norm(fast, exact, cv::NORM_INF), 0) << size;
  }
  std::cout << "veil fast vs exact over 24 images: worst RMSE " << worst_rmse << ", worst max " << worst_max
            << " levels\n";
}

TEST(Veil, SkippedOnlyWhereNoPixelCanMoveHalfALevel) {
  // The worst case for the bound: black beside white, where the blur differs from the pixel by
  // nearly full scale, and the black side sits on the sRGB curve's steepest part.
  cv::Mat img(64, 128, CV_8UC3, cv::Scalar::all(0));
  img(cv::Rect(64, 0, 64, 64)).setTo(cv::Scalar::all(255));
  const VeilSample below = veil_of(0.99 * kVeilSkipFraction, 8);
  const VeilSample at = veil_of(1.01 * kVeilSkipFraction, 8);
  EXPECT_FALSE(below.visible());
  EXPECT_TRUE(at.visible());
  cv::Mat skipped = img.clone();
  apply_veil(skipped, below);
  EXPECT_EQ(cv::norm(skipped, img, cv::NORM_INF), 0) << "a skipped veil changed the image";
  // The bound itself: the largest change the mix can make at that fraction, in 8-bit codes.
  const cv::Mat lin = to_linear(img);
  const cv::Mat blurred = veil_blur(lin, 8, VeilMethod::Exact);
  double worst = 0;
  const double s = below.scattered();
  for (int y = 0; y < lin.rows; ++y)
    for (int x = 0; x < lin.cols; ++x) {
      const double a = lin.at<cv::Vec3f>(y, x)[0], b = blurred.at<cv::Vec3f>(y, x)[0];
      worst = std::max(worst, 255.0 * std::abs(linear_to_srgb((1 - s) * a + s * b) - linear_to_srgb(a)));
    }
  EXPECT_LT(worst, 0.5) << "the skip bound does not hold";
  EXPECT_GT(worst, 0.1) << "the test image does not come near the bound";
  // Where the highlights' lift ran, lifted light reaches the gain, and so does the bound.
  HighlightLift lift;
  lift.threshold = 0.9f;
  lift.gain = 16.0f;
  EXPECT_TRUE(below.visible(lift)) << "a lifted frame was skipped by the unlifted bound";
  EXPECT_FALSE(veil_of(0.99 * kVeilSkipFraction / 16, 8).visible(lift));
  // Above the bound the same image does change.
  cv::Mat applied = img.clone();
  apply_veil(applied, veil_of(0.01, 8));
  EXPECT_GT(cv::norm(applied, img, cv::NORM_INF), 0);
}

TEST(Veil, LiftedHighlightsGlowByTheGain) {
  // A clipped lamp on a dark street: with the lift, the lamp's scattered light is `gain` times
  // what its stored 255 says, so the glow around it is about `gain` times brighter (in linear
  // light, minus the dark street's own share).
  cv::Mat img(128, 128, CV_8UC3, cv::Scalar::all(10));
  img(cv::Rect(56, 56, 16, 16)).setTo(cv::Scalar::all(255));
  HighlightLift lift;
  lift.threshold = 0.9f;
  lift.gain = 8.0f;
  cv::Mat plain = img.clone(), lifted = img.clone();
  const VeilSample v = veil_of(0.1, 12);
  apply_veil(plain, v);
  apply_veil(lifted, v, lift);
  // The lamp's weight w in the glow at the probe, from the exact blur of the lamp alone.
  cv::Mat lamp(img.size(), CV_32FC3, cv::Scalar::all(0));
  lamp(cv::Rect(56, 56, 16, 16)).setTo(cv::Scalar::all(1));
  const double w = veil_blur(lamp, 12, VeilMethod::Exact).at<cv::Vec3f>(64, 90)[0];
  const auto& table = srgb8_to_linear_table();
  const double street = table[10], s = v.scattered();
  const double glow_plain = table[plain.at<cv::Vec3b>(64, 90)[0]] - (1 - s) * street;
  const double glow_lifted = table[lifted.at<cv::Vec3b>(64, 90)[0]] - (1 - s) * street;
  const double expected = (street * (1 - w) + 8.0 * w) / (street * (1 - w) + w);
  ASSERT_GT(glow_plain, 0);
  EXPECT_GT(expected, 5.0) << "the probe is too far from the lamp to tell";
  // 8-bit storage of a dark pixel costs a few percent of these small values.
  EXPECT_NEAR(glow_lifted / glow_plain, expected, 0.1 * expected) << "glow " << glow_plain << " -> " << glow_lifted;
  // The lamp itself stays at full scale.
  EXPECT_EQ(lifted.at<cv::Vec3b>(64, 64)[0], 255);
}

TEST(Veil, DrawIsPerSampleAndInTheSceneRange) {
  SceneConfig config = scene_preset("paper");
  config.veil.enabled = true;
  config.veil.optical_depth = {0.01, 0.05};
  config.veil.spread_deg = {2, 10};
  const double fx = 565.5;
  double lo = 1, hi = 0;
  for (std::uint64_t seed = 1; seed <= 200; ++seed) {
    const VeilSample a = sample_veil(config, fx, seed), b = sample_veil(config, fx, seed);
    EXPECT_EQ(a.optical_depth, b.optical_depth);
    EXPECT_EQ(a.spread_deg, b.spread_deg);
    EXPECT_GE(a.optical_depth, 0.01);
    EXPECT_LE(a.optical_depth, 0.05);
    EXPECT_GE(a.spread_deg, 2);
    EXPECT_LE(a.spread_deg, 10);
    EXPECT_NEAR(a.sigma_px, fx * std::tan(a.spread_deg * kDegToRad), 1e-9);
    lo = std::min(lo, a.optical_depth);
    hi = std::max(hi, a.optical_depth);
  }
  EXPECT_LT(lo, 0.015);
  EXPECT_GT(hi, 0.045);
  config.veil.enabled = false;
  EXPECT_FALSE(sample_veil(config, fx, 7).visible());
}

TEST(Veil, SceneFileReadsAndPrintsIt) {
  const std::string text = R"({"effects": {"veil": {"optical_depth": [0.01, 0.04], "spread_deg": [3, 6]}}})";
  const SceneConfig c = parse_scene_json(text, "veil.json");
  EXPECT_TRUE(c.veil.enabled);
  EXPECT_EQ(c.veil.optical_depth.hi, 0.04);
  EXPECT_EQ(c.veil.spread_deg.lo, 3);
  const SceneConfig again = parse_scene_json(scene_to_json(c), "printed");
  EXPECT_TRUE(again.veil.enabled);
  EXPECT_EQ(scene_to_json(again), scene_to_json(c));
  bool named = false;
  for (const auto& n : c.effect_names()) named |= n == "veil";
  EXPECT_TRUE(named);
  expect_scene_refused(R"({"effects": {"veil": {"optical_depth": [0, 5]}}})", "optical_depth");
  expect_scene_refused(R"({"effects": {"veil": {"spread_deg": [0, 5]}}})", "spread_deg");
  expect_scene_refused(R"({"effects": {"veil": {"thickness": 1}}})", "thickness");
  expect_scene_refused(R"({"effects": {"veil": "auto"}})", "veil");
}

}  // namespace
}  // namespace raindrop

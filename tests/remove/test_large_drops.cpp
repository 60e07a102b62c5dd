// The coarse pass for large drops (raindrop/remove/large_drops.h): which parts of a mask count
// as large, when the pass runs, and that it replaces exactly those parts with the coarse copy's
// result, upsampled, leaving everything else as the working-scale pass made it.
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"
#include "raindrop/remove/large_drops.h"
#include "raindrop/remove/remover.h"
#include "remove_test_util.h"
#include "smoke_remover.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

Remover& smoke() { return smoke_remover(); }

// The tests of the coarse pass's mechanics use textured street images, which the sharpness rule
// (large_drops.h) would keep from the pass: they lift it. The rule has its own tests below.
constexpr double kNoLimit = std::numeric_limits<double>::infinity();

// What `remover` makes of `img` at `coarse_scale` with every pixel a drop, brought back to
// full size as the coarse pass does (its 3RN and RFN averaged with the mirror image's, the
// result smoothed by kLargeDropSmoothing, then bilinear), as 8-bit.
cv::Mat coarse_result_upsampled(Remover& remover, const cv::Mat& img, double coarse_scale) {
  cv::Mat small, expected, expected8;
  cv::resize(img, small, scaled_size(img.size(), coarse_scale), 0, 0, cv::INTER_AREA);
  RemoveOptions native;
  native.threshold = -1.0;  // P > -1 always
  native.scale = 1.0;
  native.keep_float = true;
  native.large_drops = false;
  native.mirror_average = kLargeDropMirrorAverage;
  const RemoveResult s = remover.run(small, native);
  cv::Mat smoothed;
  cv::GaussianBlur(s.rgb, smoothed, cv::Size(0, 0), kLargeDropSmoothing, kLargeDropSmoothing, cv::BORDER_REPLICATE);
  cv::resize(smoothed, expected, img.size(), 0, 0, cv::INTER_LINEAR);
  expected.convertTo(expected8, CV_8U, 255.0);
  return expected8;
}

TEST(LargeDrops, PartsAtLeastTheDiameterAcrossAreLarge) {
  cv::Mat mask(120, 200, CV_8U, cv::Scalar(0));
  // Filled disks of diameter 17 and 23 px (area ~227 and ~415 against pi * 10^2 ~ 314), and a
  // ring 40 px across: its area (a thin band) decides, not its outline.
  cv::circle(mask, {30, 30}, 8, cv::Scalar(255), cv::FILLED);
  cv::circle(mask, {80, 30}, 11, cv::Scalar(255), cv::FILLED);
  cv::circle(mask, {150, 60}, 20, cv::Scalar(255), 1);
  int count = -1;
  const cv::Mat large = large_drop_mask(mask, &count);
  EXPECT_EQ(count, 1);
  EXPECT_EQ(large.at<unsigned char>(30, 30), 0);
  EXPECT_EQ(large.at<unsigned char>(30, 80), 255);
  EXPECT_EQ(cv::countNonZero(large), cv::countNonZero(mask(cv::Rect(60, 10, 40, 40))));
  EXPECT_EQ(large.at<unsigned char>(60, 170), 0);
}

TEST(LargeDrops, TheCoarseCopyMustHoldALargeDrop) {
  EXPECT_TRUE(coarse_pass_fits({2 * kLargeDropDiameter, 2 * kLargeDropDiameter}));
  EXPECT_FALSE(coarse_pass_fits({2 * kLargeDropDiameter - 1, 500}));
  EXPECT_FALSE(coarse_pass_fits({500, 2 * kLargeDropDiameter - 1}));
  // A 64x64 image: a copy at a third is 21 px, too small; the pass does not run.
  RemoveOptions o;
  const RemoveResult r = smoke().run(make_image(64, 64, 5), o);
  EXPECT_EQ(r.coarse_scale, 0.0);
  EXPECT_EQ(r.large_drops, 0);
}

// No large drop found: the result is the working-scale pass's, bit for bit.
TEST(LargeDrops, NoLargeDropLeavesTheResultAsItWas) {
  const cv::Mat img = make_image(600, 300, 6);
  RemoveOptions none;
  none.threshold = 1.0;  // P > 1 never: empty masks
  const RemoveResult with = smoke().run(img, none);
  RemoveOptions off = none;
  off.large_drops = false;
  const RemoveResult without = smoke().run(img, off);
  EXPECT_DOUBLE_EQ(with.coarse_scale, with.scale / 3.0);
  EXPECT_EQ(with.large_drops, 0);
  EXPECT_EQ(max_abs_diff(with.image, without.image), 0);
  EXPECT_EQ(cv::countNonZero(with.mask != without.mask), 0);
  // The coarse copy's detector ran; its 3RN and RFN did not (nothing to replace).
  EXPECT_GT(with.network_pixels, without.network_pixels);
  EXPECT_EQ(with.reconstructed_pixels, without.reconstructed_pixels);
  EXPECT_EQ(without.reconstructed_pixels, without.network_pixels);
}

// A mask over everything is one large drop: the output is the coarse copy's result upsampled.
TEST(LargeDrops, AFullMaskIsTheCoarseCopysResultUpsampled) {
  const cv::Mat img = make_image(600, 300, 7);
  RemoveOptions all;
  all.threshold = -1.0;  // P > -1 always
  all.large_drop_max_sharpness = kNoLimit;
  const RemoveResult r = smoke().run(img, all);
  ASSERT_EQ(r.large_drops, 1);
  // Both passes ran whole, the coarse one's 3RN and RFN twice (mirror averaging).
  RemoveOptions fine_only = all;
  fine_only.large_drops = false;
  const double fine = smoke().run(img, fine_only).network_pixels;
  EXPECT_EQ(r.reconstructed_pixels, fine + (kLargeDropMirrorAverage ? 2 : 1) * (r.network_pixels - fine));
  const double coarse_scale = r.scale / kLargeDropScaleDivisor;
  EXPECT_DOUBLE_EQ(r.coarse_scale, coarse_scale);
  EXPECT_EQ(cv::countNonZero(r.mask), static_cast<int>(r.mask.total()));
  // With the input's detail given back (large_drops.h: add_input_detail): the fill plus half the
  // input's high frequencies, at kLargeDropDetailSigma pixels of the working scale.
  ASSERT_EQ(all.large_drop_detail, kLargeDropDetail);
  cv::Mat fill, in, blurred;
  coarse_result_upsampled(smoke(), img, coarse_scale).convertTo(fill, CV_32F, 1.0 / 255.0);
  img.convertTo(in, CV_32F, 1.0 / 255.0);
  cv::GaussianBlur(in, blurred, cv::Size(0, 0), kLargeDropDetailSigma / r.scale, kLargeDropDetailSigma / r.scale,
                   cv::BORDER_REPLICATE);
  cv::Mat expected = fill + kLargeDropDetail * (in - blurred), expected8;
  expected.convertTo(expected8, CV_8U, 255.0);
  EXPECT_LE(max_abs_diff(r.image, expected8), 2);
  EXPECT_GT(max_abs_diff(r.image, coarse_result_upsampled(smoke(), img, coarse_scale)), 10) << "no detail came back";
  // And without it, the fill alone.
  RemoveOptions fill_alone = all;
  fill_alone.large_drop_detail = 0.0;
  EXPECT_LE(max_abs_diff(smoke().run(img, fill_alone).image, coarse_result_upsampled(smoke(), img, coarse_scale)), 1);
}

// add_input_detail alone: half the input's high frequencies added where the upsampled weight is
// 1, in proportion where it is between 0 and 1, and the result's own bytes (alpha included)
// where it is 0; gain 0 changes nothing. A grey+alpha 16-bit image, so that the float round
// trip and the alpha copy are both exercised.
TEST(LargeDrops, TheInputsDetailComesBackWhereTheFillWentOnly) {
  const int w = 240, h = 150;
  cv::Mat texture(h, w, CV_32F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      texture.at<float>(y, x) = 0.5f + 0.2f * std::sin(0.9f * x) * std::cos(0.7f * y) + 0.001f * x;
  cv::Mat grey16, alpha16(h, w, CV_16U), input;
  texture.convertTo(grey16, CV_16U, 65535.0);
  cv::randu(alpha16, 0, 65536);
  cv::merge(std::vector<cv::Mat>{grey16, alpha16}, input);
  cv::Mat result(h, w, CV_16UC2, cv::Scalar(30000, 0));  // a flat fill, alpha 0
  cv::Mat weight_small(50, 80, CV_32F, cv::Scalar(0));    // a third of the size: a block of 1s
  weight_small(cv::Rect(20, 15, 30, 20)).setTo(1.0f);
  const double sigma = 4.0;
  cv::Mat unchanged = result.clone();
  add_input_detail(input, weight_small, sigma, 0.0, unchanged);
  EXPECT_EQ(cv::countNonZero(cv::Mat(unchanged != result).reshape(1)), 0);
  cv::Mat out = result.clone();
  add_input_detail(input, weight_small, sigma, 0.5, out);
  cv::Mat weight, blurred;
  cv::resize(weight_small, weight, input.size(), 0, 0, cv::INTER_LINEAR);
  cv::GaussianBlur(texture, blurred, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
  int inside = 0, outside = 0, partial = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float a = weight.at<float>(y, x);
      const cv::Vec2w o = out.at<cv::Vec2w>(y, x), r = result.at<cv::Vec2w>(y, x);
      if (a <= 0.0f) {
        ++outside;
        ASSERT_EQ(o, r) << "at " << x << "," << y;
        continue;
      }
      inside += a >= 1.0f;
      partial += a < 1.0f;
      const double want = 30000.0 / 65535.0 + 0.5 * a * (texture.at<float>(y, x) - blurred.at<float>(y, x));
      ASSERT_NEAR(o[0] / 65535.0, want, 2e-3) << "at " << x << "," << y << ", weight " << a;
      ASSERT_EQ(o[1], r[1]) << "alpha at " << x << "," << y;
    }
  }
  EXPECT_GT(inside, 4000);
  EXPECT_GT(partial, 300);
  EXPECT_GT(outside, 15000);
}

// A wide blur (sigma 8 and more: large photographs) is computed on a reduced copy
// (detail_blur_reduction): on a texture of 40-pixel waves, which that copy (5 times smaller)
// holds as 8-pixel ones, the detail given back where the weight is 1 is the exact high-pass's
// within 0.03 of its 0.1: area-averaging and bilinear upsampling soften such waves by about a
// fifth (0.021 measured); leaving the detail out misses by 0.1.
TEST(LargeDrops, AWideBlursDetailIsTheExactOnesForWhatTheCopyHolds) {
  EXPECT_EQ(detail_blur_reduction(7.9), 1);
  EXPECT_EQ(detail_blur_reduction(8.0), 2);
  EXPECT_EQ(detail_blur_reduction(23.4), 5);
  const int w = 600, h = 450;
  const double sigma = 20.0;
  cv::Mat texture(h, w, CV_32FC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float v = 0.5f + 0.2f * static_cast<float>(std::sin(2 * M_PI * x / 40.0) * std::cos(2 * M_PI * y / 40.0));
      texture.at<cv::Vec3f>(y, x) = cv::Vec3f(v, v, v);
    }
  cv::Mat input;
  texture.convertTo(input, CV_8UC3, 255.0);
  cv::Mat in, blurred;
  input.convertTo(in, CV_32FC3, 1.0 / 255.0);
  cv::GaussianBlur(in, blurred, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
  cv::Mat result(h, w, CV_8UC3, cv::Scalar::all(128));
  cv::Mat weight_small(150, 200, CV_32F, cv::Scalar(0));
  weight_small(cv::Rect(50, 40, 100, 70)).setTo(1.0f);
  add_input_detail(input, weight_small, sigma, 0.5, result);
  double worst = 0, largest = 0;
  for (int y = 150; y < 300; ++y)
    for (int x = 180; x < 420; ++x) {
      const double want = 128.0 / 255.0 + 0.5 * (in.at<cv::Vec3f>(y, x)[1] - blurred.at<cv::Vec3f>(y, x)[1]);
      worst = std::max(worst, std::abs(result.at<cv::Vec3b>(y, x)[1] / 255.0 - want));
      largest = std::max(largest, std::abs(want - 128.0 / 255.0));
    }
  EXPECT_GT(largest, 0.08) << "the texture's detail is too faint to test";
  EXPECT_LT(worst, 0.03);
}

// With two threads the coarse pass runs beside the working-scale pass (it reads only the
// input); with one, after it. The result must not depend on that: the same large drops, mask
// and pixel counts, and the image equal up to the rounding of RFN's thread split (as
// Remover.SideBySideEqualsInOrder holds for RDN and 3RN).
TEST(LargeDrops, BesideTheWorkingPassEqualsInOrder) {
  SessionConfig one, two;
  one.threads = 1;
  two.threads = 2;
  Remover in_order(smoke_models(), one), beside(smoke_models(), two);
  const cv::Mat img = make_image(600, 300, 7);
  RemoveOptions all;
  all.threshold = -1.0;  // every pixel a drop: both passes run every network
  all.large_drop_max_sharpness = kNoLimit;
  RemoveOptions found;    // the models' threshold: the coarse pass may stop after its detector
  found.large_drop_max_sharpness = kNoLimit;
  for (const RemoveOptions& o : {all, found}) {
    const RemoveResult a = in_order.run(img, o), b = beside.run(img, o);
    EXPECT_EQ(a.large_drops, b.large_drops);
    EXPECT_EQ(a.sharp_large_drops, b.sharp_large_drops);
    EXPECT_DOUBLE_EQ(a.coarse_scale, b.coarse_scale);
    EXPECT_DOUBLE_EQ(a.network_pixels, b.network_pixels);
    EXPECT_DOUBLE_EQ(a.reconstructed_pixels, b.reconstructed_pixels);
    EXPECT_EQ(cv::countNonZero(a.mask != b.mask), 0);
    EXPECT_LE(max_abs_diff(a.image, b.image), 1);
  }
  EXPECT_EQ(in_order.run(img, all).large_drops, 1);
}

// The coarse pass keeps what the working-scale pass keeps: size, channels, depth, alpha.
TEST(LargeDrops, FormatsAreKept) {
  const cv::Mat rgb = make_image(300, 150, 8);
  cv::Mat grey, rgba16, alpha(rgb.size(), CV_8U);
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  cv::randu(alpha, 0, 256);
  cv::Mat rgba;
  cv::merge(std::vector<cv::Mat>{rgb, alpha}, rgba);
  rgba.convertTo(rgba16, CV_16U, 257.0);
  RemoveOptions all;
  all.threshold = -1.0;  // one mask over everything: the coarse pass takes it all
  all.large_drop_max_sharpness = kNoLimit;
  for (const cv::Mat& img : {grey, rgba16}) {
    const RemoveResult r = smoke().run(img, all);
    ASSERT_EQ(r.large_drops, 1);
    EXPECT_EQ(r.image.size(), img.size());
    EXPECT_EQ(r.image.type(), img.type());
    if (img.channels() == 4) {
      std::vector<cv::Mat> in_planes, out_planes;
      cv::split(img, in_planes);
      cv::split(r.image, out_planes);
      EXPECT_EQ(cv::countNonZero(in_planes[3] != out_planes[3]), 0) << "alpha must be copied through";
    }
  }
}

// Where the coarse pass finds a large drop in part of the image only, every pixel out of reach of
// its upsampled mask (and of the working-scale mask) is the working-scale pass's, bit for bit:
// the coarse result, smoothing included, reaches no further than its drops. Two flat halves give
// the untrained fixture detector two flat probability levels; a threshold between them makes one
// half a drop.
TEST(LargeDrops, PixelsAwayFromLargeDropsAreTheWorkingScalePasss) {
  cv::Mat img(300, 600, CV_8UC3, cv::Scalar(40, 60, 50));
  img(cv::Rect(300, 0, 300, 300)).setTo(cv::Scalar(210, 200, 190));
  bool found = false;
  for (int i = 1; i < 100 && !found; ++i) {
    RemoveOptions on;
    on.threshold = i / 100.0;
    const RemoveResult with = smoke().run(img, on);
    const double covered = cv::countNonZero(with.mask) / static_cast<double>(with.mask.total());
    if (with.large_drops == 0 || covered < 0.2 || covered > 0.8) continue;
    found = true;
    RemoveOptions off = on;
    off.large_drops = false;
    const RemoveResult without = smoke().run(img, off);
    // Out of reach: more than two coarse pixels (bilinear upsampling's support) from any pixel
    // of the written mask, the union of both passes' masks.
    const int reach = static_cast<int>(std::ceil(2.0 / with.coarse_scale)) + 1;
    cv::Mat near;
    cv::dilate(with.mask, near, cv::getStructuringElement(cv::MORPH_RECT, {2 * reach + 1, 2 * reach + 1}));
    const cv::Mat far = near == 0;
    ASSERT_GT(cv::countNonZero(far), 1000) << "threshold " << *on.threshold << ": nothing out of reach to compare";
    cv::Mat diff, channels[3];
    cv::absdiff(with.image, without.image, diff);
    cv::split(diff, channels);
    const cv::Mat largest = cv::max(cv::max(channels[0], channels[1]), channels[2]);
    double worst = 0;
    cv::Point at;
    cv::minMaxLoc(largest, nullptr, &worst, nullptr, &at, far);
    EXPECT_EQ(worst, 0.0) << "threshold " << *on.threshold << ", covered " << covered << ", at " << at
                          << ", reach " << reach;
  }
  ASSERT_TRUE(found) << "no threshold made part of the image a large drop";
}

// The large-drop growth (RemoveOptions::large_drop_growth) dilates each drop of the coarse pass's
// mask by its own size: the written mask holds the one without it and reaches further, while the
// working-scale pass (no coarse pass) is the same with any growth. The two flat halves of the test
// above, at the first threshold that makes one half a large drop.
TEST(LargeDrops, TheirMasksGrowWithThem) {
  cv::Mat img(300, 600, CV_8UC3, cv::Scalar(40, 60, 50));
  img(cv::Rect(300, 0, 300, 300)).setTo(cv::Scalar(210, 200, 190));
  for (int i = 1; i < 100; ++i) {
    RemoveOptions without;
    without.threshold = i / 100.0;
    without.large_drop_growth = 0.0;
    const RemoveResult a = smoke().run(img, without);
    const double covered = cv::countNonZero(a.mask) / static_cast<double>(a.mask.total());
    if (a.large_drops == 0 || covered < 0.2 || covered > 0.8) continue;
    RemoveOptions with = without;
    with.large_drop_growth = 0.5;
    const RemoveResult b = smoke().run(img, with);
    EXPECT_EQ(b.large_drops, a.large_drops);
    EXPECT_EQ(cv::countNonZero(a.mask > b.mask), 0) << "the growth took mask pixels away";
    EXPECT_GT(cv::countNonZero(b.mask > a.mask), 1000) << "a half-image drop's mask did not grow";
    RemoveOptions fine = with;
    fine.large_drops = false;
    RemoveOptions fine0 = without;
    fine0.large_drops = false;
    EXPECT_EQ(max_abs_diff(smoke().run(img, fine).image, smoke().run(img, fine0).image), 0)
        << "the growth reached the working-scale pass";
    with.large_drop_growth = 11.0;
    EXPECT_THROW(smoke().run(img, with), raindrop::Error);
    EXPECT_THROW(smoke().run(make_image(40, 30, 1), with), raindrop::Error) << "checked before the coarse pass is ruled out";
    return;
  }
  FAIL() << "no threshold made part of the image a large drop";
}

// Mirror averaging (the coarse pass's, and --mirror-average's): the mean of the network's output
// and of its output on the mirror image mirrored back, for every input and channel count; so
// exactly mirror-equivariant, which the network alone is not.
TEST(LargeDrops, MirrorAveragingIsTheMeanOfBothViews) {
  Models models(smoke_models(), {});
  const int h = 24, w = 37;  // odd width: the mirror has no fixed column pair
  cv::Mat r(3 * h, w, CV_32F), e(h, w, CV_32F);
  cv::randu(r, 0.0f, 1.0f);
  cv::randu(e, 0.0f, 2.0f);
  auto mirror = [](const cv::Mat& planes) {
    cv::Mat m;
    cv::flip(planes, m, 1);
    return m;
  };
  auto run = [&](const cv::Mat& rr, const cv::Mat& ee, bool averaged) {
    cv::Mat out(3 * h, w, CV_32F);
    if (averaged) {
      run_mirror_averaged(models.rrn(), {rr.ptr<float>(), ee.ptr<float>()}, {3, 1}, h, w, 3, out.ptr<float>());
    } else {
      models.rrn().run({rr.ptr<float>(), ee.ptr<float>()}, h, w, out.ptr<float>());
    }
    return out;
  };
  const cv::Mat rm = mirror(r), em = mirror(e);  // flipping the stacked planes flips each plane
  const cv::Mat direct = run(r, e, false), other = mirror(run(rm, em, false));
  const cv::Mat averaged = run(r, e, true);
  EXPECT_LE(cv::norm(averaged, 0.5f * (direct + other), cv::NORM_INF), 1e-6);
  EXPECT_EQ(cv::norm(run(rm, em, true), mirror(averaged), cv::NORM_INF), 0.0) << "not exactly mirror-equivariant";
  EXPECT_GT(cv::norm(direct, other, cv::NORM_INF), 1e-3) << "the network is mirror-equivariant: the test cannot fail";
}

// sharpness_map (large_drops.h) against closed forms: nothing on a flat image, 2a on a luma
// a x^2 (the discrete Laplacian of a quadratic is exact), 4 x 255 inside a black and white
// checkerboard; the luma weights sum to one, so a grey image, its RGB copy and its 16-bit and
// float copies agree.
TEST(LargeDrops, SharpnessIsTheLaplacianOfTheLuma) {
  const cv::Mat flat(40, 60, CV_8UC3, cv::Scalar(90, 140, 30));
  EXPECT_EQ(cv::norm(sharpness_map(flat), cv::NORM_INF), 0.0);

  const double a = 0.01;
  cv::Mat quadratic(30, 100, CV_32FC3);
  for (int y = 0; y < quadratic.rows; ++y)
    for (int x = 0; x < quadratic.cols; ++x) quadratic.at<cv::Vec3f>(y, x) = cv::Vec3f::all(float(a * x * x / 255.0));
  const cv::Mat q = sharpness_map(quadratic);
  ASSERT_EQ(q.size(), quadratic.size());
  ASSERT_EQ(q.type(), CV_32FC1);
  for (int x = 1; x < quadratic.cols - 1; ++x) EXPECT_NEAR(q.at<float>(15, x), 2 * a, 1e-3) << "x " << x;

  cv::Mat board(20, 20, CV_8UC1);
  for (int y = 0; y < board.rows; ++y)
    for (int x = 0; x < board.cols; ++x) board.at<unsigned char>(y, x) = (x + y) % 2 ? 255 : 0;
  const cv::Mat b = sharpness_map(board);
  for (int y = 1; y < board.rows - 1; ++y)
    for (int x = 1; x < board.cols - 1; ++x) EXPECT_FLOAT_EQ(b.at<float>(y, x), 4 * 255.0f);

  // One channel at a time (R, G, B in that order): the Laplacian of that channel's weight times
  // its quadratic. An RGBA copy with random alpha gives the same map: alpha is not luma.
  const double weights[3] = {0.299, 0.587, 0.114};
  for (int c = 0; c < 3; ++c) {
    cv::Mat one(30, 100, CV_32FC3, cv::Scalar(0, 0, 0));
    for (int y = 0; y < one.rows; ++y)
      for (int x = 0; x < one.cols; ++x) one.at<cv::Vec3f>(y, x)[c] = float(a * x * x / 255.0);
    const cv::Mat m = sharpness_map(one);
    for (int x = 1; x < one.cols - 1; ++x) EXPECT_NEAR(m.at<float>(15, x), 2 * a * weights[c], 1e-3) << "channel " << c;
    cv::Mat alpha(one.size(), CV_32F), rgba;
    cv::randu(alpha, 0.0f, 1.0f);
    cv::merge(std::vector<cv::Mat>{one, alpha}, rgba);
    EXPECT_EQ(cv::norm(sharpness_map(rgba), m, cv::NORM_INF), 0.0) << "channel " << c;
  }

  // Rows are done in bands; across their edges (an image 200 rows tall) the map is the one
  // computed on the whole image at once.
  const cv::Mat tall = make_image(90, 200, 15);
  cv::Mat tall_f, luma(tall.size(), CV_32F), whole;
  tall.convertTo(tall_f, CV_32F, 1.0 / 255.0);
  for (int y = 0; y < tall.rows; ++y)
    for (int x = 0; x < tall.cols; ++x) {
      const cv::Vec3f p = tall_f.at<cv::Vec3f>(y, x);
      luma.at<float>(y, x) = 255.0f * (0.299f * p[0] + 0.587f * p[1] + 0.114f * p[2]);
    }
  cv::Laplacian(luma, whole, CV_32F, 1, 1.0, 0.0, cv::BORDER_REPLICATE);
  EXPECT_LT(cv::norm(sharpness_map(tall), cv::abs(whole), cv::NORM_INF), 1e-3);

  const cv::Mat grey = make_image(64, 48, 12);
  cv::Mat grey8, rgb8, rgb16, rgbf;
  cv::cvtColor(grey, grey8, cv::COLOR_RGB2GRAY);
  cv::cvtColor(grey8, rgb8, cv::COLOR_GRAY2RGB);
  rgb8.convertTo(rgb16, CV_16U, 257.0);
  rgb8.convertTo(rgbf, CV_32F, 1.0 / 255.0);
  const cv::Mat s = sharpness_map(grey8);
  EXPECT_GT(cv::mean(s)[0], 1.0) << "a textured image: the comparisons below cannot fail otherwise";
  for (const cv::Mat& other : {rgb8, rgb16, rgbf}) EXPECT_LT(cv::norm(sharpness_map(other), s, cv::NORM_INF), 1e-2);
}

// smooth_large_drops keeps the parts whose mean sharpness, over the finer pixels under them, is
// at most the limit (a part exactly at it stays), and says how many.
TEST(LargeDrops, OnlySmoothPartsStay) {
  cv::Mat large(60, 90, CV_8U, cv::Scalar(0));
  cv::circle(large, {20, 30}, 12, cv::Scalar(255), cv::FILLED);
  cv::circle(large, {65, 30}, 12, cv::Scalar(255), cv::FILLED);
  // The sharpness on a grid three times finer: 10 levels under the left part, and under the
  // right one 12 on every other column and 0 between (a mean of 6, a maximum of 12).
  cv::Mat sharp(180, 270, CV_32F, cv::Scalar(0));
  sharp(cv::Rect(0, 0, 126, 180)).setTo(10.0f);
  for (int x = 136; x < 270; x += 2) sharp.col(x).setTo(12.0f);
  int count = -1;
  cv::Mat kept = smooth_large_drops(large, sharp, 7.0, &count);
  EXPECT_EQ(count, 1);
  EXPECT_EQ(cv::countNonZero(kept(cv::Rect(0, 0, 45, 60))), 0) << "the left part is sharp";
  EXPECT_EQ(cv::countNonZero(kept(cv::Rect(45, 0, 45, 60))), cv::countNonZero(large(cv::Rect(45, 0, 45, 60))))
      << "the right part is smooth on average";
  kept = smooth_large_drops(large, sharp, 10.0, &count);
  EXPECT_EQ(count, 2) << "a part exactly at the limit stays";
  EXPECT_EQ(cv::countNonZero(kept != large), 0);
  kept = smooth_large_drops(large, sharp, 5.9, &count);
  EXPECT_EQ(count, 0);
  EXPECT_EQ(cv::countNonZero(kept), 0);
}

// In the pipeline: a sharp image under a mask over everything is no large drop (the
// working-scale pass's result, bit for bit); the same image blurred is one. The limit is
// compared with the working-scale image's own sharpness, on either side of it.
TEST(LargeDrops, SharpRegionsAreLeftToTheWorkingScalePass) {
  cv::Mat sharp = make_image(600, 300, 13);
  cv::Mat grain(sharp.size(), CV_8UC3);
  cv::randu(grain, 0, 48);  // fine texture everywhere: sharp at any scale
  sharp += grain;
  cv::Mat smooth;
  cv::GaussianBlur(sharp, smooth, cv::Size(0, 0), 6.0);
  RemoveOptions all;
  all.threshold = -1.0;  // one mask over everything
  RemoveOptions fine_only = all;
  fine_only.large_drops = false;
  const RemoveResult r = smoke().run(sharp, all);
  cv::Mat working;
  cv::resize(sharp, working, scaled_size(sharp.size(), r.scale), 0, 0, cv::INTER_AREA);
  const double mean_sharpness = cv::mean(sharpness_map(working))[0];
  ASSERT_GT(mean_sharpness, kLargeDropMaxSharpness) << "the test image is not sharp enough to test the rule";
  EXPECT_EQ(r.large_drops, 0);
  EXPECT_EQ(r.sharp_large_drops, 1);
  const RemoveResult fine = smoke().run(sharp, fine_only);
  EXPECT_EQ(max_abs_diff(r.image, fine.image), 0);
  EXPECT_EQ(r.reconstructed_pixels, fine.reconstructed_pixels) << "the coarse pass's 3RN and RFN ran for nothing";
  const RemoveResult s = smoke().run(smooth, all);
  EXPECT_EQ(s.large_drops, 1);
  EXPECT_EQ(s.sharp_large_drops, 0);
  RemoveOptions limit = all;
  limit.large_drop_max_sharpness = 1.05 * mean_sharpness;
  EXPECT_EQ(smoke().run(sharp, limit).large_drops, 1);
  limit.large_drop_max_sharpness = 0.95 * mean_sharpness;
  EXPECT_EQ(smoke().run(sharp, limit).large_drops, 0);
  // An image at the working size or smaller runs natively (the image itself is the working-scale
  // image): the same rule, in each input format.
  cv::Mat small_sharp, small_smooth;
  cv::resize(sharp, small_sharp, {300, 150}, 0, 0, cv::INTER_NEAREST);
  cv::resize(smooth, small_smooth, {300, 150}, 0, 0, cv::INTER_AREA);
  ASSERT_GT(cv::mean(sharpness_map(small_sharp))[0], kLargeDropMaxSharpness);
  for (const auto& [img, expected] : {std::pair{small_sharp, 0}, std::pair{small_smooth, 1}}) {
    cv::Mat grey, rgba16, rgbf;
    cv::cvtColor(img, grey, cv::COLOR_RGB2GRAY);
    cv::cvtColor(img, rgba16, cv::COLOR_RGB2RGBA);
    rgba16.convertTo(rgba16, CV_16U, 257.0);
    img.convertTo(rgbf, CV_32F, 1.0 / 255.0);
    for (const cv::Mat& m : {img, grey, rgba16, rgbf}) {
      const RemoveResult n = smoke().run(m, all);
      EXPECT_EQ(n.scale, 1.0);
      EXPECT_EQ(n.large_drops, expected) << "channels " << m.channels() << ", depth " << m.depth();
    }
  }
  RemoveOptions bad = all;
  for (double v : {-1.0, std::nan("")}) {
    bad.large_drop_max_sharpness = v;
    EXPECT_THROW(smoke().run(sharp, bad), raindrop::Error) << v;
  }
}

// Large drops can go to other models than the working-scale pass's (Remover's large_drop_dir,
// models/<config>/LARGE_DROPS): with a mask over everything, the output is those models' result
// on the coarse copy, upsampled, and not the main models'.
TEST(LargeDropModels, ReconstructTheLargeDrops) {
  const fs::path other = source_dir() / "models" / "compact";
  Remover with_other(smoke_models(), {}, other);
  EXPECT_EQ(with_other.large_drop_model_dir(), other);
  const cv::Mat img = make_image(600, 300, 9);
  RemoveOptions all;
  all.threshold = -1.0;  // every detector's mask covers everything: one large drop
  all.large_drop_max_sharpness = kNoLimit;
  all.large_drop_detail = 0.0;  // the fill alone: which models made it (the detail is the input's)
  const RemoveResult r = with_other.run(img, all);
  ASSERT_EQ(r.large_drops, 1);
  const double coarse_scale = r.scale / kLargeDropScaleDivisor;
  Remover other_alone(other);
  const cv::Mat expected8 = coarse_result_upsampled(other_alone, img, coarse_scale);
  EXPECT_LE(max_abs_diff(r.image, expected8), 1);
  EXPECT_GT(max_abs_diff(smoke().run(img, all).image, expected8), 10) << "the test cannot tell the models apart";
}

// They are loaded on the first large drop: a photograph without one never pays for them (here:
// unreadable graphs that are never needed), and the first that has one gets a one-line error
// naming the file.
TEST(LargeDropModels, LoadOnlyForALargeDrop) {
  TempDir tmp;
  for (const char* f : {"rdn.onnx", "rrn.onnx", "rfn.onnx"}) write_file(tmp / "broken" / f, "not a graph");
  Remover r(smoke_models(), {}, tmp / "broken");
  const cv::Mat img = make_image(600, 300, 10);
  RemoveOptions none;
  none.threshold = 1.0;  // no drop at all
  EXPECT_EQ(max_abs_diff(r.run(img, none).image, smoke().run(img, none).image), 0);
  RemoveOptions all;
  all.threshold = -1.0;
  all.large_drop_max_sharpness = kNoLimit;
  for (int attempt = 0; attempt < 2; ++attempt) {  // the failure is kept: the same error again
    try {
      r.run(img, all);
      FAIL() << "expected an error";
    } catch (const raindrop::Error& e) {
      EXPECT_NE(std::string(e.what()).find("broken"), std::string::npos) << e.what();
    }
  }
}

// A folder without the three graphs is refused when the Remover is made, before any image.
TEST(LargeDropModels, AFolderWithoutTheGraphsIsRefusedAtOnce) {
  TempDir tmp;
  write_file(tmp / "half" / "rdn.onnx", "x");
  EXPECT_THROW(Remover(smoke_models(), {}, tmp / "half"), raindrop::Error);
  // The large drops' models need no detector: rrn.onnx and rfn.onnx are enough.
  fs::create_directories(tmp / "two");
  for (const char* f : {"rrn.onnx", "rfn.onnx"}) fs::copy_file(source_dir() / "models" / "compact" / f, tmp / "two" / f);
  Remover two(smoke_models(), {}, tmp / "two");
  RemoveOptions all;
  all.threshold = -1.0;
  all.large_drop_max_sharpness = kNoLimit;
  EXPECT_EQ(two.run(make_image(600, 300, 11), all).large_drops, 1);
  Remover same(smoke_models(), {}, smoke_models() / "");
  EXPECT_TRUE(same.large_drop_model_dir().empty()) << "the models' own folder: one set of models";
}

}  // namespace
}  // namespace removetest

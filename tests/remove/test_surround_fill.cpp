// Small drops filled from their surroundings (raindrop/remove/surround_fill.h): the push-pull
// interpolation in closed form and in its bounds, which parts of a mask it is given, and that
// the 3RN's output is kept bit for bit everywhere else.
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include "raindrop/remove/surround_fill.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

// 3 planes of h x w, every pixel (r, g, b).
std::vector<float> flat_planes(int h, int w, float r, float g, float b) {
  const size_t plane = static_cast<size_t>(h) * w;
  std::vector<float> v(3 * plane);
  std::fill(v.begin(), v.begin() + plane, r);
  std::fill(v.begin() + plane, v.begin() + 2 * plane, g);
  std::fill(v.begin() + 2 * plane, v.end(), b);
  return v;
}

float at(const std::vector<float>& v, int h, int w, int c, int y, int x) {
  return v[c * static_cast<size_t>(h) * w + static_cast<size_t>(y) * w + x];
}

TEST(PushPullFill, AFlatColourFillsAnyHoleWithItself) {
  for (const cv::Size size : {cv::Size(64, 48), cv::Size(37, 23), cv::Size(1, 9)}) {
    const int h = size.height, w = size.width;
    const std::vector<float> rgb = flat_planes(h, w, 0.2f, 0.55f, 0.9f);
    cv::Mat hole(h, w, CV_8U, cv::Scalar(0));
    cv::circle(hole, {w / 2, h / 2}, std::max(1, std::min(w, h) / 3), cv::Scalar(255), cv::FILLED);
    hole.at<unsigned char>(0, 0) = 255;  // a hole at the corner too
    ASSERT_GT(cv::countNonZero(hole), 0);
    ASSERT_LT(cv::countNonZero(hole), h * w);
    std::vector<float> out(rgb.size(), -1.0f);
    ASSERT_TRUE(push_pull_fill(rgb.data(), h, w, hole, out.data()));
    for (size_t i = 0; i < out.size(); ++i) ASSERT_NEAR(out[i], rgb[i], 1e-5f) << "size " << size << ", index " << i;
  }
}

// Every filled value is a convex combination of the known pixels: within their range, per
// channel, for random images and holes of every size (odd sizes exercise the 1- and 2-pixel
// blocks at the edges). Known pixels are the input exactly.
TEST(PushPullFill, FilledValuesLieWithinTheKnownPixelsRange) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 40; ++trial) {
    const int h = 1 + static_cast<int>(rng() % 70), w = 1 + static_cast<int>(rng() % 90);
    const size_t plane = static_cast<size_t>(h) * w;
    std::vector<float> rgb(3 * plane);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (float& v : rgb) v = u(rng);
    cv::Mat hole(h, w, CV_8U, cv::Scalar(0));
    const int holes = 1 + static_cast<int>(rng() % 6);
    for (int k = 0; k < holes; ++k)
      cv::circle(hole, {static_cast<int>(rng() % w), static_cast<int>(rng() % h)}, static_cast<int>(rng() % 20),
                 cv::Scalar(255), cv::FILLED);
    std::vector<float> out(rgb.size());
    const bool all_hole = cv::countNonZero(hole) == h * w;
    ASSERT_EQ(push_pull_fill(rgb.data(), h, w, hole, out.data()), !all_hole);
    if (all_hole) continue;
    for (int c = 0; c < 3; ++c) {
      float lo = 1e9f, hi = -1e9f;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          if (!hole.at<unsigned char>(y, x)) {
            lo = std::min(lo, at(rgb, h, w, c, y, x));
            hi = std::max(hi, at(rgb, h, w, c, y, x));
          }
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const float v = at(out, h, w, c, y, x);
          if (hole.at<unsigned char>(y, x)) {
            ASSERT_TRUE(std::isfinite(v));
            ASSERT_GE(v, lo - 1e-5f) << "trial " << trial;
            ASSERT_LE(v, hi + 1e-5f) << "trial " << trial;
          } else {
            ASSERT_EQ(v, at(rgb, h, w, c, y, x)) << "a known pixel is the input's";
          }
        }
    }
  }
}

// Left half one colour, right half another, a hole across the middle: the fill takes each
// side's colour near that side and passes between them, monotonically along each row.
TEST(PushPullFill, AHoleBetweenTwoColoursIsFilledFromTheNearerSide) {
  const int h = 40, w = 80;
  std::vector<float> rgb = flat_planes(h, w, 0.0f, 0.0f, 0.0f);
  for (int y = 0; y < h; ++y)
    for (int x = w / 2; x < w; ++x) rgb[static_cast<size_t>(y) * w + x] = 1.0f;  // red channel: 0 | 1
  cv::Mat hole(h, w, CV_8U, cv::Scalar(0));
  hole(cv::Rect(24, 8, 32, 24)).setTo(255);
  std::vector<float> out(rgb.size());
  ASSERT_TRUE(push_pull_fill(rgb.data(), h, w, hole, out.data()));
  for (int y = 8; y < 32; ++y) {
    EXPECT_LT(at(out, h, w, 0, y, 25), 0.3f) << "row " << y << ": next to the left side";
    EXPECT_GT(at(out, h, w, 0, y, 54), 0.7f) << "row " << y << ": next to the right side";
    for (int x = 25; x < 56; ++x) ASSERT_LE(at(out, h, w, 0, y, x - 1), at(out, h, w, 0, y, x) + 1e-6f);
  }
}

TEST(PushPullFill, ANothingButHoleImageIsRefused) {
  const std::vector<float> rgb = flat_planes(8, 8, 0.5f, 0.5f, 0.5f);
  std::vector<float> out(rgb.size(), -1.0f);
  EXPECT_FALSE(push_pull_fill(rgb.data(), 8, 8, cv::Mat(8, 8, CV_8U, cv::Scalar(255)), out.data()));
  EXPECT_EQ(out[0], -1.0f) << "nothing written";
}

// A scene for the rule: a flat grey left half and a textured right half (random levels, far
// above the limit), with three parts in the mask: a small disk on the flat half, a small disk on
// the textured half, and a large disk on the flat half.
struct RuleScene {
  int h = 120, w = 240;
  std::vector<float> rgb;
  cv::Mat mask;
  RuleScene() {
    rgb = flat_planes(h, w, 0.6f, 0.6f, 0.6f);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    const size_t plane = static_cast<size_t>(h) * w;
    for (int y = 0; y < h; ++y)
      for (int x = w / 2; x < w; ++x) {
        const float v = u(rng);
        for (int c = 0; c < 3; ++c) rgb[c * plane + static_cast<size_t>(y) * w + x] = v;
      }
    mask = cv::Mat(h, w, CV_8U, cv::Scalar(0));
    cv::circle(mask, {30, 30}, 6, cv::Scalar(255), cv::FILLED);   // small, flat surround
    cv::circle(mask, {180, 30}, 6, cv::Scalar(255), cv::FILLED);  // small, textured surround
    cv::circle(mask, {50, 85}, 20, cv::Scalar(255), cv::FILLED);  // large (about 1260 px), flat
  }
};

TEST(SurroundFill, OnlySmallPartsOverSmoothSurroundingsAreChosen) {
  RuleScene s;
  int parts = -1;
  const cv::Mat chosen = surround_fill_mask(s.mask, s.rgb.data(), kSurroundFillArea, kSurroundFillMad, &parts);
  EXPECT_EQ(parts, 1);
  cv::Mat expected(s.mask.size(), CV_8U, cv::Scalar(0));
  cv::circle(expected, {30, 30}, 6, cv::Scalar(255), cv::FILLED);
  EXPECT_EQ(cv::countNonZero(chosen != expected), 0) << "exactly the small disk on the flat half";
  // A larger area admits the large disk; a looser limit the textured one; 0 turns the fill off.
  surround_fill_mask(s.mask, s.rgb.data(), 2000, kSurroundFillMad, &parts);
  EXPECT_EQ(parts, 2);
  surround_fill_mask(s.mask, s.rgb.data(), kSurroundFillArea, 255.0, &parts);
  EXPECT_EQ(parts, 2);
  EXPECT_EQ(cv::countNonZero(surround_fill_mask(s.mask, s.rgb.data(), 0, 255.0, &parts)), 0);
  EXPECT_EQ(parts, 0);
}

// A dense windshield puts other drops, missed by the detector, into most surrounds. The median
// absolute deviation ignores them while they are fewer than half of the surround pixels (a
// textured surround, where most pixels differ, is RuleScene's).
TEST(SurroundFill, NeighbouringDropsDoNotMakeASurroundRough) {
  const int h = 60, w = 60;
  std::vector<float> rgb = flat_planes(h, w, 0.8f, 0.8f, 0.8f);
  cv::Mat dark(h, w, CV_8U, cv::Scalar(0));
  for (int x = 20; x < 40; x += 3) dark.col(x).setTo(255);  // dark streaks: about a third of the surround
  const size_t plane = static_cast<size_t>(h) * w;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if (dark.at<unsigned char>(y, x))
        for (int c = 0; c < 3; ++c) rgb[c * plane + static_cast<size_t>(y) * w + x] = 0.1f;
  cv::Mat mask(h, w, CV_8U, cv::Scalar(0));
  cv::circle(mask, {30, 30}, 5, cv::Scalar(255), cv::FILLED);
  int parts = -1;
  surround_fill_mask(mask, rgb.data(), kSurroundFillArea, kSurroundFillMad, &parts);
  EXPECT_EQ(parts, 1);
  // The standard deviation of that surround is about 0.47 x 0.7 x 255 = 84 levels.
}

TEST(SurroundFill, APartWithoutASurroundIsNotFilled) {
  const std::vector<float> rgb = flat_planes(10, 10, 0.5f, 0.5f, 0.5f);
  int parts = -1;
  surround_fill_mask(cv::Mat(10, 10, CV_8U, cv::Scalar(255)), rgb.data(), kSurroundFillArea, 255.0, &parts);
  EXPECT_EQ(parts, 0) << "a mask over the whole window has no pixel outside it";
}

// The 3RN's output is replaced in the chosen parts by the fill and kept bit for bit elsewhere,
// including in the parts not chosen.
TEST(SurroundFill, OnlyTheChosenPartsOfTheReconstructionChange) {
  RuleScene s;
  const size_t plane = static_cast<size_t>(s.h) * s.w;
  std::vector<float> ihat(3 * plane);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (float& v : ihat) v = u(rng);
  const std::vector<float> before = ihat;
  cv::Mat filled;
  EXPECT_EQ(fill_small_drops_from_surround(s.rgb.data(), s.mask, kSurroundFillArea, kSurroundFillMad, ihat, &filled), 1);
  cv::Mat chosen(s.h, s.w, CV_8U, cv::Scalar(0));
  cv::circle(chosen, {30, 30}, 6, cv::Scalar(255), cv::FILLED);
  // The parts it reports filled are those it filled, as surround_fill_mask chooses them.
  ASSERT_EQ(filled.type(), CV_8UC1);
  EXPECT_EQ(cv::norm(filled, chosen, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(filled, surround_fill_mask(s.mask, s.rgb.data(), kSurroundFillArea, kSurroundFillMad), cv::NORM_INF), 0.0);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < s.h; ++y)
      for (int x = 0; x < s.w; ++x) {
        const size_t i = c * plane + static_cast<size_t>(y) * s.w + x;
        if (chosen.at<unsigned char>(y, x))
          ASSERT_NEAR(ihat[i], 0.6f, 1e-5f) << "the flat grey around the part";
        else
          ASSERT_EQ(ihat[i], before[i]);
      }
  // Off: nothing changes.
  ihat = before;
  EXPECT_EQ(fill_small_drops_from_surround(s.rgb.data(), s.mask, 0, kSurroundFillMad, ihat), 0);
  EXPECT_EQ(ihat, before);
}

// The rule's limit is inclusive, and both medians are the upper one (index n / 2 of the n
// sorted values): a surround of 4 pixels at 100 levels and 4 at 106 has the median 106 and the
// absolute deviations 0, 0, 0, 0, 6, 6, 6, 6, whose upper median is 6. (With lower medians it
// would be 0, and a limit under 6 would fill it.)
TEST(SurroundFill, TheLimitIsInclusiveOnTheUpperMedians) {
  const int h = 3, w = 5;
  std::vector<float> rgb = flat_planes(h, w, 0.0f, 0.0f, 0.0f);
  cv::Mat mask(h, w, CV_8U, cv::Scalar(255));
  // Eight unmasked pixels around a masked part: four at 100 levels, four at 106.
  const int xs[8] = {0, 1, 2, 3, 0, 1, 2, 3}, ys[8] = {0, 0, 0, 0, 2, 2, 2, 2};
  const size_t plane = static_cast<size_t>(h) * w;
  for (int i = 0; i < 8; ++i) {
    mask.at<unsigned char>(ys[i], xs[i]) = 0;
    const float v = (i < 4 ? 100.0f : 106.0f) / 255.0f;
    for (int c = 0; c < 3; ++c) rgb[c * plane + static_cast<size_t>(ys[i]) * w + xs[i]] = v;
  }
  int parts = -1;
  surround_fill_mask(mask, rgb.data(), kSurroundFillArea, 6.0 + 1e-3, &parts);
  EXPECT_EQ(parts, 1);
  surround_fill_mask(mask, rgb.data(), kSurroundFillArea, 5.99, &parts);
  EXPECT_EQ(parts, 0);
}

// The pipeline passes a tile's window of a larger mask (an ROI, rows not contiguous): the result
// is the same as for a copy of that window.
TEST(SurroundFill, AWindowOfALargerMaskIsFilledAsItsCopy) {
  std::mt19937 rng(21);
  cv::Mat canvas(90, 160, CV_8U, cv::Scalar(0));
  for (int k = 0; k < 25; ++k)
    cv::circle(canvas, {static_cast<int>(rng() % 160), static_cast<int>(rng() % 90)}, 2 + static_cast<int>(rng() % 6),
               cv::Scalar(255), cv::FILLED);
  const cv::Rect win(17, 9, 101, 67);
  cv::Mat roi = canvas(win), copy = roi.clone();
  ASSERT_FALSE(roi.isContinuous());
  const size_t plane = static_cast<size_t>(win.area());
  std::vector<float> rgb(3 * plane), ihat(3 * plane);
  std::uniform_real_distribution<float> u(0.45f, 0.46f);  // smooth: every small part qualifies
  for (float& v : rgb) v = u(rng);
  for (float& v : ihat) v = 2.0f;
  std::vector<float> a = ihat, b = ihat;
  const int na = fill_small_drops_from_surround(rgb.data(), roi, kSurroundFillArea, kSurroundFillMad, a);
  const int nb = fill_small_drops_from_surround(rgb.data(), copy, kSurroundFillArea, kSurroundFillMad, b);
  EXPECT_GT(na, 0);
  EXPECT_EQ(na, nb);
  EXPECT_EQ(a, b);
}

// Thin parts have windows far larger than their area; past kSurroundWindowBudget times the image
// all of them are filled from one push-pull of the whole image, which bounds the cost. Below it,
// each part from its own window: on a smooth image the two differ only a little.
TEST(SurroundFill, ManyThinPartsAreFilledFromOneWholeImageFill) {
  const int h = 300, w = 600;
  const size_t plane = static_cast<size_t>(h) * w;
  std::vector<float> rgb(3 * plane);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) rgb[c * plane + static_cast<size_t>(y) * w + x] = 0.3f + 0.001f * x + 0.0005f * y;
  cv::Mat mask(h, w, CV_8U, cv::Scalar(0));
  for (int x : {20, 320})
    for (int y = 2; y + 2 < h; y += 4) mask(cv::Rect(x, y, 40, 2)).setTo(255);  // 148 strips of 40x2: 80 px each
  std::vector<float> ihat(3 * plane, 2.0f);
  const int n = fill_small_drops_from_surround(rgb.data(), mask, kSurroundFillArea, 255.0, ihat);
  ASSERT_EQ(n, 148);
  // Their windows (up to 200 x 162 each, none the whole image) add up to far more than 4 x 300 x
  // 600: the whole-image fill, exactly.
  std::vector<float> whole(3 * plane);
  ASSERT_TRUE(push_pull_fill(rgb.data(), h, w, mask, whole.data()));
  for (size_t i = 0; i < ihat.size(); ++i) {
    const size_t p = i % plane;
    if (mask.at<unsigned char>(static_cast<int>(p / w), static_cast<int>(p % w)))
      ASSERT_EQ(ihat[i], whole[i]);
    else
      ASSERT_EQ(ihat[i], 2.0f);
  }
  // One strip alone stays within the budget: its own window's fill, close to the whole image's
  // but not equal to it (which shows that the comparison above can tell the two apart).
  cv::Mat one(h, w, CV_8U, cv::Scalar(0));
  one(cv::Rect(320, 142, 40, 2)).setTo(255);
  std::vector<float> single(3 * plane, 2.0f), whole_one(3 * plane);
  ASSERT_EQ(fill_small_drops_from_surround(rgb.data(), one, kSurroundFillArea, 255.0, single), 1);
  ASSERT_TRUE(push_pull_fill(rgb.data(), h, w, one, whole_one.data()));
  float largest = 0.0f;
  for (size_t i = 0; i < single.size(); ++i) {
    const size_t p = i % plane;
    if (one.at<unsigned char>(static_cast<int>(p / w), static_cast<int>(p % w))) {
      ASSERT_NEAR(single[i], whole_one[i], 0.02f);
      largest = std::max(largest, std::abs(single[i] - whole_one[i]));
    }
  }
  EXPECT_GT(largest, 0.0f);
}

// A drop's rim just past its mask: a dark ring 2 px wide around a disk the detector found
// (grey 0.6 around), and, beside another found disk, a dark pole that goes on past any rim.
struct RimScene {
  int h = 60, w = 120;
  std::vector<float> rgb = flat_planes(h, w, 0.6f, 0.6f, 0.6f);
  cv::Mat mask = cv::Mat(h, w, CV_8U, cv::Scalar(0));
  cv::Mat ring = cv::Mat(h, w, CV_8U, cv::Scalar(0)), pole = cv::Mat(h, w, CV_8U, cv::Scalar(0));
  RimScene() {
    cv::circle(mask, {30, 30}, 6, cv::Scalar(255), cv::FILLED);
    cv::circle(ring, {30, 30}, 8, cv::Scalar(255), cv::FILLED);
    ring.setTo(0, mask);  // the 2 px outside the disk
    cv::circle(mask, {90, 30}, 5, cv::Scalar(255), cv::FILLED);
    pole.colRange(96, 98).setTo(255);  // touches the second disk's 1-px surround, runs the frame's height
    pole.setTo(0, mask);
    const size_t plane = static_cast<size_t>(h) * w;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        if (ring.at<unsigned char>(y, x) || pole.at<unsigned char>(y, x))
          for (int c = 0; c < 3; ++c) rgb[c * plane + static_cast<size_t>(y) * w + x] = 0.1f;
  }
};

TEST(SurroundFill, ARimThatEndsJoinsItsPartAndAPoleThatGoesOnDoesNot) {
  for (const int rim : {0, 1, 2, 3, 4}) {
    SCOPED_TRACE("rim " + std::to_string(rim));
    RimScene s;
    const cv::Mat mask_before = s.mask.clone();
    const size_t plane = static_cast<size_t>(s.h) * s.w;
    std::vector<float> ihat(3 * plane, 0.25f);
    cv::Mat filled;
    ASSERT_EQ(fill_small_drops_from_surround(s.rgb.data(), s.mask, kSurroundFillArea, kSurroundFillMad, ihat, &filled, rim),
              2);
    // The ring is 2 px wide: taken whole from 2 steps on; 1 step would leave half of it, so the
    // growth is refused (the next step would add as much again).
    cv::Mat expected = mask_before.clone();
    if (rim >= 2) expected.setTo(255, s.ring);
    EXPECT_EQ(cv::countNonZero((s.mask != 0) != (expected != 0)), 0) << "the mask grows by the ring exactly";
    EXPECT_EQ(cv::countNonZero((filled != 0) != (expected != 0)), 0) << "the filled parts are the grown ones";
    EXPECT_EQ(cv::countNonZero((s.mask != 0) & s.pole), 0) << "the pole is scenery";
    // Grown, the drop and its rim are filled with the grey around them; not grown, the drop's
    // fill takes in the dark ring around it (what the growth is for), and the ring stays.
    double darkest = 1.0;
    for (int y = 0; y < s.h; ++y)
      for (int x = 0; x < s.w; ++x)
        for (int c = 0; c < 3; ++c) {
          const float v = ihat[c * plane + static_cast<size_t>(y) * s.w + x];
          if (expected.at<unsigned char>(y, x) && x < 60) {
            if (rim >= 2) {
              ASSERT_NEAR(v, 0.6f, 1e-5f);
            }
            darkest = std::min(darkest, static_cast<double>(v));
          } else if (!expected.at<unsigned char>(y, x)) {
            ASSERT_EQ(v, 0.25f) << "outside the parts, the 3RN's output untouched";
          }
        }
    if (rim < 2) {
      EXPECT_LT(darkest, 0.5) << "the ring's dark bleeds into the drop's fill";
    }
  }
}

// What counts as a rim: pixels more than kRimLevels off the surround median, darker or brighter
// (a bright halo is taken as a dark rim is); a band that reaches the edge of the mask given (the
// image's, or a tile's window) may go on past it and is left alone.
TEST(SurroundFill, ARimIsMoreThanTwelveLevelsOffAndEndsInsideTheFrame) {
  const int h = 40, w = 40;
  const auto grown_by = [&](float ring_offset_levels, cv::Point centre) {
    std::vector<float> rgb = flat_planes(h, w, 0.6f, 0.6f, 0.6f);  // luma 153
    cv::Mat mask(h, w, CV_8U, cv::Scalar(0)), ring(h, w, CV_8U, cv::Scalar(0));
    cv::circle(mask, centre, 5, cv::Scalar(255), cv::FILLED);
    cv::circle(ring, centre, 7, cv::Scalar(255), cv::FILLED);
    ring.setTo(0, mask);
    const size_t plane = static_cast<size_t>(h) * w;
    const float v = 0.6f + ring_offset_levels / 255.0f;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        if (ring.at<unsigned char>(y, x))
          for (int c = 0; c < 3; ++c) rgb[c * plane + static_cast<size_t>(y) * w + x] = v;
    const int before = cv::countNonZero(mask);
    std::vector<float> ihat(3 * plane, 0.0f);
    EXPECT_EQ(fill_small_drops_from_surround(rgb.data(), mask, kSurroundFillArea, kSurroundFillMad, ihat, nullptr, 3), 1);
    return cv::countNonZero(mask) - before;
  };
  const cv::Point middle(20, 20);
  EXPECT_EQ(grown_by(11.0f, middle), 0) << "11 levels off: not a rim";
  EXPECT_GT(grown_by(13.0f, middle), 0) << "13 levels brighter: a halo";
  EXPECT_GT(grown_by(-13.0f, middle), 0) << "13 levels darker: a rim";
  EXPECT_EQ(grown_by(-60.0f, {6, 20}), 0) << "a ring cut by the frame's edge";
}

}  // namespace
}  // namespace removetest

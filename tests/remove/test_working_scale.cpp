// The working scale (raindrop/remove/working_scale.h): which scale an image is processed at,
// how the result comes back to full size, and that pixels outside the mask stay the input's.
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"
#include "raindrop/remove/pixels.h"
#include "raindrop/remove/remover.h"
#include "raindrop/remove/working_scale.h"
#include "remove_test_util.h"
#include "smoke_remover.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

Remover& smoke() { return smoke_remover(); }

float max_float_diff(const cv::Mat& a, const cv::Mat& b) {
  double mx = 0;
  cv::minMaxLoc(cv::abs(a.reshape(1) - b.reshape(1)), nullptr, &mx);
  return static_cast<float>(mx);
}

TEST(WorkingScale, LongSideBroughtToTheWorkingSizeNeverEnlarged) {
  EXPECT_DOUBLE_EQ(auto_working_scale({512, 256}, 512), 1.0);
  EXPECT_DOUBLE_EQ(auto_working_scale({256, 256}, 512), 1.0);
  EXPECT_DOUBLE_EQ(auto_working_scale({2048, 1024}, 512), 0.25);
  EXPECT_DOUBLE_EQ(auto_working_scale({1280, 720}, 512), 0.4);
  EXPECT_DOUBLE_EQ(auto_working_scale({720, 1280}, 512), 0.4);  // portrait: the long side
  EXPECT_DOUBLE_EQ(auto_working_scale({2048, 1024}, 1024), 0.5);
  EXPECT_EQ(scaled_size({2048, 1024}, 0.25), cv::Size(512, 256));
  EXPECT_EQ(scaled_size({1280, 720}, 0.4), cv::Size(512, 288));
  EXPECT_EQ(scaled_size({3, 1}, 0.01), cv::Size(1, 1));
}

// Bands of rows upsample exactly as cv::resize does on the whole image, wherever they start.
TEST(WorkingScale, BandsUpsampleLikeAWholeImageResize) {
  const cv::Size full(301, 203), small(77, 51);
  cv::Mat out_small(small, CV_32FC3), mask_small(small, CV_32F, cv::Scalar(1.0f));
  cv::randu(out_small, 0.0f, 1.0f);
  cv::Mat whole;
  cv::resize(out_small, whole, full, 0, 0, cv::INTER_LINEAR);
  const cv::Mat input(full, CV_32FC3, cv::Scalar::all(0.5f));
  for (const int band : {1, 7, 64, 203}) {
    for (int y0 = 0; y0 < full.height; y0 += band) {
      const int rows = std::min(band, full.height - y0);
      cv::Mat alpha;
      const cv::Mat got = blend_upsampled_rows(input.rowRange(y0, y0 + rows), y0, full, out_small, mask_small, alpha);
      ASSERT_LE(max_float_diff(got, whole.rowRange(y0, y0 + rows)), 1e-5f) << "band " << band << " at row " << y0;
      ASSERT_LE(max_float_diff(alpha, cv::Mat(rows, full.width, CV_32F, cv::Scalar(1.0f))), 1e-6f);
    }
  }
}

// Any region (the remover blends only the columns a drop reaches) is exactly that part of the
// whole rows' blend, wherever it starts.
TEST(WorkingScale, RegionsBlendExactlyAsTheirPartOfTheWhole) {
  const cv::Size full(301, 203), small(77, 51);
  cv::Mat out_small(small, CV_32FC3), mask_small(small, CV_32F);
  cv::randu(out_small, 0.0f, 1.0f);
  cv::randu(mask_small, -0.5f, 1.0f);  // a third of it 0 or below: kept pixels inside regions too
  cv::Mat input(full, CV_32FC3);
  cv::randu(input, 0.0f, 1.0f);
  cv::Mat whole_alpha;
  const cv::Mat whole = blend_upsampled_rows(input, 0, full, out_small, mask_small, whole_alpha);
  for (const cv::Rect region : {cv::Rect(0, 0, 1, 1), cv::Rect(300, 202, 1, 1), cv::Rect(17, 5, 90, 16),
                                cv::Rect(123, 190, 178, 13), cv::Rect(0, 40, 301, 3)}) {
    cv::Mat alpha;
    const cv::Mat got = blend_upsampled(input(region), region, full, out_small, mask_small, alpha);
    EXPECT_EQ(max_float_diff(got, whole(region)), 0.0f) << region;
    EXPECT_EQ(max_float_diff(alpha, whole_alpha(region)), 0.0f) << region;
    EXPECT_EQ(max_float_diff(upsample_region(out_small, full, region), upsample_region(out_small, full, cv::Rect(0, 0, full.width, full.height))(region)), 0.0f) << region;
  }
}

// The mask weights the blend: 0 keeps the input exactly, 1 takes the upsampled output, and
// the seam of a half-covered image lies where the small mask's edge projects.
// upsampled_reach: outside the part of a region it names (same rows, a run of its columns), the
// upsampled weights are exactly 0, and with no weight above 0 it is empty. (It may be wider
// than the non-zero pixels: a tap with weight 0 still counts.) Random sparse weights, none
// included, odd sizes and scales, many regions.
TEST(WorkingScale, UpsampledReachHoldsEveryNonZeroWeight) {
  cv::RNG rng(31);
  for (int trial = 0; trial < 40; ++trial) {
    const cv::Size small(rng.uniform(3, 60), rng.uniform(3, 40));
    const cv::Size full(small.width * rng.uniform(1, 5) + rng.uniform(0, 7), small.height * rng.uniform(1, 5) + rng.uniform(0, 7));
    cv::Mat weight(small, CV_32F, cv::Scalar(0));
    for (int k = rng.uniform(0, 4); k > 0; --k)
      weight.at<float>(rng.uniform(0, small.height), rng.uniform(0, small.width)) = rng.uniform(0.01f, 1.0f);
    const cv::Mat whole = upsample_region(weight, full, cv::Rect(cv::Point(), full));
    for (int r = 0; r < 6; ++r) {
      const int y = rng.uniform(0, full.height), x = rng.uniform(0, full.width);
      const cv::Rect region(x, y, rng.uniform(1, full.width - x + 1), rng.uniform(1, full.height - y + 1));
      SCOPED_TRACE(::testing::Message() << "trial " << trial << " small " << small << " full " << full << " region " << region);
      const cv::Rect reach = upsampled_reach(weight, full, region);
      const cv::Mat part = whole(region);
      cv::Mat outside = part.clone();
      if (!reach.empty()) {
        ASSERT_EQ((reach & region), reach);
        ASSERT_EQ(reach.y, region.y);
        ASSERT_EQ(reach.height, region.height);
        outside(reach - region.tl()).setTo(0);
      } else {
        EXPECT_EQ(cv::countNonZero(part), 0);
      }
      if (cv::countNonZero(weight) == 0) {
        EXPECT_TRUE(reach.empty());
      }
      EXPECT_EQ(cv::countNonZero(outside), 0) << "a weight above 0 outside the reach";
    }
  }
}

TEST(WorkingScale, MaskWeightsTheBlend) {
  const cv::Size full(400, 100), small(100, 25);
  const cv::Mat out_small(small, CV_32FC3, cv::Scalar::all(1.0f));
  cv::Mat mask_small(small, CV_32F, cv::Scalar(0.0f));
  mask_small.colRange(50, 100).setTo(1.0f);
  cv::Mat input(full, CV_32FC3);
  cv::randu(input, 0.0f, 0.5f);
  cv::Mat alpha;
  const cv::Mat got = blend_upsampled_rows(input, 0, full, out_small, mask_small, alpha);
  // Small column 49 (alpha 0) covers full columns 196-199; 50 covers 200-203. Bilinear
  // weights reach 0 at the centre of column 49 (full x = 197.5) and 1 at that of column 50.
  EXPECT_EQ(max_float_diff(got.colRange(0, 198), input.colRange(0, 198)), 0.0f);
  EXPECT_EQ(max_float_diff(got.colRange(202, 400), cv::Mat(100, 198, CV_32FC3, cv::Scalar::all(1.0f))), 0.0f);
  EXPECT_NEAR(alpha.at<float>(50, 199), 0.375f, 1e-6f);  // (199.5 - 197.5) / 4 - 0.125
  EXPECT_NEAR(alpha.at<float>(50, 200), 0.625f, 1e-6f);
}

// With an empty mask nothing the networks did comes back: a large image is returned as it
// was, bit for bit, in every format; at its own scale the refine network changes it.
TEST(WorkingScale, EmptyMaskReturnsTheInputBitForBit) {
  const cv::Mat rgb8 = make_image(1100, 600, 41);  // (rgb8 const, the others made below)
  cv::Mat rgb16, rgba16, grey8;
  rgb8.convertTo(rgb16, CV_16U, 257.0);
  rgb16.at<cv::Vec3w>(5, 7) = cv::Vec3w(1, 65534, 30001);  // values that no 8-bit pixel has
  cv::Mat alpha(rgb8.size(), CV_16U);
  cv::randu(alpha, 0, 65535);
  cv::merge(std::vector<cv::Mat>{rgb16, alpha}, rgba16);
  cv::cvtColor(rgb8, grey8, cv::COLOR_RGB2GRAY);
  RemoveOptions none;
  none.threshold = 1.0;  // P > 1 never holds
  for (const cv::Mat* m : {&rgb8, static_cast<const cv::Mat*>(&rgba16), static_cast<const cv::Mat*>(&grey8)}) {
    const RemoveResult r = smoke().run(*m, none);
    EXPECT_NEAR(r.scale, 512.0 / 1100.0, 1e-12);
    EXPECT_EQ(cv::countNonZero(r.mask), 0);
    EXPECT_EQ(max_abs_diff(r.image, *m), 0) << "channels " << m->channels();
  }
  RemoveOptions native = none;
  native.scale = 1.0;
  const RemoveResult r = smoke().run(rgb8, native);
  EXPECT_EQ(r.scale, 1.0);
  EXPECT_GT(max_abs_diff(r.image, rgb8), 0) << "the refine network ran on every pixel at scale 1";
}

// A full mask: the output is the networks' result on the area-downscaled copy, upsampled.
TEST(WorkingScale, FullMaskIsTheUpsampledResultOfTheSmallCopy) {
  const cv::Mat img = make_image(1024, 640, 42);
  RemoveOptions all;
  all.threshold = -1.0;  // P > -1 always
  all.large_drops = false;  // one mask over everything: the coarse pass would take it all
  const RemoveResult r = smoke().run(img, all);
  ASSERT_DOUBLE_EQ(r.scale, 0.5);
  EXPECT_EQ(cv::countNonZero(r.mask), static_cast<int>(r.mask.total()));
  cv::Mat small, expected;
  cv::resize(img, small, {512, 320}, 0, 0, cv::INTER_AREA);
  RemoveOptions all_native = all;
  all_native.scale = 1.0;
  all_native.keep_float = true;
  const RemoveResult s = smoke().run(small, all_native);
  cv::resize(s.rgb, expected, img.size(), 0, 0, cv::INTER_LINEAR);
  cv::Mat expected8;
  expected.convertTo(expected8, CV_8U, 255.0);
  EXPECT_LE(max_abs_diff(r.image, expected8), 1);
}

// A partial mask: every pixel farther than one small pixel from the final mask is the input's.
TEST(WorkingScale, PixelsAwayFromTheMaskAreTheInputs) {
  const cv::Mat img = make_image(1536, 768, 43);
  RemoveOptions o;
  o.threshold = 0.5;
  o.large_drops = false;  // the working-scale pass's own margin (the coarse pass has its own)
  const RemoveResult r = smoke().run(img, o);
  ASSERT_DOUBLE_EQ(r.scale, 1.0 / 3.0);
  const int covered = cv::countNonZero(r.mask);
  ASSERT_GT(covered, 0);
  ASSERT_LT(covered, static_cast<int>(r.mask.total()));
  cv::Mat far;
  cv::distanceTransform(r.mask == 0, far, cv::DIST_L2, 5);
  const cv::Mat away = far > 3.0f + 1.0f;  // one small pixel is 3 full ones
  cv::Mat differs;
  cv::absdiff(r.image, img, differs);
  cv::cvtColor(differs, differs, cv::COLOR_RGB2GRAY);
  EXPECT_EQ(cv::countNonZero((differs > 0) & away), 0);
  EXPECT_GT(cv::countNonZero(differs > 0), 0) << "inside the mask the networks' result comes in";
}

TEST(WorkingScale, ScaleOutsideTheUnitIntervalIsRefused) {
  const cv::Mat img = make_image(32, 32, 1);
  for (const double bad : {0.0, -0.5, 1.5, std::nan("")}) {
    RemoveOptions o;
    o.scale = bad;
    EXPECT_THROW(smoke().run(img, o), raindrop::Error) << bad;
  }
}

TEST(WorkingScaleCli, ScaleOptionIsCheckedAndReported) {
  TempDir tmp;
  write_image(tmp / "in.png", make_image(1024, 512, 44));
  for (const char* bad : {"0", "1.5", "nan", "x"}) {
    const RunResult r = run_remove({"in.png", "out.png", "--models", smoke_models().string(), "--scale", bad}, tmp.path());
    EXPECT_EQ(r.code, 2) << bad << ": " << r.describe();
    EXPECT_FALSE(fs::exists(tmp / "out.png"));
  }
  RunResult r = run_remove({"in.png", "out.png", "--models", smoke_models().string(), "--time"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("1024x512 at scale 0.5,"), std::string::npos) << r.err;
  r = run_remove({"in.png", "out.png", "--models", smoke_models().string(), "--time", "--scale", "1"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("1024x512 at scale 1,"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace removetest

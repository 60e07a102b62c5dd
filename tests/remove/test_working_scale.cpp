// The working scale (raindrop/remove/working_scale.h): which scale an image is processed at,
// how the result comes back to full size, and that pixels outside the mask stay the input's.
#include <cmath>
#include <cstring>

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

// upsampled_reach: outside the part of a region it names (same rows, a run of its columns), the
// upsampled weights are exactly 0, and with no weight above 0 it is empty. (It may be wider
// than the pixels above 0: a tap of weight 0 still counts.) Random weights (none, isolated
// points or blobs), small images down to 1 pixel wide or high, odd scales, random regions
// and the composite's own regions: full-width bands of 16 rows.
TEST(WorkingScale, UpsampledReachHoldsEveryNonZeroWeight) {
  cv::RNG rng(31);
  int nonempty = 0;
  for (int trial = 0; trial < 80; ++trial) {
    const cv::Size small(trial % 10 == 0 ? 1 : rng.uniform(1, 60), trial % 10 == 1 ? 1 : rng.uniform(1, 40));
    const cv::Size full(small.width * rng.uniform(1, 5) + rng.uniform(0, 7), small.height * rng.uniform(1, 5) + rng.uniform(0, 7));
    cv::Mat weight(small, CV_32F, cv::Scalar(0));
    for (int k = rng.uniform(0, 4); k > 0; --k) {
      const cv::Point at(rng.uniform(0, small.width), rng.uniform(0, small.height));
      if (trial % 3 == 0) {
        cv::circle(weight, at, rng.uniform(1, 4), cv::Scalar(rng.uniform(0.01f, 1.0f)), cv::FILLED);
      } else {
        weight.at<float>(at) = rng.uniform(0.01f, 1.0f);
      }
    }
    const cv::Mat whole = upsample_region(weight, full, cv::Rect(cv::Point(), full));
    std::vector<cv::Rect> regions;
    for (int y = 0; y < full.height; y += 16) regions.emplace_back(0, y, full.width, std::min(16, full.height - y));
    for (int r = 0; r < 6; ++r) {
      const int y = rng.uniform(0, full.height), x = rng.uniform(0, full.width);
      regions.emplace_back(x, y, rng.uniform(1, full.width - x + 1), rng.uniform(1, full.height - y + 1));
    }
    for (const cv::Rect& region : regions) {
      SCOPED_TRACE(::testing::Message() << "trial " << trial << " small " << small << " full " << full << " region " << region);
      const cv::Rect reach = upsampled_reach(weight, full, region);
      cv::Mat outside = whole(region).clone();
      if (!reach.empty()) {
        ++nonempty;
        ASSERT_EQ((reach & region), reach);
        ASSERT_EQ(reach.y, region.y);
        ASSERT_EQ(reach.height, region.height);
        outside(reach - region.tl()).setTo(0);
      }
      EXPECT_EQ(cv::countNonZero(outside), 0) << "a weight above 0 outside the reach";
      if (cv::countNonZero(weight) == 0) {
        EXPECT_TRUE(reach.empty());
      }
    }
  }
  EXPECT_GT(nonempty, 200) << "too few regions that a weight reaches: the test checks little";
  // Tight enough to be worth it: one small pixel reaches a few full columns, not the band.
  cv::Mat point(cv::Size(100, 20), CV_32F, cv::Scalar(0));
  point.at<float>(10, 50) = 1.0f;
  const cv::Rect one = upsampled_reach(point, {400, 80}, cv::Rect(0, 40, 400, 16));
  EXPECT_GE(one.x, 196);
  EXPECT_LE(one.x + one.width, 206);
}

// The composite (Remover::run's way back to full size) against the plain version it replaced:
// the upsampled weight over whole bands, one blended span from a band's first drop column to
// its last. Every type the remover takes, with and without the float result, with a float base
// that is the input's own or another (the large-drop pass), scattered drops with gaps under and
// over the 16 columns that split a band's work, and 1 to 5 threads: the same bytes and floats.
detail::Upsampled reference_composite(const cv::Mat& base, const cv::Mat& base_rgb, const cv::Mat& rgb_small,
                                      const cv::Mat& weight_small, bool keep_float) {
  const cv::Size full = base.size();
  detail::Upsampled up;
  up.image.create(full, base.type());
  up.mask.create(full, CV_8U);
  if (keep_float) up.rgb.create(full, CV_32FC3);
  const size_t pixel_bytes = base.elemSize();
  for (int y0 = 0; y0 < full.height; y0 += 16) {
    const int rows = std::min(16, full.height - y0);
    const cv::Rect band(0, y0, full.width, rows);
    const cv::Mat alpha = upsample_region(weight_small, full, band);
    int x0 = full.width, x1 = 0;
    for (int y = 0; y < rows; ++y) {
      for (int x = 0; x < full.width; ++x) {
        const float a = alpha.at<float>(y, x);
        up.mask.at<unsigned char>(y0 + y, x) = a >= 0.5f ? 255 : 0;
        if (a > 0.0f) x0 = std::min(x0, x), x1 = std::max(x1, x + 1);
      }
    }
    base(band).copyTo(up.image(band));
    if (keep_float) (base_rgb.empty() ? to_rgb_float(base, band) : base_rgb(band)).copyTo(up.rgb(band));
    if (x0 >= x1) continue;
    const cv::Rect span(x0, y0, x1 - x0, rows);
    cv::Mat span_alpha;
    const cv::Mat blended = blend_upsampled(base_rgb.empty() ? to_rgb_float(base, span) : base_rgb(span), span, full,
                                            rgb_small, weight_small, span_alpha);
    store_rgb_float(blended, up.image, span.tl());
    if (keep_float) blended.copyTo(up.rgb(span));
    for (int y = 0; y < rows; ++y) {
      for (int x = 0; x < span.width; ++x) {
        if (span_alpha.at<float>(y, x) <= 0.0f)
          std::memcpy(up.image.ptr<unsigned char>(y0 + y) + (x0 + x) * pixel_bytes,
                      base.ptr<unsigned char>(y0 + y) + (x0 + x) * pixel_bytes, pixel_bytes);
      }
    }
  }
  copy_alpha(base, up.image);
  return up;
}

bool same_bytes(const cv::Mat& a, const cv::Mat& b) {
  if (a.empty() || b.empty()) return a.empty() == b.empty();
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int y = 0; y < a.rows; ++y) {
    if (std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()) != 0) return false;
  }
  return true;
}

TEST(WorkingScale, CompositeIsTheWholeBandCompositeByteForByte) {
  cv::RNG rng(77);
  for (int trial = 0; trial < 60; ++trial) {
    const int depth = trial % 2 ? CV_16U : CV_8U, channels = 1 + trial % 4;
    const cv::Size small(rng.uniform(1, 120), rng.uniform(1, 40));
    const cv::Size full(small.width * rng.uniform(1, 4) + rng.uniform(0, 5), small.height * rng.uniform(1, 4) + rng.uniform(0, 5));
    cv::Mat base(full, CV_MAKETYPE(depth, channels));
    rng.fill(base, cv::RNG::UNIFORM, 0, depth == CV_16U ? 65536 : 256);
    cv::Mat rgb_small(small, CV_32FC3);
    rng.fill(rgb_small, cv::RNG::UNIFORM, 0.0, 1.0);
    // An 8-bit mask, as both callers have: none, scattered drops, or most of the image.
    cv::Mat mask8(small, CV_8U, cv::Scalar(0));
    const int kind = trial % 3;
    for (int k = kind == 0 ? 0 : rng.uniform(1, 12); k > 0; --k)
      cv::circle(mask8, {rng.uniform(0, small.width), rng.uniform(0, small.height)}, rng.uniform(0, 3),
                 cv::Scalar(kind == 2 ? 255 : rng.uniform(1, 256)), cv::FILLED);
    if (kind == 2) mask8.rowRange(0, small.height / 2).setTo(255);
    cv::Mat weight;
    mask8.convertTo(weight, CV_32F, 1.0 / 255.0);
    const bool keep_float = trial % 5 < 2;
    cv::Mat base_rgb;
    if (trial % 7 == 3) {  // the large-drop pass: a float base of its own
      base_rgb.create(full, CV_32FC3);
      rng.fill(base_rgb, cv::RNG::UNIFORM, 0.0, 1.0);
    }
    const detail::Upsampled want = reference_composite(base, base_rgb, rgb_small, weight, keep_float);
    for (int workers = 1; workers <= 5; workers += 2) {
      SCOPED_TRACE(::testing::Message() << "trial " << trial << " type " << base.type() << " small " << small << " full "
                                        << full << " keep_float " << keep_float << " workers " << workers);
      const detail::Upsampled got = detail::composite_upsampled(base, base_rgb, rgb_small, weight, keep_float, workers);
      EXPECT_TRUE(same_bytes(got.image, want.image));
      EXPECT_TRUE(same_bytes(got.mask, want.mask));
      EXPECT_TRUE(same_bytes(got.rgb, want.rgb));
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
  // At scale 1 the refine network's output everywhere (the contract's step 7), unless the
  // pixels outside the mask are to be kept (remover.h, keep_outside_mask).
  RemoveOptions native = none;
  native.scale = 1.0;
  const RemoveResult r = smoke().run(rgb8, native);
  EXPECT_EQ(r.scale, 1.0);
  EXPECT_GT(max_abs_diff(r.image, rgb8), 0) << "the refine network ran on every pixel at scale 1";
  native.keep_outside_mask = true;
  EXPECT_EQ(max_abs_diff(smoke().run(rgb8, native).image, rgb8), 0);
}

// With keep_outside_mask, images the networks see at full size (at or below the working size,
// or scale 1) keep every pixel outside the final mask bit for bit, in every pixel format, as
// larger images do; inside it they take the pipeline's output (the contract's step 7: the
// refine network's output everywhere, the default, which changes pixels outside the mask too).
TEST(WorkingScale, ImagesAtFullSizeKeepTheirPixelsOutsideTheMask) {
  const cv::Mat rgb8 = make_image(480, 320, 44);
  cv::Mat rgb16, rgba8, grey8;
  rgb8.convertTo(rgb16, CV_16U, 257.0);
  rgb16.at<cv::Vec3w>(9, 4) = cv::Vec3w(3, 65533, 40001);
  cv::cvtColor(rgb8, rgba8, cv::COLOR_RGB2RGBA);
  cv::Mat alpha(rgb8.size(), CV_8U);
  cv::randu(alpha, 0, 255);
  cv::insertChannel(alpha, rgba8, 3);
  cv::cvtColor(rgb8, grey8, cv::COLOR_RGB2GRAY);
  for (const cv::Mat* m : {&rgb8, static_cast<const cv::Mat*>(&rgb16), static_cast<const cv::Mat*>(&rgba8),
                           static_cast<const cv::Mat*>(&grey8)}) {
    SCOPED_TRACE("type " + std::to_string(m->type()));
    // The smoke detector's map is flat-ish: the first threshold that masks between a twentieth
    // and nineteen twentieths of the image.
    RemoveOptions o;
    o.keep_outside_mask = true;
    RemoveResult r;
    for (const double t : {0.5, 0.45, 0.4, 0.35, 0.3, 0.25, 0.2, 0.15, 0.1, 0.05, 0.02}) {
      o.threshold = t;
      r = smoke().run(*m, o);
      const double covered = cv::countNonZero(r.mask) / static_cast<double>(r.mask.total());
      if (covered > 0.05 && covered < 0.95) break;
    }
    ASSERT_EQ(r.scale, 1.0);
    const double covered = cv::countNonZero(r.mask) / static_cast<double>(r.mask.total());
    ASSERT_GT(covered, 0.05) << "no threshold masks part of the image";
    ASSERT_LT(covered, 0.95);
    RemoveOptions paper = o;
    paper.keep_outside_mask = false;
    const RemoveResult everywhere = smoke().run(*m, paper);
    EXPECT_EQ(cv::countNonZero(everywhere.mask != r.mask), 0) << "the same mask either way";
    const double one_level = m->depth() == CV_16U ? 257.0 : 1.0;
    std::vector<cv::Mat> in, got, rfn;
    cv::split(*m, in);
    cv::split(r.image, got);
    cv::split(everywhere.image, rfn);
    int outside_changed_by_rfn = 0;
    for (int c = 0; c < m->channels(); ++c) {
      SCOPED_TRACE("channel " + std::to_string(c));
      // Outside the mask, and the alpha channel everywhere: the input's own values.
      const cv::Mat kept = m->channels() == 4 && c == 3 ? cv::Mat(r.mask.size(), CV_8U, cv::Scalar(255)) : r.mask == 0;
      ASSERT_EQ(cv::countNonZero((got[c] != in[c]) & kept), 0) << "outside the mask (or alpha)";
      outside_changed_by_rfn += cv::countNonZero((rfn[c] != in[c]) & kept);
      cv::Mat inside_diff;
      cv::absdiff(got[c], rfn[c], inside_diff);
      double worst = 0;
      cv::minMaxLoc(inside_diff, nullptr, &worst, nullptr, nullptr, ~kept);
      ASSERT_LE(worst, one_level) << "inside the mask";
    }
    EXPECT_GT(outside_changed_by_rfn, 0) << "the refine network changes pixels outside the mask when kept everywhere";
  }
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

// --keep-outside-mask reaches the remover: a 320x240 image (seen at full size) and its mask
// written; every pixel the mask leaves out is the input's with the flag, and not all without.
TEST(WorkingScaleCli, KeepOutsideMaskKeepsTheInputsPixels) {
  TempDir tmp;
  const cv::Mat img = make_image(320, 240, 45);
  write_image(tmp / "in.png", img);
  for (const bool keep : {true, false}) {
    std::vector<std::string> args = {"in.png", "out.png", "--models", smoke_models().string(), "--mask", "mask.png",
                                     "--threshold", "0.3"};
    if (keep) args.push_back("--keep-outside-mask");
    const RunResult r = run_remove(args, tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    const auto out = read_image(tmp / "out.png");
    const auto mask = read_image(tmp / "mask.png");
    ASSERT_TRUE(out && mask);
    ASSERT_GT(cv::countNonZero(mask->pixels), 0);
    ASSERT_LT(cv::countNonZero(mask->pixels), static_cast<int>(mask->pixels.total()));
    cv::Mat differs;
    cv::absdiff(out->pixels, img, differs);
    cv::cvtColor(differs, differs, cv::COLOR_RGB2GRAY);
    const int outside_changed = cv::countNonZero((differs > 0) & (mask->pixels == 0));
    if (keep) {
      EXPECT_EQ(outside_changed, 0);
    } else {
      EXPECT_GT(outside_changed, 0) << "the refine network's output everywhere by default";
    }
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

// The removal library (raindrop::removal::Remover) on the fixture models: wiring of the
// stages, stability on extreme inputs, odd sizes, tiling, formats, model checks.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>

#include "raindrop/common/error.h"
#include "raindrop/remove/edge_map.h"
#include "raindrop/remove/model.h"
#include "raindrop/remove/pixels.h"
#include "raindrop/remove/remover.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

SessionConfig two_threads() {
  SessionConfig c;
  c.threads = 2;
  return c;
}

// One Remover for the whole suite: loading takes longer than running the tiny graphs.
Remover& smoke() {
  static Remover r(smoke_models(), two_threads());
  return r;
}

// The pipeline at the image's own size (the working-scale tests below set their own scale).
RemoveOptions with_float() {
  RemoveOptions o;
  o.keep_float = true;
  o.scale = 1.0;
  return o;
}

// with_float() in tiles of at most `tile` pixels (0: the whole image at once). The tiling tests
// compare tiles with the whole image, so they leave out the fill from the surround: it is
// decided per tile (surround_fill.h), and a part that a tile's edge cuts is judged by its piece.
RemoveOptions with_float(int tile, int overlap) {
  RemoveOptions o = with_float();
  o.surround_fill_area = 0;
  o.tile = tile;
  o.overlap = overlap;
  return o;
}

// Every value finite and in [0, 1].
::testing::AssertionResult all_in_unit_range(const cv::Mat& f) {
  if (f.depth() != CV_32F) return ::testing::AssertionFailure() << "not float";
  const cv::Mat flat = f.reshape(1);
  for (int y = 0; y < flat.rows; ++y) {
    for (int x = 0; x < flat.cols; ++x) {
      const float v = flat.at<float>(y, x);
      if (!std::isfinite(v) || v < 0.0f || v > 1.0f)
        return ::testing::AssertionFailure() << "value " << v << " at row " << y << " col " << x;
    }
  }
  return ::testing::AssertionSuccess();
}

bool mask_is_binary(const cv::Mat& m) { return cv::countNonZero((m != 0) & (m != 255)) == 0; }

// NCHW planes of an 8-bit RGB image (v / 255), and the inverse.
std::vector<float> planes(const cv::Mat& rgb8) {
  const cv::Mat f = to_rgb_float(rgb8, cv::Rect(0, 0, rgb8.cols, rgb8.rows));
  std::vector<float> p(3 * f.total());
  for (int y = 0; y < f.rows; ++y)
    for (int x = 0; x < f.cols; ++x)
      for (int c = 0; c < 3; ++c) p[c * f.total() + y * f.cols + x] = f.at<cv::Vec3f>(y, x)[c];
  return p;
}

cv::Mat from_planes(const std::vector<float>& p, int h, int w) {
  cv::Mat f(h, w, CV_32FC3);
  const size_t n = static_cast<size_t>(h) * w;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) f.at<cv::Vec3f>(y, x)[c] = clamp01(p[c * n + y * w + x]);
  return f;
}

float max_float_diff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  double mx = 0;
  cv::minMaxLoc(d.reshape(1), nullptr, &mx);
  return static_cast<float>(mx);
}

TEST(Remover, ReadsTheModelMetadata) {
  const ModelInfo& info = smoke().info();
  EXPECT_EQ(info.config, "smoke");
  EXPECT_EQ(info.pad_multiple, 2);  // the graphs say 1; always even (model.cpp says why)
  EXPECT_DOUBLE_EQ(info.threshold, 0.2);
  EXPECT_EQ(info.dilation, 3);
}

// With threshold 1 the mask is empty (P <= 1), so B = R and the output is clamp(RFN(R));
// with threshold 0 it is full (a sigmoid is > 0 here), so the output is clamp(RFN(clamp(3RN(R, E)))).
// Checked against the graphs run directly, which pins the wiring between the stages.
TEST(Remover, EmptyAndFullMasksWireTheStagesAsTheContractSays) {
  const cv::Mat img = make_image(46, 32, 1);  // even: no padding (odd sizes are padded, AnySizeWorks)
  const int h = img.rows, w = img.cols;
  Models models(smoke_models(), two_threads());
  const std::vector<float> r = planes(img);
  std::vector<float> rfn_of_r(r.size());
  models.rfn().run({r.data()}, h, w, rfn_of_r.data());
  std::vector<float> e(static_cast<size_t>(h) * w);
  const cv::Mat edge = edge_map(to_rgb_float(img, cv::Rect(0, 0, w, h)));
  std::memcpy(e.data(), edge.ptr<float>(), e.size() * sizeof(float));
  std::vector<float> ihat(r.size()), out_full(r.size());
  models.rrn().run({r.data(), e.data()}, h, w, ihat.data());
  for (float& v : ihat) v = clamp01(v);
  models.rfn().run({ihat.data()}, h, w, out_full.data());

  RemoveOptions none = with_float();
  none.threshold = 1.0;
  const RemoveResult a = smoke().run(img, none);
  EXPECT_EQ(cv::countNonZero(a.mask), 0);
  EXPECT_LE(max_float_diff(a.rgb, from_planes(rfn_of_r, h, w)), 1e-6f);

  RemoveOptions all = with_float();
  all.threshold = 0.0;
  const RemoveResult b = smoke().run(img, all);
  EXPECT_EQ(cv::countNonZero(b.mask), h * w);
  EXPECT_LE(max_float_diff(b.rgb, from_planes(out_full, h, w)), 1e-6f);
  EXPECT_GT(max_float_diff(a.rgb, b.rgb), 1e-3f) << "the mask must make a difference";
}

// Small parts of the mask over a smooth image are filled from their surround
// (surround_fill.h): the output is clamp(RFN(B)) with B built from the 3RN's output with those
// parts replaced by the push-pull fill, checked against the graphs and the fill run directly.
TEST(Remover, SmallPartsOverSmoothSurroundingsAreFilledBeforeTheRfn) {
  const int h = 48, w = 64;
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<unsigned char>(90 + x), static_cast<unsigned char>(120 + y / 2),
                                          static_cast<unsigned char>(160 - x / 2));
  cv::circle(img, {20, 16}, 3, cv::Scalar(30, 30, 30), cv::FILLED);  // two dark dots for the detector
  cv::circle(img, {45, 32}, 3, cv::Scalar(30, 30, 30), cv::FILLED);
  Models models(smoke_models(), two_threads());
  const std::vector<float> r = planes(img);
  std::vector<float> e(static_cast<size_t>(h) * w), p(static_cast<size_t>(h) * w);
  const cv::Mat edge = edge_map(to_rgb_float(img, cv::Rect(0, 0, w, h)));
  std::memcpy(e.data(), edge.ptr<float>(), e.size() * sizeof(float));
  models.rdn().run({r.data()}, h, w, p.data());
  // A threshold that keeps the 2% most probable pixels: small parts of the mask.
  std::vector<float> sorted = p;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() * 98 / 100, sorted.end());
  RemoveOptions o = with_float();
  o.threshold = sorted[sorted.size() * 98 / 100];
  o.surround_fill_mad = 255.0;  // the dots may sit in any part's surround: the wiring is what is checked
  o.surround_fill_rim = 0;      // the parts as found (their growth into rims: below)
  const RemoveResult on = smoke().run(img, o);
  ASSERT_GT(on.surround_filled, 0) << "mask " << cv::countNonZero(on.mask) << " px";
  ASSERT_LT(cv::countNonZero(on.mask), h * w / 4);

  std::vector<float> ihat(r.size()), out(r.size());
  models.rrn().run({r.data(), e.data()}, h, w, ihat.data());
  for (float& v : ihat) v = clamp01(v);
  // The smoke models carry no raindrop.surround_fill_area: the default area.
  cv::Mat found = on.mask.clone();
  EXPECT_EQ(fill_small_drops_from_surround(r.data(), found, kSurroundFillArea, o.surround_fill_mad, ihat),
            on.surround_filled);
  const size_t plane = static_cast<size_t>(h) * w;
  for (int c = 0; c < 3; ++c)
    for (size_t i = 0; i < plane; ++i)
      if (!on.mask.at<unsigned char>(static_cast<int>(i / w), static_cast<int>(i % w))) ihat[c * plane + i] = r[c * plane + i];
  models.rfn().run({ihat.data()}, h, w, out.data());
  EXPECT_LE(max_float_diff(on.rgb, from_planes(out, h, w)), 1e-6f);

  RemoveOptions off = o;
  off.surround_fill_area = 0;
  const RemoveResult without = smoke().run(img, off);
  EXPECT_EQ(without.surround_filled, 0);
  EXPECT_EQ(cv::countNonZero(without.mask != on.mask), 0);
  EXPECT_GT(max_float_diff(on.rgb, without.rgb), 1e-4f) << "the fill must make a difference";

  // Grown into their rims, the filled parts only add to the mask (surround_fill.h).
  RemoveOptions rims = o;
  rims.surround_fill_rim = kSurroundFillRim;
  const RemoveResult grown = smoke().run(img, rims);
  EXPECT_EQ(cv::countNonZero(on.mask & ~grown.mask), 0);
  EXPECT_EQ(grown.surround_filled, on.surround_filled);
}

// The fill's area limit is given with the long side at 512 (surround_fill.h): an image of long
// side 768 processed at scale 1 sees its drops 1.5 times as wide, so the limit is 2.25 times the
// option. Chosen here so that the largest part of the mask is above the option and within 2.25x.
TEST(Remover, TheFillLimitFollowsTheScale) {
  EXPECT_EQ(surround_fill_area_at_scale(150, {1280, 720}, 0.4), 150);  // the default scale: as given
  EXPECT_EQ(surround_fill_area_at_scale(150, {1280, 720}, 0.6), 338);  // (0.6 / 0.4)^2 = 2.25: 337.5 rounds up
  EXPECT_EQ(surround_fill_area_at_scale(1 << 30, {8192, 8192}, 1.0), std::numeric_limits<int>::max());  // clamped
  EXPECT_EQ(surround_fill_area_at_scale(150, {720, 480}, 1.0), 297);   // (720 / 512)^2 = 1.98
  EXPECT_EQ(surround_fill_area_at_scale(150, {256, 256}, 1.0), 150);   // never enlarged: scale 1 is 512's
  EXPECT_EQ(surround_fill_area_at_scale(150, {256, 256}, 0.5), 38);
  EXPECT_EQ(surround_fill_area_at_scale(0, {1280, 720}, 1.0), 0);      // off stays off
  // The rims' reach scales with the width of a drop, not its area.
  EXPECT_EQ(surround_fill_rim_at_scale(3, {1280, 720}, 0.4), 3);  // the default scale: as given
  EXPECT_EQ(surround_fill_rim_at_scale(3, {1280, 720}, 1.0), 8);  // 2.5 x 3 = 7.5 rounds up
  EXPECT_EQ(surround_fill_rim_at_scale(3, {1280, 720}, 0.6), 5);  // 4.5 (4.4999999999999991 in doubles) rounds up
  EXPECT_EQ(surround_fill_rim_at_scale(1, {1280, 720}, 0.6), 2);  // 1.5 likewise
  EXPECT_EQ(surround_fill_rim_at_scale(3, {1280, 720}, 0.1), 1);  // 0.75: at least one step while on
  EXPECT_EQ(surround_fill_rim_at_scale(3, {256, 256}, 1.0), 3);   // never enlarged: scale 1 is 512's
  EXPECT_EQ(surround_fill_rim_at_scale(0, {1280, 720}, 1.0), 0);  // off stays off

  const int h = 64, w = 768;
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<unsigned char>(90 + x / 8), static_cast<unsigned char>(120 + y / 2),
                                          static_cast<unsigned char>(160 - x / 16));
  for (int i = 0; i < 8; ++i) cv::circle(img, {40 + 90 * i, 20 + 3 * i}, 2 + i, cv::Scalar(30, 30, 30), cv::FILLED);
  Models models(smoke_models(), two_threads());
  const std::vector<float> r = planes(img);
  std::vector<float> p(static_cast<size_t>(h) * w);
  models.rdn().run({r.data()}, h, w, p.data());
  std::vector<float> sorted = p;  // a threshold that keeps the 3% most probable pixels: small parts
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() * 97 / 100, sorted.end());
  RemoveOptions o;
  o.scale = 1.0;
  o.large_drops = false;
  o.threshold = sorted[sorted.size() * 97 / 100];
  o.surround_fill_mad = 255.0;  // every surround counts as smooth: the limit is what is checked
  o.surround_fill_area = 0;
  o.surround_fill_rim = 0;  // parts as found, so the masks with and without the fill are one
  const RemoveResult off = smoke().run(img, o);
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(off.mask, labels, stats, centroids, 8) - 1;
  ASSERT_GE(n, 2) << "the detector must find parts of several sizes";
  int largest = 0;
  for (int i = 1; i <= n; ++i) largest = std::max(largest, stats.at<int>(i, cv::CC_STAT_AREA));
  o.surround_fill_area = (largest * 4 + 8) / 9;  // 2.25 o >= largest > o
  ASSERT_GT(largest, o.surround_fill_area);
  const RemoveResult on = smoke().run(img, o);
  EXPECT_EQ(cv::countNonZero(on.mask != off.mask), 0);
  int at_option = 0, at_scale = 0;
  surround_fill_mask(on.mask, r.data(), *o.surround_fill_area, o.surround_fill_mad, &at_option);
  surround_fill_mask(on.mask, r.data(), surround_fill_area_at_scale(*o.surround_fill_area, img.size(), 1.0),
                     o.surround_fill_mad, &at_scale);
  EXPECT_EQ(at_scale, n);
  EXPECT_LT(at_option, at_scale);
  EXPECT_EQ(on.surround_filled, at_scale);
}

TEST(Remover, DilationGrowsTheMask) {
  const cv::Mat img = make_image(80, 60, 2);
  RemoveOptions o;
  o.dilation = 1;
  const int n1 = cv::countNonZero(smoke().run(img, o).mask);
  o.dilation = 7;
  const int n7 = cv::countNonZero(smoke().run(img, o).mask);
  ASSERT_GT(n1, 0) << "test image should trigger some detections";
  ASSERT_LT(n1, 80 * 60);
  EXPECT_GT(n7, n1);
}

TEST(Remover, ExtremeInputsGiveFiniteOutputsInRange) {
  const int w = 48, h = 40;
  std::vector<std::pair<std::string, cv::Mat>> inputs;
  inputs.emplace_back("black", cv::Mat(h, w, CV_8UC3, cv::Scalar::all(0)));
  inputs.emplace_back("white", cv::Mat(h, w, CV_8UC3, cv::Scalar::all(255)));
  cv::Mat saturated(h, w, CV_8UC3);
  const cv::Vec3b colours[] = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {255, 255, 0}, {255, 0, 255}, {0, 255, 255}};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) saturated.at<cv::Vec3b>(y, x) = colours[(x / 8 + y / 8) % 6];
  inputs.emplace_back("saturated colours", saturated);
  cv::Mat noise8(h, w, CV_8UC3), noise16(h, w, CV_16UC3), noise_f(h, w, CV_32FC3);
  cv::RNG rng(5);
  rng.fill(noise8, cv::RNG::UNIFORM, 0, 256);
  rng.fill(noise16, cv::RNG::UNIFORM, 0, 65536);
  rng.fill(noise_f, cv::RNG::UNIFORM, -1.0, 2.0);  // out of range on purpose: clamped on the way in
  noise_f.at<cv::Vec3f>(3, 3) = cv::Vec3f(std::numeric_limits<float>::quiet_NaN(), 0.5f, 0.5f);
  inputs.emplace_back("uniform noise 8-bit", noise8);
  inputs.emplace_back("uniform noise 16-bit", noise16);
  inputs.emplace_back("float noise with NaN", noise_f);
  for (const auto& [name, img] : inputs) {
    SCOPED_TRACE(name);
    for (const double t : {0.0, 0.2, 1.0}) {
      RemoveOptions o = with_float();
      o.threshold = t;
      const RemoveResult r = smoke().run(img, o);
      ASSERT_EQ(r.rgb.size(), img.size());
      EXPECT_TRUE(all_in_unit_range(r.rgb)) << "threshold " << t;
      EXPECT_TRUE(mask_is_binary(r.mask));
      EXPECT_EQ(r.image.type(), img.type());
      if (img.depth() == CV_32F) {
        EXPECT_TRUE(all_in_unit_range(r.image));
      }
    }
  }
}

TEST(Remover, AnySizeWorks) {
  for (const cv::Size s : {cv::Size(1, 1), cv::Size(2, 3), cv::Size(3, 2), cv::Size(7, 5), cv::Size(33, 17),
                           cv::Size(1, 40), cv::Size(40, 1)}) {
    SCOPED_TRACE(::testing::PrintToString(s));
    const cv::Mat img = make_image(s.width, s.height, s.area());
    const RemoveResult r = smoke().run(img, with_float());
    EXPECT_EQ(r.image.size(), s);
    EXPECT_EQ(r.image.type(), CV_8UC3);
    EXPECT_EQ(r.mask.size(), s);
    EXPECT_TRUE(all_in_unit_range(r.rgb));
    EXPECT_EQ(r.tiles_x * r.tiles_y, 1);
    // Padded to even sizes (model.cpp says why), so the networks see a little more.
    EXPECT_DOUBLE_EQ(r.network_pixels, static_cast<double>((s.width + 1) / 2 * 2) * ((s.height + 1) / 2 * 2));
  }
}

TEST(Remover, LargeNonMultipleSizeIsTiledAndMatchesTheWholeImage) {
  // 1031 x 517 with the default 1024 tile: two windows across.
  const cv::Mat img = make_image(1031, 517, 9);
  const RemoveResult tiled = smoke().run(img, with_float(kDefaultTile, kDefaultOverlap));
  EXPECT_EQ(tiled.tiles_x, 2);
  EXPECT_EQ(tiled.tiles_y, 1);
  EXPECT_EQ(tiled.image.size(), img.size());
  EXPECT_TRUE(all_in_unit_range(tiled.rgb));
  const RemoveResult ref = smoke().run(img, with_float(0, kDefaultOverlap));
  EXPECT_EQ(cv::countNonZero(tiled.mask != ref.mask), 0);
  EXPECT_LE(max_float_diff(tiled.rgb, ref.rgb), 1e-4f);
  EXPECT_LE(max_abs_diff(tiled.image, ref.image), 1);
}

// The fixture's receptive radius for the output is RFN 4 + 3RN 7 = 11 pixels; with an
// overlap of 48 the blend ramps start 12 pixels inside each window, so the tiled output is
// the whole-image output up to float rounding, and the mask is the same bit for bit.
TEST(Remover, TiledEqualsWholeWhenTheOverlapCoversTheReceptiveField) {
  const cv::Mat img = make_image(300, 211, 3);
  const RemoveResult ref = smoke().run(img, with_float(0, 48));
  const RemoveResult t = smoke().run(img, with_float(128, 48));
  EXPECT_GE(t.tiles_x, 3);
  EXPECT_GE(t.tiles_y, 2);
  EXPECT_EQ(cv::countNonZero(t.mask != ref.mask), 0);
  EXPECT_LE(max_float_diff(t.rgb, ref.rgb), 1e-4f);
  EXPECT_LE(max_abs_diff(t.image, ref.image), 1);
}

// The fill's parts grow into their rims (surround_fill.h) in every tile from the mask as the
// detector found it, not from another tile's growth: dark dots with lighter rings on a smooth
// gradient, where the rings join the parts, give the same mask tiled as whole, and outputs no
// further apart than without the rims.
TEST(Remover, RimsGrowTheSameTiledAsWhole) {
  cv::Mat img(211, 300, CV_8UC3);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<unsigned char>(100 + x / 4), static_cast<unsigned char>(140 + y / 4), 170);
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 3; ++j) {
      const cv::Point c(30 + 60 * i, 35 + 70 * j);
      cv::circle(img, c, 3, cv::Scalar(60, 60, 60), cv::FILLED);
      cv::circle(img, c, 2, cv::Scalar(20, 20, 20), cv::FILLED);
    }
  RemoveOptions whole = with_float(0, 48);
  whole.threshold = 0.25;
  // Parts of 12-62 px as found and 38-87 grown: a limit between the two fills every one as found
  // and refuses the larger ones grown, as a tile that saw another tile's growth would.
  whole.surround_fill_area = 65;
  whole.surround_fill_rim = 5;  // the fixture detector's parts sit a few pixels off its dots
  RemoveOptions found = whole;
  found.surround_fill_rim = 0;
  const RemoveResult as_found = smoke().run(img, found);
  const RemoveResult ref = smoke().run(img, whole);
  ASSERT_GT(ref.surround_filled, 0);
  EXPECT_EQ(cv::countNonZero(as_found.mask & ~ref.mask), 0) << "growth only adds";
  ASSERT_GT(cv::countNonZero(ref.mask != as_found.mask), 0) << "the rings must join the parts here";
  RemoveOptions tiled = whole, tiled_found = found;
  tiled.tile = tiled_found.tile = 128;
  const RemoveResult t = smoke().run(img, tiled), t_found = smoke().run(img, tiled_found);
  EXPECT_GE(t.tiles_x * t.tiles_y, 4);
  EXPECT_EQ(cv::countNonZero(t.mask != ref.mask), 0);
  // The fill itself is decided per tile (a part a window's edge cuts is judged by its piece), so
  // tiled and whole outputs differ with it on; the rims add nothing to that.
  EXPECT_LE(max_float_diff(t.rgb, ref.rgb), max_float_diff(t_found.rgb, as_found.rgb) + 1e-4f);
}

// With two threads a single tile's RDN and 3RN run side by side on one thread each, and tiled
// images run on sessions of their own with both threads; with one thread everything runs in
// order on one set of sessions. The output must not depend on that: same mask bit for bit,
// float output equal up to rounding.
TEST(Remover, SideBySideEqualsInOrder) {
  SessionConfig one;
  one.threads = 1;
  Remover in_order(smoke_models(), one);
  ASSERT_EQ(in_order.run(make_image(8, 8, 1)).image.size(), cv::Size(8, 8));
  EXPECT_EQ(smoke().run(make_image(8, 8, 1)).image.size(), cv::Size(8, 8));
  for (const int tile : {0, 96}) {
    const cv::Mat img = make_image(200, 211, 21);
    const RemoveOptions o = with_float(tile, 16);
    const RemoveResult a = in_order.run(img, o), b = smoke().run(img, o);
    EXPECT_EQ(a.tiles_x * a.tiles_y, tile ? 9 : 1);
    EXPECT_EQ(cv::countNonZero(a.mask != b.mask), 0) << "tile " << tile;
    EXPECT_LE(max_float_diff(a.rgb, b.rgb), 1e-5f) << "tile " << tile;
    EXPECT_LE(max_abs_diff(a.image, b.image), 1) << "tile " << tile;
  }
}

// A small overlap puts tile-edge effects inside the ramps: the seams are cross-faded and the
// difference stays small (stated bound: mean < 1/255, max < 40/255 on this random-weight
// model). The mask is still exactly the whole-image mask: each pixel's probability comes
// from the tile that owns it, >= overlap/2 = 8 pixels from that tile's inner edges, more
// than the RDN's receptive radius of 7.
TEST(Remover, SmallOverlapStillBlendsSeams) {
  const cv::Mat img = make_image(300, 211, 4);
  const RemoveResult ref = smoke().run(img, with_float(0, 16));
  const RemoveResult t = smoke().run(img, with_float(96, 16));
  EXPECT_GE(t.tiles_x * t.tiles_y, 6);
  EXPECT_TRUE(all_in_unit_range(t.rgb));
  cv::Mat d;
  cv::absdiff(t.rgb, ref.rgb, d);
  EXPECT_LT(cv::mean(d)[0], 1.0 / 255.0);
  EXPECT_LT(max_float_diff(t.rgb, ref.rgb), 40.0f / 255.0f);
  EXPECT_EQ(cv::countNonZero(t.mask != ref.mask), 0);
}

TEST(Remover, FormatsAreKept) {
  const cv::Mat rgb8 = make_image(37, 29, 11);
  cv::Mat grey8;
  cv::cvtColor(rgb8, grey8, cv::COLOR_RGB2GRAY);
  cv::Mat alpha8(rgb8.size(), CV_8U);
  cv::randu(alpha8, 0, 256);
  cv::Mat rgba8, ga8, rgb16, rgba16, grey16;
  cv::merge(std::vector<cv::Mat>{rgb8, alpha8}, rgba8);
  cv::merge(std::vector<cv::Mat>{grey8, alpha8}, ga8);
  rgb8.convertTo(rgb16, CV_16U, 257.0);
  rgba8.convertTo(rgba16, CV_16U, 257.0);
  grey8.convertTo(grey16, CV_16U, 257.0);

  const RemoveResult base = smoke().run(rgb8, with_float());
  for (const cv::Mat* m : std::vector<const cv::Mat*>{&rgb8, &grey8, &rgba8, &ga8, &rgb16, &rgba16, &grey16}) {
    SCOPED_TRACE("type " + std::to_string(m->type()));
    const RemoveResult r = smoke().run(*m);
    ASSERT_EQ(r.image.type(), m->type());
    ASSERT_EQ(r.image.size(), m->size());
    if (m->channels() == 2 || m->channels() == 4) {
      cv::Mat a_in, a_out;
      cv::extractChannel(*m, a_in, m->channels() - 1);
      cv::extractChannel(r.image, a_out, m->channels() - 1);
      EXPECT_EQ(cv::countNonZero(a_in != a_out), 0) << "alpha must pass through unchanged";
    }
  }
  // RGBA's colour is RGB's (alpha is not composited into the colour).
  const RemoveResult rgba = smoke().run(rgba8);
  cv::Mat rgb_of_rgba;
  cv::cvtColor(rgba.image, rgb_of_rgba, cv::COLOR_RGBA2RGB);
  EXPECT_EQ(max_abs_diff(rgb_of_rgba, base.image), 0);
  // 16-bit v * 257 is the same float as 8-bit v / 255: same result at 16-bit precision.
  const RemoveResult r16 = smoke().run(rgb16);
  cv::Mat r16_as_8;
  r16.image.convertTo(r16_as_8, CV_8U, 1.0 / 257.0);
  EXPECT_LE(max_abs_diff(r16_as_8, base.image), 1);
  // Grey: the networks see (g, g, g); the output is the luma of their RGB output.
  cv::Mat grey_as_rgb;
  cv::cvtColor(grey8, grey_as_rgb, cv::COLOR_GRAY2RGB);
  const RemoveResult g_rgb = smoke().run(grey_as_rgb, with_float());
  const RemoveResult g = smoke().run(grey8);
  cv::Mat luma(grey8.size(), CV_8U);
  store_rgb_float(g_rgb.rgb, luma, 0);
  EXPECT_EQ(max_abs_diff(g.image, luma), 0);
  EXPECT_EQ(cv::countNonZero(g.mask != g_rgb.mask), 0);
}

// --fine-drops (fine_drops.h) for every input format, at a scale where the fine copy is tiled
// and with the float output kept: the formats, the alpha and the size come through, the float
// output stays finite in [0, 1], and it changes only pixels within a pixel of the written mask.
// Where the working copy is the image's own size, it does not run.
TEST(Remover, FineDropsKeepEveryFormat) {
  // Small bright dots on a flat ground: the smoke models' detector marks them at 0.3, and their
  // surround is smooth, so the fine pass fills them.
  cv::Mat rgb8(150, 200, CV_8UC3, cv::Scalar(120, 130, 140));
  for (int i = 0; i < 8; ++i) cv::circle(rgb8, {20 + 22 * i, 40 + 10 * (i % 3)}, 2, cv::Scalar(250, 250, 250), cv::FILLED);
  cv::Mat grey8, alpha8(rgb8.size(), CV_8U), rgba8, ga8, rgb16, grey16, rgb32;
  cv::cvtColor(rgb8, grey8, cv::COLOR_RGB2GRAY);
  cv::randu(alpha8, 0, 256);
  cv::merge(std::vector<cv::Mat>{rgb8, alpha8}, rgba8);
  cv::merge(std::vector<cv::Mat>{grey8, alpha8}, ga8);
  rgb8.convertTo(rgb16, CV_16U, 257.0);
  grey8.convertTo(grey16, CV_16U, 257.0);
  rgb8.convertTo(rgb32, CV_32F, 1.0 / 255.0);
  int filled = 0;
  for (const cv::Mat* m : std::vector<const cv::Mat*>{&rgb8, &grey8, &rgba8, &ga8, &rgb16, &grey16, &rgb32}) {
    SCOPED_TRACE("type " + std::to_string(m->type()));
    RemoveOptions off;
    off.scale = 0.5;
    off.keep_float = true;
    off.tile = 64;  // the fine copy (150x113) in tiles
    off.overlap = 16;
    off.threshold = 0.3;
    RemoveOptions on = off;
    on.fine_drops = true;
    const RemoveResult a = smoke().run(*m, off), b = smoke().run(*m, on);
    EXPECT_EQ(a.fine_scale, 0.0);
    EXPECT_DOUBLE_EQ(b.fine_scale, 0.75);
    ASSERT_EQ(b.image.type(), m->type());
    ASSERT_EQ(b.image.size(), m->size());
    ASSERT_EQ(b.mask.size(), m->size());
    EXPECT_TRUE(all_in_unit_range(b.rgb));
    if (m->channels() == 2) {
      cv::Mat a_out;
      cv::extractChannel(b.image, a_out, 1);
      EXPECT_EQ(cv::countNonZero(alpha8 != a_out), 0) << "alpha must pass through unchanged";
    }
    cv::Mat diff, changed, near_mask;
    cv::absdiff(a.rgb, b.rgb, diff);
    cv::cvtColor(diff, diff, cv::COLOR_RGB2GRAY);
    changed = diff > 0;
    cv::dilate(b.mask, near_mask, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
    EXPECT_EQ(cv::countNonZero(changed & ~near_mask), 0) << "changed away from the mask";
    EXPECT_EQ(cv::countNonZero((a.mask > 0) & ~(b.mask > 0)), 0) << "the mask lost pixels";
    if (b.fine_drops == 0) {
      EXPECT_EQ(cv::countNonZero(changed), 0);
    } else {
      EXPECT_GT(cv::countNonZero(changed), 0) << "parts filled, output unchanged";
    }
    filled += b.fine_drops;
  }
  EXPECT_GT(filled, 0) << "no image had a part to fill: the test checks nothing";
  // At the image's own scale there is nothing finer to see.
  RemoveOptions own;
  own.scale = 1.0;
  own.fine_drops = true;
  EXPECT_EQ(smoke().run(rgb8, own).fine_scale, 0.0);
  // Sizes that round alike at both scales: 3x3 at 0.5 and at 0.75 are both 2x2.
  RemoveOptions tiny = own;
  tiny.scale = 0.5;
  EXPECT_EQ(smoke().run(make_image(3, 3, 1), tiny).fine_scale, 0.0);
}

TEST(Remover, StageTimesAreRecorded) {
  const RemoveResult r = smoke().run(make_image(64, 48, 12));
  EXPECT_GT(r.times.rdn, 0.0);
  EXPECT_GT(r.times.rrn, 0.0);
  EXPECT_GT(r.times.rfn, 0.0);
  EXPECT_GE(r.times.total(), r.times.rdn + r.times.rrn + r.times.rfn);
  EXPECT_NE(r.times.describe().find("RDN"), std::string::npos);
}

TEST(Remover, RejectsBadOptions) {
  const cv::Mat img = make_image(16, 16, 1);
  RemoveOptions o;
  o.dilation = 0;
  EXPECT_THROW(smoke().run(img, o), raindrop::Error);
  o = {};
  o.threshold = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(smoke().run(img, o), raindrop::Error);
  o = {};
  o.tile = 10;
  EXPECT_THROW(smoke().run(img, o), raindrop::Error);
  o = {};
  o.surround_fill_area = -1;
  EXPECT_THROW(smoke().run(img, o), raindrop::Error);
  o = {};
  o.surround_fill_mad = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(smoke().run(img, o), raindrop::Error);
  EXPECT_THROW(smoke().run(cv::Mat()), raindrop::Error);
  EXPECT_THROW(smoke().run(cv::Mat(4, 4, CV_64FC3, cv::Scalar::all(0))), raindrop::Error);
}

// -------------------------------------------------------------------------------------------
// Model files that break the contract: one clear error naming the file.

class BadModels : public ::testing::Test {
 protected:
  void SetUp() override {
    for (const char* f : {"rdn.onnx", "rrn.onnx", "rfn.onnx"}) fs::copy_file(smoke_models() / f, tmp / f);
  }
  std::string load_error() {
    try {
      Models m(tmp.path(), two_threads());
    } catch (const raindrop::Error& e) {
      return e.what();
    }
    return "";
  }
  TempDir tmp;
};

TEST_F(BadModels, TheCopyLoads) { EXPECT_EQ(load_error(), ""); }

TEST_F(BadModels, MissingFile) {
  fs::remove(tmp / "rrn.onnx");
  const std::string e = load_error();
  EXPECT_NE(e.find("rrn.onnx"), std::string::npos) << e;
  EXPECT_NE(e.find("missing"), std::string::npos) << e;
}

TEST_F(BadModels, EmptyFile) {
  write_file(tmp / "rfn.onnx", "");
  const std::string e = load_error();
  EXPECT_NE(e.find("rfn.onnx"), std::string::npos) << e;
  EXPECT_NE(e.find("empty"), std::string::npos) << e;
}

TEST_F(BadModels, CorruptFile) {
  std::string bytes = read_file(tmp / "rdn.onnx");
  bytes.resize(bytes.size() / 3);
  write_file(tmp / "rdn.onnx", bytes);
  const std::string e = load_error();
  EXPECT_NE(e.find("rdn.onnx"), std::string::npos) << e;
  EXPECT_NE(e.find("cannot load"), std::string::npos) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos) << "one line: " << e;
}

TEST_F(BadModels, NotAModel) {
  write_file(tmp / "rdn.onnx", "this is not a protobuf\n");
  const std::string e = load_error();
  EXPECT_NE(e.find("rdn.onnx"), std::string::npos) << e;
}

TEST_F(BadModels, WrongGraphInPlace) {
  fs::copy_file(smoke_models() / "rfn.onnx", tmp / "rdn.onnx", fs::copy_options::overwrite_existing);
  const std::string e = load_error();
  EXPECT_NE(e.find("rdn.onnx"), std::string::npos) << e;
  EXPECT_NE(e.find("expected [image] / [mask_prob]"), std::string::npos) << e;
}

TEST_F(BadModels, MissingFolder) {
  try {
    Models m(tmp / "nope", two_threads());
    FAIL() << "expected an error";
  } catch (const raindrop::Error& e) {
    EXPECT_NE(std::string(e.what()).find("nope"), std::string::npos);
  }
}

// Workers that spin between operators take a core from the session running beside them.
TEST(Session, IdleWorkersSleepInsteadOfSpinning) {
  for (const int threads : {0, 1, 2}) {
    SessionConfig c;
    c.threads = threads;
    Ort::SessionOptions so = make_session_options(c);
    ASSERT_TRUE(so.HasConfigEntry(kIntraOpSpinningKey)) << threads << " threads";
    EXPECT_EQ(so.GetConfigEntry(kIntraOpSpinningKey), "0") << threads << " threads";
  }
}

TEST(Device, CudaIsAClearErrorWithoutTheProvider) {
  const auto providers = available_providers();
  if (std::find(providers.begin(), providers.end(), "CUDAExecutionProvider") != providers.end())
    GTEST_SKIP() << "this ONNX Runtime has CUDA; the error path cannot be checked here";
  SessionConfig c;
  c.device = Device::cuda;
  try {
    Models m(smoke_models(), c);
    FAIL() << "expected an error";
  } catch (const raindrop::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("no CUDA execution provider"), std::string::npos) << msg;
    EXPECT_NE(msg.find("CPUExecutionProvider"), std::string::npos) << msg;
  }
}

}  // namespace
}  // namespace removetest

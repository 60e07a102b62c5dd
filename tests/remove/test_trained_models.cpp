// The committed models do their job: on drops that raindrop-render puts on its own demo
// backgrounds (no data set needed), every model in models/ finds the drops and takes the image
// closer to the clean one; and, where the shared data is present, the default gains what
// docs/RESULTS.md 3.4 measured on real lens-cover photographs, and as much on large street frames
// as on the same drops at its working size (3.4). This fails for an untrained, corrupted or mis-exported model, and
// for a pipeline change (threshold, dilation, blending) that breaks the trained networks.
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

#include "raindrop/common/error.h"
#include "raindrop/remove/int8_precision.h"
#include "raindrop/remove/model_paths.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

double psnr(const cv::Mat& a, const cv::Mat& b) {
  const double mse = cv::norm(a, b, cv::NORM_L2SQR) / static_cast<double>(a.total() * a.channels());
  return mse > 0 ? 10.0 * std::log10(255.0 * 255.0 / mse) : 100.0;
}

double iou(const cv::Mat& a, const cv::Mat& b) {
  const cv::Mat A = a > 127, B = b > 127;
  const double inter = cv::countNonZero(A & B), uni = cv::countNonZero(A | B);
  return uni > 0 ? inter / uni : 1.0;
}

cv::Mat read_or_fail(const fs::path& p) {
  std::string why;
  auto img = read_image(p, &why);
  EXPECT_TRUE(img.has_value()) << p << ": " << why;
  return img ? img->pixels : cv::Mat();
}

// raindrop-render's demo set (a checkerboard and a street, one variant each, seed 7) at `size`
// (WIDTHxHEIGHT) into tmp/out, with the renderer's default scene or the preset `scene`.
void render_demo(const TempDir& tmp, const std::string& size, const std::string& out, const std::string& scene = "") {
  std::vector<std::string> args{"--demo", "--size", size, "--seed", "7", "--out", out, "-q", "-j", "1"};
  if (!scene.empty()) args.insert(args.end(), {"--scene", scene});
  const RunResult r = run_command(RAINDROP_RENDER_BIN, args, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
}

// Thresholds sit well below what the committed models reach (compact: +3.7 dB on the
// checkerboard, +6.4 dB on the street; mask IoU 0.72-0.77 after the default 3x3 dilation) and
// far above an untrained model (the fixture in tools/tests/fixtures/models-smoke: no gain).
constexpr double kMinGainDb = 2.0;
constexpr double kMinMaskIoU = 0.6;

TEST(TrainedModels, RemoveRenderedDrops) {
  REQUIRE_RENDER();
  const auto dirs = trained_models();
  if (dirs.empty()) GTEST_SKIP() << "no trained models in " << (source_dir() / "models");
  TempDir tmp;
  // 512x256 is the size the models were trained at (the paper's); one variant per background.
  ASSERT_NO_FATAL_FAILURE(render_demo(tmp, "512x256", "set"));
  RunResult r;
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(tmp / "set/rainy")) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  ASSERT_EQ(names.size(), 2u);
  for (const auto& dir : dirs) {
    const std::string config = dir.filename().string();
    const fs::path out = tmp / ("out-" + config), masks = tmp / ("masks-" + config);
    r = run_remove({"set/rainy", out.string(), "--models", dir.string(), "--mask-dir", masks.string(), "-q", "-j", "1"}, tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    for (const auto& n : names) {
      const cv::Mat rainy = read_or_fail(tmp / "set/rainy" / n), clean = read_or_fail(tmp / "set/clean" / n),
                    truth = read_or_fail(tmp / "set/mask" / n), removed = read_or_fail(out / n),
                    found = read_or_fail(masks / n);
      ASSERT_FALSE(rainy.empty() || clean.empty() || truth.empty() || removed.empty() || found.empty());
      const double before = psnr(rainy, clean), after = psnr(removed, clean), overlap = iou(found, truth);
      EXPECT_GE(after - before, kMinGainDb) << config << " on " << n << ": PSNR " << before << " -> " << after << " dB";
      EXPECT_GE(overlap, kMinMaskIoU) << config << " on " << n << ": detected mask IoU " << overlap;
      std::printf("%s %s: PSNR %.2f -> %.2f dB, mask IoU %.3f\n", config.c_str(), n.c_str(), before, after, overlap);
    }
  }
}

// The working scale makes the models' effect independent of the image size: the same drops
// rendered at 512x256 and at 2048x1024 (same seed: same drops, four times the pixels) gain
// within 1 dB of each other, where the full-size run without it lost most of its gain
// (docs/RESULTS.md 3.4).
TEST(TrainedModels, GainDoesNotDependOnTheImageSize) {
  REQUIRE_RENDER();
  const auto dirs = trained_models();
  if (dirs.empty()) GTEST_SKIP() << "no trained models in " << (source_dir() / "models");
  TempDir tmp;
  for (const char* size : {"512x256", "2048x1024"}) {
    ASSERT_NO_FATAL_FAILURE(render_demo(tmp, size, std::string("set-") + size));
  }
  for (const auto& dir : dirs) {
    const std::string config = dir.filename().string();
    double gain[2] = {0, 0};
    int k = 0;
    for (const std::string size : {"512x256", "2048x1024"}) {
      const fs::path set = tmp / ("set-" + size), out = tmp / ("out-" + config + "-" + size);
      const RunResult r = run_remove({(set / "rainy").string(), out.string(), "--models", dir.string(), "-q", "-j", "1"}, tmp.path());
      ASSERT_EQ(r.code, 0) << r.describe();
      for (const char* n : {"checkerboard_v00.png", "street_v00.png"}) {
        const cv::Mat rainy = read_or_fail(set / "rainy" / n), clean = read_or_fail(set / "clean" / n),
                      removed = read_or_fail(out / n);
        ASSERT_FALSE(rainy.empty() || clean.empty() || removed.empty());
        gain[k] += (psnr(removed, clean) - psnr(rainy, clean)) / 2;
      }
      ++k;
    }
    std::printf("%s: gain %.2f dB at 512x256, %.2f dB at 2048x1024\n", config.c_str(), gain[0], gain[1]);
    EXPECT_GE(gain[1], kMinGainDb) << config;
    EXPECT_LE(std::abs(gain[0] - gain[1]), 1.0) << config << ": " << gain[0] << " dB at 512x256, " << gain[1]
                                                << " dB at 2048x1024";
  }
}

// An image of odd height or width is as well restored along its bottom and right borders as
// the same content at even size (one more row and column, copies of the last ones: real
// content there would change the border's context). The RDN and 3RN run at half resolution; before the
// pipeline padded every image to even sizes, an odd border fell on the other phase of their
// stride-2 grid and its last rows came out wrong (compact on the demo checkerboard: bottom 4
// rows 6.5 levels from the clean image at 511x255 against 4.9 at 512x256, single pixels off by
// 180 levels).
TEST(TrainedModels, OddSizesAreRestoredAsWellAtTheirBorders) {
  REQUIRE_RENDER();
  const auto dirs = trained_models();
  if (dirs.empty()) GTEST_SKIP() << "no trained models in " << (source_dir() / "models");
  TempDir tmp;
  ASSERT_NO_FATAL_FAILURE(render_demo(tmp, "512x256", "set"));
  RunResult r;
  const std::vector<std::string> names = {"checkerboard_v00.png", "street_v00.png"};
  fs::create_directories(tmp / "in");
  for (const auto& n : names) {
    const cv::Mat rainy = read_or_fail(tmp / "set/rainy" / n);
    ASSERT_FALSE(rainy.empty());
    const cv::Mat odd = rainy(cv::Rect(0, 0, rainy.cols - 1, rainy.rows - 1)).clone();
    cv::Mat even;
    cv::copyMakeBorder(odd, even, 0, 1, 0, 1, cv::BORDER_REPLICATE);
    write_image(tmp / "in" / ("even_" + n), even);
    write_image(tmp / "in" / ("odd_" + n), odd);
  }
  for (const auto& dir : dirs) {
    const std::string config = dir.filename().string();
    const fs::path out = tmp / ("out-" + config);
    r = run_remove({"in", out.string(), "--models", dir.string(), "-q", "-j", "1"}, tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    for (const auto& n : names) {
      const cv::Mat clean = read_or_fail(tmp / "set/clean" / n), even = read_or_fail(out / ("even_" + n)),
                    odd = read_or_fail(out / ("odd_" + n));
      ASSERT_FALSE(clean.empty() || even.empty() || odd.empty());
      const int W = odd.cols, H = odd.rows;
      for (const cv::Rect border : {cv::Rect(0, H - 4, W, 4), cv::Rect(W - 4, 0, 4, H)}) {
        const double e_even = cv::norm(even(border), clean(border), cv::NORM_L1) / (border.area() * 3.0);
        const double e_odd = cv::norm(odd(border), clean(border), cv::NORM_L1) / (border.area() * 3.0);
        EXPECT_LE(e_odd, 1.1 * e_even + 0.1) << config << " on " << n << ", border " << border << ": mean error " << e_odd
                                             << " levels at " << W << "x" << H << " against " << e_even << " padded to even";
      }
    }
  }
}

}  // namespace
}  // namespace removetest

namespace removetest {
namespace {

// 8-bit luma as the pinned protocol computes it (tools/raindrop_tools/metrics.py: floor(0.299 R
// + 0.587 G + 0.114 B + 0.5)), of an 8-bit RGB image.
cv::Mat luma8(const cv::Mat& rgb) {
  cv::Mat y(rgb.size(), CV_64F);
  for (int r = 0; r < rgb.rows; ++r)
    for (int c = 0; c < rgb.cols; ++c) {
      const cv::Vec3b p = rgb.at<cv::Vec3b>(r, c);
      y.at<double>(r, c) = std::floor(0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2] + 0.5);
    }
  return y;
}

double psnr_y(const cv::Mat& a, const cv::Mat& b) { return psnr(luma8(a), luma8(b)); }

// The folder raindrop-remove loads from the source tree without --models (models/DEFAULT's; its
// int8 copy on a CPU with VNNI, `int8_fast`), found by its own search; the models root itself
// where there are none (the callers skip).
fs::path default_models(bool int8_fast = raindrop::removal::int8_runs_fast()) {
  raindrop::removal::ModelSearch search;
  search.source_models = source_dir() / "models";
  search.int8_fast = int8_fast;
  try {
    return raindrop::removal::find_models(search);
  } catch (const raindrop::Error&) {
    return search.source_models;
  }
}

// The shipped default on real photographs: the held-out half of the real lens-cover pairs (the
// 5 scene groups of the group-wise split that no committed model trained on; tools/raindrop_tools/
// realpairs.py), as a user runs it. docs/RESULTS.md 3.4 measured +3.00 dB there for the default, 4.21
// +3.43 with its large-drop growth (the floor is issue 10's target, +3 dB, which the growth crosses), of
// which the large-drop models (its LARGE_DROPS) give about 1.7 dB (this test printed +1.71 without them on
// 2026-12-04): floors on both, so
// that losing the large-drop models or the coarse pass fails here. Needs the real pairs of the
// shared data folder; skips without them.
TEST(TrainedModels, DefaultRemovesRealLensCoverDrops) {
  const fs::path pairs = fs::path(RAINDROP_SHARED_DATA) / "real-pairs";
  std::error_code ec;
  if (std::string(RAINDROP_SHARED_DATA).empty() || !fs::is_directory(pairs, ec))
    GTEST_SKIP() << "no real pairs in " << pairs << "; the default's real-photograph gain is not checked";
  // The default on CPUs without VNNI and its int8 copy on CPUs with it (one folder where they are one).
  std::vector<fs::path> defaults{default_models(false)};
  if (default_models(true) != defaults.front()) defaults.push_back(default_models(true));
  for (const fs::path& models : defaults) {
    if (!fs::is_regular_file(models / "rdn.onnx")) GTEST_SKIP() << "no trained models in " << models;
    ASSERT_TRUE(fs::is_regular_file(models / "LARGE_DROPS")) << models << " lost its large-drop models";
  }
  // The test split of tools/raindrop_tools/realpairs.py's group-wise rule over these pairs' 10
  // groups (tools/tests/test_realpairs.py holds the rule to these 5 names).
  const std::vector<std::string> test_groups = {"robotcar_i0", "robotcar_i14400", "robotcar_i4800", "robotcar_i8000",
                                                "robotcar_i9600"};
  TempDir tmp;
  fs::create_directories(tmp / "in");
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(pairs)) {
    const std::string n = e.path().filename().string();
    const auto tail = n.rfind("_t");
    if (tail == std::string::npos || n.size() < 9 || n.substr(n.size() - 9) != "_rain.png") continue;
    if (std::find(test_groups.begin(), test_groups.end(), n.substr(0, tail)) == test_groups.end()) continue;
    fs::copy_file(e.path(), tmp / "in" / n);
    names.push_back(n);
  }
  // On purpose a failure, not a skip: a different copy of the pairs would make the floors below
  // meaningless.
  ASSERT_EQ(names.size(), 50u) << "the held-out split of " << pairs << " should have 50 pairs";
  for (const fs::path& models : defaults) {
    SCOPED_TRACE(models.filename().string());
    double gain[2] = {0, 0};
    int k = 0;
    for (const std::vector<std::string>& extra :
         {std::vector<std::string>{}, std::vector<std::string>{"--large-drop-models", models.string()}}) {
      const fs::path out = tmp / (models.filename().string() + "-out" + std::to_string(k));
      std::vector<std::string> args{"in", out.string(), "--models", models.string(), "-q", "-j", "1"};
      args.insert(args.end(), extra.begin(), extra.end());
      const RunResult r = run_remove(args, tmp.path());
      ASSERT_EQ(r.code, 0) << r.describe();
      for (const auto& n : names) {
        const std::string clean_name = n.substr(0, n.size() - 9) + "_clean.png";
        const cv::Mat rainy = read_or_fail(tmp / "in" / n), clean = read_or_fail(pairs / clean_name),
                      removed = read_or_fail(out / n);
        ASSERT_FALSE(rainy.empty() || clean.empty() || removed.empty());
        ASSERT_TRUE(rainy.type() == CV_8UC3 && clean.type() == CV_8UC3 && removed.type() == CV_8UC3) << n;
        gain[k] += (psnr_y(removed, clean) - psnr_y(rainy, clean)) / static_cast<double>(names.size());
      }
      ++k;
    }
    std::printf("real lens-cover test split, %s: default +%.2f dB, its own networks for large drops +%.2f dB\n",
                models.filename().c_str(), gain[0], gain[1]);
    // Issue 10's target, +3 dB; the large-drop growth (4.21) took the default from +3.00 to +3.43.
    EXPECT_GE(gain[0], 3.0) << "the default's gain on held-out real pairs (docs/RESULTS.md 4.21: +3.43)";
    EXPECT_GE(gain[0] - gain[1], 0.8) << "what the large-drop models add (docs/RESULTS.md 3.4: +3.00 against +1.63 for the default; 4.11: compact +1.48)";
  }
}

// The default gains as much on a large street frame as on the same drops at the size its networks
// see: drops of the paper preset rendered with one seed (the same drops, relative to the frame)
// onto the held-out Cityscapes frames at 1280x720 and at 512x288, the size raindrop-remove
// brings 1280x720 to. Their PSNR-Y gains stay within 1 dB (the target). `compact` alone
// gained about 2 dB less at 1280x720: it had learnt drops rendered at 512 px, not drops
// area-averaged down from a larger frame (8.59 against 6.51 dB; docs/RESULTS.md 3.4). The default
// measured 8.30 and 7.45, 8.26 and 7.48 with its large-drop growth (4.21), 8.33 and 7.44 with the coarse pass's
// sharpness limit (4.22): the 1 dB is the target itself, not a margin around today's model. Both
// gains must also stay near what they are, so that a model that loses its effect at both sizes
// alike does not pass. Needs the shared Cityscapes frames (the first two of the val split);
// skips without them.
TEST(TrainedModels, DefaultGainsAsMuchOnLargeStreetFrames) {
  REQUIRE_RENDER();
  const fs::path cityscapes = fs::path(RAINDROP_SHARED_DATA) / "cityscapes-mini";
  std::error_code ec;
  if (std::string(RAINDROP_SHARED_DATA).empty() || !fs::is_directory(cityscapes / "leftImg8bit" / "val", ec))
    GTEST_SKIP() << "no Cityscapes frames in " << cityscapes << "; the full-size gain is not checked";
  const fs::path models = default_models();
  if (!fs::is_regular_file(models / "rdn.onnx")) GTEST_SKIP() << "no trained models in " << models;
  TempDir tmp;
  double gain[2] = {0, 0};
  int k = 0;
  for (const std::string size : {"512x288", "1280x720"}) {
    const std::string set = "set-" + size, out = "out-" + size;
    RunResult r = run_command(RAINDROP_RENDER_BIN,
                              {"--cityscapes", cityscapes.string(), "--split", "val", "--limit", "2", "--variants", "16", "--seed", "9",
                               "--size", size, "--out", set, "-q", "-j", "1"},
                              tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    r = run_remove({set + "/rainy", out, "--models", models.string(), "-q", "-j", "1"}, tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    int n = 0;
    for (const auto& e : fs::directory_iterator(tmp / set / "rainy")) {
      const std::string name = e.path().filename().string();
      const cv::Mat rainy = read_or_fail(e.path()), clean = read_or_fail(tmp / set / "clean" / name),
                    removed = read_or_fail(tmp / out / name);
      ASSERT_FALSE(rainy.empty() || clean.empty() || removed.empty()) << name;
      gain[k] += psnr_y(removed, clean) - psnr_y(rainy, clean);
      ++n;
    }
    ASSERT_EQ(n, 32) << "2 held-out frames x 16 variants at " << size;
    gain[k] /= n;
    ++k;
  }
  std::printf("%s on held-out Cityscapes frames: gain %.2f dB at 512x288, %.2f dB at 1280x720\n",
              models.filename().string().c_str(), gain[0], gain[1]);
  EXPECT_GE(gain[0], 7.5) << "at 512x288 (measured 8.33)";
  EXPECT_GE(gain[1], 6.5) << "at 1280x720 (measured 7.44)";
  EXPECT_LE(std::abs(gain[0] - gain[1]), 1.0) << gain[0] << " dB at 512x288, " << gain[1] << " dB at 1280x720";
}

// --fine-drops (fine_drops.h) on the default: sharp windshield drops rendered at 1280x720 on the
// demo street (working scale 0.4, many drops 2-4 px there) come out closer to the clean frame
// (measured +0.20 dB), the checkerboard hardly further from it (-0.002 dB with the router's head
// at its first threshold, 0.75; -0.028 dB since it is 0.5, docs/RESULTS.md 4.50: the pass fills
// 73 parts of the checkerboard instead of 47, its mask 8.5% of it instead of 6.2%; -0.051 dB with the
// default's int8 copy, which a CPU with VNNI runs, and +0.17 dB on the street); every pixel it changes
// is within a pixel of the written mask; at 512x256 (the networks see every pixel) it changes
// nothing.
TEST(TrainedModels, FineDropsTakeSmallWindshieldDropsOutAndTouchNothingElse) {
  REQUIRE_RENDER();
  const fs::path models = default_models();
  if (!fs::is_regular_file(models / "rdn.onnx")) GTEST_SKIP() << "no trained models in " << models;
  TempDir tmp;
  for (const std::string size : {"1280x720", "512x256"}) {
    const std::string set = "set-" + size;
    ASSERT_NO_FATAL_FAILURE(render_demo(tmp, size, set, "windshield-sharp"));
    RunResult r = run_remove({set + "/rainy", "out-" + size, "--models", models.string(), "-q", "-j", "2"}, tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    r = run_remove({set + "/rainy", "fine-" + size, "--models", models.string(), "--fine-drops", "--mask-dir",
                    "masks-" + size, "--time", "-j", "2"},
                   tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    if (size == "1280x720") {
      EXPECT_NE(r.err.find("fine drops filled at scale 0.6"), std::string::npos) << r.err;
    }
    for (const std::string n : {"checkerboard_v00.png", "street_v00.png"}) {
      const cv::Mat rainy = read_or_fail(tmp / set / "rainy" / n), clean = read_or_fail(tmp / set / "clean" / n),
                    base = read_or_fail(tmp / ("out-" + size) / n), fine = read_or_fail(tmp / ("fine-" + size) / n),
                    mask = read_or_fail(tmp / ("masks-" + size) / n);
      ASSERT_FALSE(rainy.empty() || clean.empty() || base.empty() || fine.empty() || mask.empty()) << n;
      const double before = psnr(base, clean), after = psnr(fine, clean);
      std::printf("%s at %s: PSNR %.2f -> %.2f dB, with --fine-drops %.2f dB\n", n.c_str(), size.c_str(),
                  psnr(rainy, clean), before, after);
      if (size == "512x256") {
        EXPECT_EQ(cv::norm(base, fine, cv::NORM_INF), 0.0) << n << ": changed at the networks' own scale";
        continue;
      }
      if (n == "street_v00.png") {
        EXPECT_GE(after - before, 0.05) << n;
      }
      EXPECT_GE(after - before, models.filename().string().find("-int8") == std::string::npos ? -0.05 : -0.1) << n;
      cv::Mat diff;
      cv::absdiff(base, fine, diff);
      std::vector<cv::Mat> channels;
      cv::split(diff, channels);
      cv::Mat changed(base.size(), CV_8U, cv::Scalar(0));
      for (const cv::Mat& c : channels) changed |= c > 0;
      cv::Mat near_mask;
      cv::dilate(mask > 0, near_mask, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
      EXPECT_EQ(cv::countNonZero(changed & ~near_mask), 0) << n << ": pixels changed away from the mask";
      EXPECT_GT(cv::countNonZero(changed), 0) << n;
    }
  }
}

// The default's large drops get masks that grow with them (its raindrop.large_drop_growth;
// docs/RESULTS.md 4.21): on the demo checkerboard under lens-cover-merged drops, where the coarse
// pass finds large drops, the written mask holds the one without the growth and more.
TEST(TrainedModels, TheDefaultsLargeDropMasksGrowWithThem) {
  REQUIRE_RENDER();
  const fs::path models = default_models();
  if (!fs::is_regular_file(models / "rdn.onnx")) GTEST_SKIP() << "no trained models in " << models;
  TempDir tmp;
  ASSERT_NO_FATAL_FAILURE(render_demo(tmp, "512x256", "set", "lens-cover-merged"));
  cv::Mat masks[2];
  int k = 0;
  for (const std::string growth : {"", "0"}) {
    std::vector<std::string> args{"set/rainy/checkerboard_v00.png", "out.png", "--models", models.string(), "--mask",
                                  "m" + std::to_string(k) + ".png", "-q", "-j", "1"};
    if (!growth.empty()) args.insert(args.end(), {"--large-drop-growth", growth});
    const RunResult r = run_remove(args, tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    masks[k] = read_or_fail(tmp / ("m" + std::to_string(k) + ".png"));
    ASSERT_FALSE(masks[k].empty());
    ++k;
  }
  EXPECT_EQ(cv::countNonZero(masks[1] > masks[0]), 0) << "the growth took mask pixels away";
  const int more = cv::countNonZero(masks[0] > masks[1]);
  std::printf("%s on lens-cover-merged drops: %d mask pixels without the growth, %d more with it\n",
              models.filename().string().c_str(), cv::countNonZero(masks[1]), more);
  EXPECT_GT(more, 0) << models << " gives large drops no growth (raindrop.large_drop_growth), or found none";
}

}  // namespace
}  // namespace removetest

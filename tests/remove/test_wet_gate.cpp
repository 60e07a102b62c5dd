// A camera's wet gate (wet_gate.h): its score against the formula, its file's refusals, the models
// it suits, what the Remover gives for an image it judges dry (the input, bit for bit) or wet
// (exactly what it gives without the gate), the program end to end, and the program's z against
// the fitting tool's.
#include <cmath>
#include <sstream>

#include <sys/stat.h>

#include <gtest/gtest.h>

#include "raindrop/common/error.h"
#include "raindrop/common/image_io.h"
#include "raindrop/remove/detector_router.h"
#include "raindrop/remove/key_file.h"
#include "raindrop/remove/remover.h"
#include "raindrop/remove/wet_gate.h"
#include "remove_test_util.h"
#include "smoke_remover.h"

namespace removetest {
namespace {

using raindrop::Error;
using raindrop::removal::check_wet_gate;
using raindrop::removal::kRouterFeatures;
using raindrop::removal::ModelInfo;
using raindrop::removal::read_wet_gate;
using raindrop::removal::RemoveOptions;
using raindrop::removal::RemoveResult;
using raindrop::removal::router_features;
using raindrop::removal::WetGate;

// A gate whose z is `bias` for every image (weights 0).
std::string gate_text(const std::string& models = "models-smoke", double bias = 0.0, int maps = 1,
                      const std::string& std_value = "1") {
  const int n = maps * kRouterFeatures;
  return "# a test gate\nformat 1\nmodels " + models + "\nmaps " + std::to_string(maps) + "\nmean" + repeated_words(n, "0") +
         "\nstd" + repeated_words(n, std_value) + "\nweight" + repeated_words(n, "0") + "\nbias " + std::to_string(bias) + "\n";
}

std::shared_ptr<const WetGate> gate_of(const TempDir& tmp, const std::string& text) {
  write_file(tmp / "camera.gate", text);
  return std::make_shared<const WetGate>(read_wet_gate(tmp / "camera.gate"));
}

// Two different maps: z is the bias plus each map's standardised, weighted features, the
// second map's under the weights 10-19.
TEST(WetGate, ScoreIsTheStandardisedLinearFormOfEachMap) {
  cv::Mat a(12, 20, CV_32F, cv::Scalar(0)), b(12, 20, CV_32F, cv::Scalar(0.1f));
  a(cv::Rect(2, 2, 4, 3)).setTo(0.8f);
  b(cv::Rect(9, 1, 6, 6)).setTo(0.5f);
  WetGate g;
  g.maps = 2;
  g.bias = -0.75;
  for (int i = 0; i < 2 * kRouterFeatures; ++i) {
    g.mean.push_back(0.1 * i);
    g.std.push_back(0.5 + 0.05 * i);
    g.weight.push_back(i % 3 == 0 ? -0.4 : 0.3 + 0.01 * i);
  }
  const auto fa = router_features(a), fb = router_features(b);
  double want = g.bias;
  for (int i = 0; i < kRouterFeatures; ++i) {
    want += g.weight[i] * (fa[i] - g.mean[i]) / g.std[i];
    want += g.weight[i + 10] * (fb[i] - g.mean[i + 10]) / g.std[i + 10];
  }
  EXPECT_NEAR(g.score(a, b), want, 1e-12);
  // One map: the second is not read (an empty one is fine).
  g.maps = 1;
  double first = g.bias;
  for (int i = 0; i < kRouterFeatures; ++i) first += g.weight[i] * (fa[i] - g.mean[i]) / g.std[i];
  EXPECT_NEAR(g.score(a, cv::Mat()), first, 1e-12);
  EXPECT_NE(first, want);
}

TEST(WetGate, ReadsItsFile) {
  TempDir tmp;
  write_file(tmp / "g", gate_text("compact-multiscale-int8", -1.5, 2));
  const WetGate g = read_wet_gate(tmp / "g");
  EXPECT_EQ(g.models, "compact-multiscale-int8");
  EXPECT_EQ(g.maps, 2);
  EXPECT_EQ(g.mean.size(), 20u);
  EXPECT_EQ(g.std[19], 1.0);
  EXPECT_EQ(g.bias, -1.5);
}

TEST(WetGate, RefusesADamagedFileNamingIt) {
  const std::string good = gate_text();
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"", "format 1"},
      {"format 2\n", "format 1"},
      {good + "bias 1\n", "given twice"},
      {gate_text("../up"), "one model folder"},
      {gate_text("a b"), "one model folder"},
      {gate_text("m", 0, 3), "'maps' must be 1 or 2"},
      {gate_text("m", 0, 0), "'maps' must be 1 or 2"},
      {gate_text("m", 0, 1, "0"), "positive"},
      {gate_text("m", 0, 1, "-1"), "positive"},
      {gate_text("m", 0, 1, "nan"), "not a finite number"},
      {gate_text("m", 0, 1, "1e999"), "not a finite number"},
      {"format 1\nmodels m\nmaps 2\nmean" + repeated_words(10, "0") + "\n", "20 numbers"},
      {"format 1\nmodels m\nmaps 1\nmean" + repeated_words(10, "0") + "\nstd" + repeated_words(10, "1") + "\nweight" + repeated_words(10, "0") + "\n",
       "'bias' must hold 1 number"},
  };
  for (const auto& [text, why] : bad) {
    TempDir tmp;
    write_file(tmp / "camera.gate", text);
    try {
      read_wet_gate(tmp / "camera.gate");
      ADD_FAILURE() << "accepted:\n" << text;
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(why), std::string::npos) << msg;
      EXPECT_NE(msg.find((tmp / "camera.gate").string()), std::string::npos) << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos);
    }
  }
  TempDir tmp;
  EXPECT_THROW(read_wet_gate(tmp / "missing.gate"), Error);
  EXPECT_THROW(read_wet_gate(tmp.path()), Error) << "a folder";
  // Neither a FIFO (which blocked the read until a writer came) nor an endless file (/dev/zero
  // grew the buffer to gigabytes) is read: not a regular file, or more than a key file holds.
  ASSERT_EQ(mkfifo((tmp / "fifo.gate").c_str(), 0600), 0);
  EXPECT_THROW(read_wet_gate(tmp / "fifo.gate"), Error);
  EXPECT_THROW(read_wet_gate("/dev/zero"), Error);
  write_file(tmp / "huge.gate", gate_text() + "#" + std::string(raindrop::removal::kMaxKeyFileBytes, 'x') + "\n");
  try {
    read_wet_gate(tmp / "huge.gate");
    ADD_FAILURE() << "a file larger than a key file holds was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not a key file"), std::string::npos) << e.what();
  }
  write_file(tmp / "long.gate", gate_text() + "# " + std::string(1000, 'x') + "\n");
  EXPECT_NO_THROW(read_wet_gate(tmp / "long.gate")) << "comments are still fine";
}

// The folder it was fitted with, its int8 copy or the float folder of an int8 copy; no other;
// two maps only where the detector's graph computes the second.
TEST(WetGate, SuitsTheModelsItWasFittedOnAndTheirInt8Twin) {
  TempDir tmp;
  ModelInfo one, two;
  two.alternative_detector = "compact-windshield-head";
  const auto gate = [&](const std::string& models, int maps) {
    write_file(tmp / "g", gate_text(models, 0, maps));
    return read_wet_gate(tmp / "g");
  };
  EXPECT_NO_THROW(check_wet_gate(gate("compact-multiscale", 1), "models/compact-multiscale", one));
  EXPECT_NO_THROW(check_wet_gate(gate("compact-multiscale", 1), "models/compact-multiscale/", one));
  EXPECT_NO_THROW(check_wet_gate(gate("compact-multiscale", 2), "/x/models/compact-multiscale-int8", two));
  EXPECT_NO_THROW(check_wet_gate(gate("compact-multiscale-int8", 2), "compact-multiscale", two));
  EXPECT_NO_THROW(check_wet_gate(gate("compact-multiscale", 1), "/x/models/compact-multiscale/.", one));
  for (const std::string other : {"compact", "compact-multiscale-int8-int8", "paper-int8"}) {
    try {
      check_wet_gate(gate("compact-multiscale", 1), "models/" + other, one);
      ADD_FAILURE() << other;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("not of '" + other + "'"), std::string::npos) << e.what();
    }
  }
  try {
    check_wet_gate(gate("compact-multiscale", 2), "models/compact-multiscale", one);
    ADD_FAILURE() << "two maps from a graph with one";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("two detector maps"), std::string::npos) << e.what();
  }
}

// Judged dry: the input, bit for bit, in every format, with an empty mask, at the working scale
// and at full size. Judged wet: exactly the output without the gate.
TEST(WetGate, ADryImageIsItsInputAndAWetOneWhatItIsWithoutTheGate) {
  TempDir tmp;
  const cv::Mat rgb8 = make_image(1100, 600, 41), small = make_image(480, 320, 44);
  cv::Mat rgba16, grey8;
  rgb8.convertTo(rgba16, CV_16U, 257.0);
  rgba16.at<cv::Vec3w>(5, 7) = cv::Vec3w(1, 65534, 30001);
  cv::cvtColor(rgba16, rgba16, cv::COLOR_RGB2RGBA);
  cv::cvtColor(rgb8, grey8, cv::COLOR_RGB2GRAY);
  RemoveOptions dry, wet, none;
  none.keep_float = dry.keep_float = wet.keep_float = true;
  dry.wet_gate = gate_of(tmp, gate_text("models-smoke", -2.0));
  wet.wet_gate = gate_of(tmp, gate_text("models-smoke", +2.0));
  for (const cv::Mat* m : {&rgb8, &small, static_cast<const cv::Mat*>(&rgba16), static_cast<const cv::Mat*>(&grey8)}) {
    SCOPED_TRACE(::testing::Message() << m->cols << "x" << m->rows << ", channels " << m->channels());
    const RemoveResult without = smoke_remover().run(*m, none);
    ASSERT_GT(max_abs_diff(without.image, *m), 0) << "the pipeline must change the image for the test to mean anything";
    const RemoveResult d = smoke_remover().run(*m, dry);
    ASSERT_TRUE(d.wet_gate_score.has_value());
    EXPECT_EQ(*d.wet_gate_score, -2.0);
    EXPECT_TRUE(d.judged_dry());
    EXPECT_EQ(max_abs_diff(d.image, *m), 0);
    EXPECT_EQ(d.mask.size(), m->size());
    EXPECT_EQ(cv::countNonZero(d.mask), 0);
    EXPECT_EQ(d.rgb.size(), m->size());
    EXPECT_EQ(d.reconstructed_pixels, 0) << "a dry image's passes stop after their detectors";
    const RemoveResult w = smoke_remover().run(*m, wet);
    EXPECT_FALSE(w.judged_dry());
    EXPECT_EQ(max_abs_diff(w.image, without.image), 0);
    EXPECT_EQ(max_abs_diff(w.mask, without.mask), 0);
    EXPECT_FALSE(without.wet_gate_score.has_value());
  }
  // The gate judges at the automatic scale, given or not; at any other it refuses.
  RemoveOptions given = dry;
  given.scale = 512.0 / 1100.0;
  EXPECT_TRUE(smoke_remover().run(rgb8, given).judged_dry());
  given.scale = 0.25;
  EXPECT_THROW(smoke_remover().run(rgb8, given), Error);
}

// With the committed default (a router whose head the detector's graph computes, and a coarse
// pass that finds large drops in glass-plate's carpet of soft drops), on one and two threads: a dry image stops both
// passes after their detectors (the coarse pass waits for the verdict, and for the router's
// choice, which a dry image never makes), a wet one is exactly what it is without the gate.
TEST(WetGate, TheDefaultsPassesStopForADryImageAndRunAsWithoutTheGateForAWetOne) {
  REQUIRE_RENDER();
  const fs::path models = source_dir() / "models" / "compact-multiscale";
  if (!fs::exists(models / "rdn.onnx")) GTEST_SKIP() << "the committed models are not in " << models;
  TempDir tmp;
  const RunResult rendered = run_command(RAINDROP_RENDER_BIN, {"--demo", "--size", "700x400", "--seed", "4", "--out", "set",
                                                               "--scene", "glass-plate", "-q", "-j", "1"}, tmp.path());
  ASSERT_EQ(rendered.code, 0) << rendered.describe();
  const auto read = read_image(tmp / "set/rainy/street_v00.png");
  ASSERT_TRUE(read.has_value());
  const cv::Mat image = read->pixels;
  RemoveOptions none, dry, wet;
  dry.wet_gate = gate_of(tmp, gate_text("compact-multiscale", -1.0, 2));
  wet.wet_gate = gate_of(tmp, gate_text("compact-multiscale", +1.0, 2));
  for (const int threads : {2, 1}) {
    SCOPED_TRACE(threads);
    raindrop::removal::SessionConfig session;
    session.threads = threads;
    raindrop::removal::Remover remover(models, session);
    ASSERT_TRUE(remover.router().has_value());
    const RemoveResult without = remover.run(image, none);
    ASSERT_GT(without.large_drops, 0) << "the coarse pass must find large drops here for the test to mean anything";
    const RemoveResult d = remover.run(image, dry);
    EXPECT_TRUE(d.judged_dry());
    EXPECT_EQ(max_abs_diff(d.image, image), 0);
    EXPECT_EQ(d.reconstructed_pixels, 0);
    EXPECT_EQ(d.large_drops, 0);
    const RemoveResult w = remover.run(image, wet);
    EXPECT_EQ(max_abs_diff(w.image, without.image), 0);
    EXPECT_EQ(max_abs_diff(w.mask, without.mask), 0);
    EXPECT_EQ(w.large_drops, without.large_drops);
    EXPECT_EQ(w.router_score, without.router_score);
  }
}

// A router whose alternative is a folder of its own (not the main graph's second map) beside a
// gate on both maps: an image the router sends there comes out exactly as without the gate (the
// alternative's graph has one output, and is not asked for the map the gate read).
TEST(WetGate, AGateOnTwoMapsLeavesARouterToAnotherFolderAsItIs) {
  const fs::path src = source_dir() / "models";
  for (const char* name : {"compact-multiscale", "compact-windshield", "paper-real-coarse"}) {
    if (!fs::exists(src / name / "rrn.onnx")) GTEST_SKIP() << "the committed models are not in " << src;
  }
  TempDir tmp;
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"compact-multiscale", "main"}, {"compact-windshield", "alt"}, {"paper-real-coarse", "paper-real-coarse"}}) {
    fs::create_directories(tmp / "models" / to);
    for (const char* file : {"rdn.onnx", "rrn.onnx", "rfn.onnx", "LARGE_DROPS"}) {
      if (fs::exists(src / from / file)) fs::create_symlink(src / from / file, tmp / "models" / to / file);
    }
  }
  write_file(tmp / "models" / "main" / "ROUTER",
             "format 1\nalternative alt\nmean" + repeated_words(10, "0") + "\nstd" + repeated_words(10, "1") + "\nweight" +
                 repeated_words(10, "0") + "\nbias 1\n");  // every image to alt
  const cv::Mat image = make_image(700, 400, 9);
  RemoveOptions none, wet, dry;
  wet.wet_gate = gate_of(tmp, gate_text("main", +1.0, 2));
  write_file(tmp / "dry.gate", gate_text("main", -1.0, 2));
  dry.wet_gate = std::make_shared<const WetGate>(read_wet_gate(tmp / "dry.gate"));
  raindrop::removal::Remover remover(tmp / "models" / "main");
  const RemoveResult without = remover.run(image, none);
  ASSERT_TRUE(without.alternative_detector());
  const RemoveResult w = remover.run(image, wet);
  EXPECT_TRUE(w.alternative_detector());
  EXPECT_EQ(max_abs_diff(w.image, without.image), 0);
  EXPECT_EQ(max_abs_diff(w.mask, without.mask), 0);
  EXPECT_EQ(max_abs_diff(remover.run(image, dry).image, image), 0);
}

// The program end to end: a dry image's file holds the input's pixels and an empty mask, and says
// so; a folder run counts them; a damaged gate, one for other models and --scale are refused
// before anything is written.
TEST(WetGateCli, ADryImageIsWrittenAsItWasAndBadGatesAreRefused) {
  TempDir tmp;
  const cv::Mat img = make_image(300, 200, 3);
  fs::create_directories(tmp / "in");
  write_image(tmp / "in" / "a.png", img);
  write_image(tmp / "in" / "b.png", make_image(200, 300, 4));
  write_file(tmp / "dry.gate", gate_text("models-smoke", -1.0));
  write_file(tmp / "wet.gate", gate_text("models-smoke", +1.0));
  const std::string models = smoke_models().string();
  const RunResult r = run_remove({"in/a.png", "out.png", "--models", models, "--mask", "mask.png", "--wet-gate", "dry.gate"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("judged dry by the wet gate (z -1.00)"), std::string::npos) << r.describe();
  const auto out = read_image(tmp / "out.png"), mask = read_image(tmp / "mask.png");
  ASSERT_TRUE(out && mask);
  EXPECT_EQ(max_abs_diff(out->pixels, img), 0);
  EXPECT_EQ(cv::countNonZero(mask->pixels), 0);

  const RunResult w = run_remove({"in/a.png", "wet.png", "--models", models, "--wet-gate", "wet.gate", "--time"}, tmp.path());
  ASSERT_EQ(w.code, 0) << w.describe();
  EXPECT_NE(w.err.find("wet gate z +1.00: wet"), std::string::npos) << w.describe();
  const auto wet_out = read_image(tmp / "wet.png");
  ASSERT_TRUE(wet_out);
  EXPECT_GT(max_abs_diff(wet_out->pixels, img), 0);

  // A dry JPEG written as a JPEG is its input file, byte for byte (not encoded again); as a PNG,
  // the pixels it was read as. And its detector's time is reported (two threads: beside the 3RN).
  raindrop::write_image_atomic(img, tmp / "in.jpg");
  const RunResult jpeg = run_remove({"in.jpg", "out.jpg", "--models", models, "--wet-gate", "dry.gate", "--time", "-j", "2"}, tmp.path());
  ASSERT_EQ(jpeg.code, 0) << jpeg.describe();
  EXPECT_EQ(read_file(tmp / "out.jpg"), read_file(tmp / "in.jpg"));
  const auto rdn = jpeg.err.find("RDN ");
  ASSERT_NE(rdn, std::string::npos) << jpeg.describe();
  EXPECT_GT(std::stod(jpeg.err.substr(rdn + 4)), 0.0) << jpeg.describe();
  // A read-only input's copy is a file of the program's own, writable as any output: a second
  // run replaces it.
  fs::permissions(tmp / "in.jpg", fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  for (int run = 0; run < 2; ++run) {
    const RunResult again = run_remove({"in.jpg", "copy.jpg", "--models", models, "--wet-gate", "dry.gate"}, tmp.path());
    ASSERT_EQ(again.code, 0) << again.describe();
  }
  EXPECT_NE(fs::status(tmp / "copy.jpg").permissions() & fs::perms::owner_write, fs::perms::none);
  EXPECT_EQ(read_file(tmp / "copy.jpg"), read_file(tmp / "in.jpg"));
  // A PNG named .jpg is read as the PNG it is, and its dry output is a JPEG as the name says.
  fs::copy_file(tmp / "in" / "a.png", tmp / "png.jpg");
  ASSERT_EQ(run_remove({"png.jpg", "named.jpg", "--models", models, "--wet-gate", "dry.gate"}, tmp.path()).code, 0);
  EXPECT_EQ(read_file(tmp / "named.jpg").substr(0, 3), "\xFF\xD8\xFF");
  ASSERT_EQ(run_remove({"in.jpg", "jpeg.png", "--models", models, "--wet-gate", "dry.gate"}, tmp.path()).code, 0);
  const auto as_read = read_image(tmp / "in.jpg"), as_png = read_image(tmp / "jpeg.png");
  ASSERT_TRUE(as_read && as_png);
  EXPECT_EQ(max_abs_diff(as_png->pixels, as_read->pixels), 0);

  const RunResult folder = run_remove({"in", "outdir", "--models", models, "--wet-gate", "dry.gate"}, tmp.path());
  ASSERT_EQ(folder.code, 0) << folder.describe();
  EXPECT_NE(folder.err.find("2 of 2 images done (2 judged dry by the wet gate: written as they were read)"), std::string::npos)
      << folder.describe();

  write_file(tmp / "damaged.gate", "format 1\nmodels models-smoke\nmaps 1\n");
  write_file(tmp / "other.gate", gate_text("compact-multiscale", -1.0));
  for (const std::string gate : {"damaged.gate", "other.gate", "missing.gate"}) {
    SCOPED_TRACE(gate);
    const RunResult bad = run_remove({"in/a.png", "refused.png", "--models", models, "--wet-gate", gate}, tmp.path());
    EXPECT_EQ(bad.code, 1) << bad.describe();
    EXPECT_EQ(split_lines(bad.err).size(), 1u) << bad.describe();
    EXPECT_NE(bad.err.find(gate), std::string::npos) << bad.describe();
    EXPECT_FALSE(fs::exists(tmp / "refused.png"));
  }
  const RunResult empty = run_remove({"in/a.png", "refused.png", "--models", models, "--wet-gate", ""}, tmp.path());
  EXPECT_EQ(empty.code, 2) << empty.describe();  // a usage error, as every other option given ''
  EXPECT_NE(empty.err.find("--wet-gate needs a value, got ''"), std::string::npos) << empty.describe();
  EXPECT_FALSE(fs::exists(tmp / "refused.png"));
  const RunResult scaled = run_remove({"in/a.png", "refused.png", "--models", models, "--wet-gate", "dry.gate", "--scale", "0.5"}, tmp.path());
  EXPECT_EQ(scaled.code, 2) << scaled.describe();
  EXPECT_FALSE(fs::exists(tmp / "refused.png"));
}

// The program's z (its --time line) against the fitting tool's (wet_gate.py judge) for a gate on
// both of the default's maps with weights on every feature, on rendered frames with three kinds of
// drops and none: one definition of the features on both sides.
TEST(WetGate, TheProgramScoresAsTheFittingTool) {
  REQUIRE_RENDER();
  if (python().empty()) GTEST_SKIP() << "RAINDROP_PYTHON is not set; the wet gate's Python parity is not checked";
  const fs::path models = source_dir() / "models" / "compact-multiscale";
  if (!fs::exists(models / "rdn.onnx")) GTEST_SKIP() << "the committed models are not in " << models;
  TempDir tmp;
  std::vector<std::string> images;
  for (const std::string scene : {"lens-cover", "windshield-sharp", "paper"}) {
    const RunResult r = run_command(RAINDROP_RENDER_BIN, {"--demo", "--size", "700x400", "--seed", "5", "--out", scene,
                                                          "--scene", scene, "-q", "-j", "1"}, tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    images.push_back((tmp / scene / "rainy" / "street_v00.png").string());
  }
  images.push_back((tmp / "paper" / "clean" / "street_v00.png").string());
  // A 16-bit frame whose low bits matter: both sides see it at 16 bits.
  {
    const auto rainy = read_image(tmp / "lens-cover" / "rainy" / "street_v00.png");
    ASSERT_TRUE(rainy.has_value());
    cv::Mat deep, noise(rainy->pixels.size(), CV_16UC3);
    rainy->pixels.convertTo(deep, CV_16U, 256.0);
    cv::randu(noise, 0, 256);
    deep += noise;
    write_image(tmp / "deep.png", deep);
    images.push_back((tmp / "deep.png").string());
  }
  // Weights that give each feature of both maps a say; z near 0 on these frames, of either sign.
  std::ostringstream g;
  g << "format 1\nmodels compact-multiscale\nmaps 2\nmean";
  for (int i = 0; i < 20; ++i) g << " " << 1.0 + 0.3 * (i % 7);
  g << "\nstd";
  for (int i = 0; i < 20; ++i) g << " " << 0.5 + 0.1 * (i % 5);
  g << "\nweight";
  for (int i = 0; i < 20; ++i) g << " " << (i % 2 ? -0.2 : 0.25) * (1 + i % 3);
  g << "\nbias 0.1\n";
  write_file(tmp / "camera.gate", g.str());
  std::vector<std::string> args = {"-m", "raindrop_tools.wet_gate", "judge", "--gate", "camera.gate", "--models", models.string()};
  args.insert(args.end(), images.begin(), images.end());
  const RunResult py = run_command(python(), args, tmp.path());
  ASSERT_EQ(py.code, 0) << py.describe();
  std::istringstream lines(py.out);
  for (const auto& image : images) {
    SCOPED_TRACE(image);
    std::string path, verdict;
    double z_py = 0;
    ASSERT_TRUE(lines >> path >> z_py >> verdict);
    EXPECT_EQ(path, image);
    const RunResult cpp = run_remove({image, (tmp / "out.png").string(), "--models", models.string(), "--wet-gate", "camera.gate",
                                      "--time", "--threads", "2"}, tmp.path());
    ASSERT_EQ(cpp.code, 0) << cpp.describe();
    const auto at = cpp.err.find("wet gate z ");
    ASSERT_NE(at, std::string::npos) << cpp.describe();
    const double z_cpp = std::stod(cpp.err.substr(at + 11));
    EXPECT_NEAR(z_cpp, z_py, 0.011);  // printed to 2 decimals
    EXPECT_EQ(verdict, z_py > 0 ? "wet" : "dry");
  }
}

}  // namespace
}  // namespace removetest

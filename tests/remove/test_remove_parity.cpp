// raindrop-remove against the Python reference (tools/raindrop_tools/reference.py): same
// images, same models; the outputs must agree to within 1/255 on 8-bit values and the masks
// (--mask) must be identical. Both sides run as programs: raindrop-remove in folder mode,
// the reference's main() once per image in one Python process.
#include <algorithm>

#include <nlohmann/json.hpp>

#include "remove_test_util.h"

namespace removetest {
namespace {

struct Case {
  std::string name;  // file name (png)
  cv::Mat image;     // 8-bit, 1, 3 or 4 channels (RGB order); empty: copy `source`
  fs::path source = {};
};

std::vector<Case> generated_cases() {
  std::vector<Case> cases;
  for (const cv::Size s : {cv::Size(1, 1), cv::Size(2, 3), cv::Size(7, 5), cv::Size(33, 17), cv::Size(64, 48),
                           cv::Size(101, 77), cv::Size(257, 130)}) {
    cases.push_back({"rgb_" + std::to_string(s.width) + "x" + std::to_string(s.height) + ".png",
                     make_image(s.width, s.height, s.area())});
  }
  cv::Mat grey;
  cv::cvtColor(make_image(45, 38, 3), grey, cv::COLOR_RGB2GRAY);
  cases.push_back({"grey_45x38.png", grey});
  cv::Mat rgba, alpha(29, 31, CV_8U);
  cv::randu(alpha, 0, 256);
  cv::merge(std::vector<cv::Mat>{make_image(31, 29, 4), alpha}, rgba);
  cases.push_back({"rgba_31x29.png", rgba});
  return cases;
}

std::optional<fs::path> real_image() {
  const fs::path dir = fs::path(RAINDROP_SHARED_DATA) / "real-raindrop";
  std::error_code ec;
  if (std::string(RAINDROP_SHARED_DATA).empty() || !fs::is_directory(dir, ec)) return std::nullopt;
  std::vector<fs::path> pngs;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.path().extension() == ".png") pngs.push_back(e.path());
  }
  std::sort(pngs.begin(), pngs.end());
  // The first small RGB PNG (JPEGs are avoided: OpenCV's and OpenImageIO's decoders may differ).
  for (const auto& p : pngs) {
    const auto img = read_image(p);
    if (img && img->channels == 3 && img->width * img->height <= 800 * 600) return p;
  }
  return std::nullopt;
}

#define SKIP_WITHOUT_PYTHON()                                                                      \
  if (python().empty())                                                                            \
  GTEST_SKIP() << "RAINDROP_PYTHON is not set (configure with -DRAINDROP_PYTHON=<python with tools "  \
                  "installed>, e.g. .venv/bin/python); the Python parity tests cannot run"

// Runs both programs on `cases` (written to tmp/in) and compares.
// `extra` goes to both programs, `cpp_extra` to raindrop-remove only.
void check_parity(const TempDir& tmp, const fs::path& models, const std::vector<Case>& cases,
                  const std::vector<std::string>& extra = {}, const std::vector<std::string>& cpp_extra = {}) {
  const fs::path in = tmp / "in", cpp = tmp / "cpp", cpp_mask = tmp / "cpp_mask", py = tmp / "py";
  fs::remove_all(in);
  fs::remove_all(cpp);
  fs::remove_all(cpp_mask);
  fs::remove_all(py);
  fs::create_directories(py);
  nlohmann::json jobs = nlohmann::json::array();
  for (const auto& c : cases) {
    if (c.image.empty()) {
      fs::create_directories(in);
      fs::copy_file(c.source, in / c.name);
    } else {
      write_image(in / c.name, c.image);
    }
  }
  for (const auto& c : cases) {
    std::vector<std::string> argv = {(in / c.name).string(), (py / c.name).string(), "--models", models.string(),
                                     "--mask", (py / ("mask_" + c.name)).string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    jobs.push_back(argv);
  }
  write_file(tmp / "jobs.json", jobs.dump());
  write_file(tmp / "driver.py",
             "import json, sys\n"
             "from raindrop_tools.reference import main\n"
             "for argv in json.load(open(sys.argv[1])):\n"
             "    rc = main(argv)\n"
             "    if rc:\n"
             "        sys.exit(f'reference failed ({rc}) on {argv}')\n");
  const RunResult pr = run_command(python(), {(tmp / "driver.py").string(), (tmp / "jobs.json").string()}, tmp.path(),
                                   {"OMP_NUM_THREADS=1"});
  ASSERT_EQ(pr.code, 0) << pr.describe();

  // The reference is the contract's single pass; the coarse pass for large drops is ours alone
  // (large_drops.h) and is tested on its own (test_large_drops.cpp), as is the detector router
  // (test_detector_router.cpp). The fill of small drops from their surround is off in the
  // reference unless asked for (Parity.SurroundFill asks), and so is its growth into rims.
  std::vector<std::string> args = {in.string(), cpp.string(), "--models", models.string(), "--mask",
                                   cpp_mask.string(), "-q", "--threads", "2", "--no-large-drops", "--no-router"};
  if (std::find(extra.begin(), extra.end(), "--surround-fill-area") == extra.end()) {
    args.push_back("--surround-fill-area");
    args.push_back("0");
  }
  // The rims' growth likewise (on by default here, off in the reference unless asked for).
  if (std::find(extra.begin(), extra.end(), "--surround-fill-rim") == extra.end()) {
    args.push_back("--surround-fill-rim");
    args.push_back("0");
  }
  args.insert(args.end(), extra.begin(), extra.end());
  args.insert(args.end(), cpp_extra.begin(), cpp_extra.end());
  const RunResult cr = run_remove(args, tmp.path());
  ASSERT_EQ(cr.code, 0) << cr.describe();

  for (const auto& c : cases) {
    SCOPED_TRACE(c.name + " with " + models.string());
    const auto input = read_image(in / c.name);
    const auto ours = read_image(cpp / c.name);
    const auto ref = read_image(py / c.name);
    const auto our_mask = read_image(cpp_mask / c.name);
    const auto ref_mask = read_image(py / ("mask_" + c.name));
    ASSERT_TRUE(input && ours && ref && our_mask && ref_mask);
    ASSERT_EQ(ours->channels, input->channels) << "the output keeps the input's channels";
    ASSERT_EQ(ref->channels, 3);
    cv::Mat ours_rgb;
    if (input->channels == 1) {
      // The reference works on the grey image replicated to RGB and writes RGB; ours is the
      // luma of that RGB (computed before rounding), so compare with the luma of its output.
      cv::Mat ref_luma(ref->height, ref->width, CV_8U);
      for (int y = 0; y < ref->height; ++y) {
        for (int x = 0; x < ref->width; ++x) {
          const cv::Vec3b p = ref->pixels.at<cv::Vec3b>(y, x);
          ref_luma.at<unsigned char>(y, x) =
              static_cast<unsigned char>(std::floor((0.299f * p[0] + 0.587f * p[1]) + 0.114f * p[2] + 0.5f));
        }
      }
      EXPECT_LE(max_abs_diff(ours->pixels, ref_luma), 1);
    } else {
      if (input->channels == 4) {
        cv::cvtColor(ours->pixels, ours_rgb, cv::COLOR_RGBA2RGB);
        cv::Mat a_in, a_out;
        cv::extractChannel(input->pixels, a_in, 3);
        cv::extractChannel(ours->pixels, a_out, 3);
        EXPECT_EQ(cv::countNonZero(a_in != a_out), 0) << "alpha must pass through";
      } else {
        ours_rgb = ours->pixels;
      }
      EXPECT_LE(max_abs_diff(ours_rgb, ref->pixels), 1) << "output differs by more than 1/255";
    }
    ASSERT_EQ(our_mask->channels, 1);
    EXPECT_EQ(max_abs_diff(our_mask->pixels, ref_mask->pixels), 0) << "masks differ";
  }
}

TEST(Parity, SmokeModelsOnGeneratedImages) {
  SKIP_WITHOUT_PYTHON();
  TempDir tmp;
  check_parity(tmp, smoke_models(), generated_cases());
}

TEST(Parity, ThresholdAndDilationOverrides) {
  SKIP_WITHOUT_PYTHON();
  TempDir tmp;
  std::vector<Case> cases = {{"a.png", make_image(90, 70, 21)}, {"b.png", make_image(13, 41, 22)}};
  check_parity(tmp, smoke_models(), cases, {"--threshold", "0.35", "--dilation", "5"});
  check_parity(tmp, smoke_models(), cases, {"--threshold", "0.1", "--dilation", "1"});
}

TEST(Parity, SmokeModelsOnARealImage) {
  SKIP_WITHOUT_PYTHON();
  const auto real = real_image();
  if (!real) GTEST_SKIP() << "no small RGB PNG in " << RAINDROP_SHARED_DATA << "/real-raindrop; real-image parity not checked";
  TempDir tmp;
  check_parity(tmp, smoke_models(), {{real->filename().string(), cv::Mat(), *real}});
}

// The fixture graphs with raindrop.pad_multiple = 8: exercises replicate padding (of the
// image and of the edge map computed before padding), the padded mask, and the crop.
TEST(Parity, PaddedModels) {
  SKIP_WITHOUT_PYTHON();
  TempDir tmp;
  const fs::path pad8 = tmp / "pad8";
  write_file(tmp / "pad.py",
             "import sys, onnx, pathlib\n"
             "src, dst = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])\n"
             "dst.mkdir(parents=True, exist_ok=True)\n"
             "for n in ('rdn', 'rrn', 'rfn'):\n"
             "    m = onnx.load(str(src / f'{n}.onnx'))\n"
             "    for p in m.metadata_props:\n"
             "        if p.key == 'raindrop.pad_multiple':\n"
             "            p.value = '8'\n"
             "    onnx.save(m, str(dst / f'{n}.onnx'))\n");
  const RunResult r = run_command(python(), {(tmp / "pad.py").string(), smoke_models().string(), pad8.string()}, tmp.path());
  if (r.code != 0 && r.err.find("No module named 'onnx'") != std::string::npos)
    GTEST_SKIP() << "the Python environment has no onnx package to make the padded variant";
  ASSERT_EQ(r.code, 0) << r.describe();
  std::vector<Case> cases;
  for (const cv::Size s : {cv::Size(1, 1), cv::Size(7, 5), cv::Size(33, 17), cv::Size(61, 45)})
    cases.push_back({"p_" + std::to_string(s.width) + "x" + std::to_string(s.height) + ".png", make_image(s.width, s.height, s.area() + 1)});
  check_parity(tmp, pad8, cases);
  // Tiled (3 x 2 windows aligned to 8, overlap/4 = 12 > the fixture's radius of 11) with
  // padding, against the reference's whole image.
  cases = {{"big.png", make_image(203, 150, 77)}};
  check_parity(tmp, pad8, cases, {}, {"--tile", "128", "--tile-overlap", "48"});
}

// The fill of small drops from their surround (surround_fill.h), implemented in numpy by the
// reference (surround_fill.py): small dark dots on a smooth gradient, found by the fixture
// models' detector at 0.25, filled by both sides alike. Without the fill the output differs,
// so the comparison covers it.
TEST(Parity, SurroundFill) {
  SKIP_WITHOUT_PYTHON();
  TempDir tmp;
  cv::Mat img(96, 128, CV_8UC3);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<unsigned char>(100 + x / 2), static_cast<unsigned char>(140 + y / 4), 170);
  for (int k = 0; k < 6; ++k) cv::circle(img, {15 + 20 * k, 20 + 10 * k}, 2, cv::Scalar(20, 20, 20), cv::FILLED);
  // Three of them with a ring that the fill's rim growth (--surround-fill-rim) takes in.
  for (int k = 0; k < 3; ++k) cv::circle(img, {25 + 40 * k, 70}, 5, cv::Scalar(60, 60, 60), cv::FILLED);
  for (int k = 0; k < 3; ++k) cv::circle(img, {25 + 40 * k, 70}, 2, cv::Scalar(20, 20, 20), cv::FILLED);
  const std::vector<Case> cases = {{"dots.png", img}};
  for (const char* mad : {"4", "255"}) {
    SCOPED_TRACE(std::string("--surround-fill-mad ") + mad);
    check_parity(tmp, smoke_models(), cases,
                 {"--threshold", "0.25", "--surround-fill-area", "150", "--surround-fill-mad", mad});
    // The rim growth alike on both sides, and not a no-op here: the output moves against rim 0.
    TempDir rim_tmp;
    check_parity(rim_tmp, smoke_models(), cases,
                 {"--threshold", "0.25", "--surround-fill-area", "150", "--surround-fill-mad", mad,
                  "--surround-fill-rim", "3"});
    const auto rim0 = read_image(tmp / "cpp" / "dots.png"), rim3 = read_image(rim_tmp / "cpp" / "dots.png");
    ASSERT_TRUE(rim0 && rim3);
    EXPECT_GT(max_abs_diff(rim0->pixels, rim3->pixels), 1) << "the rims must change the output beyond the tolerance";
    const RunResult r = run_remove({(tmp / "in" / "dots.png").string(), (tmp / "off.png").string(), "--models",
                                    smoke_models().string(), "--threshold", "0.25", "--no-large-drops",
                                    "--surround-fill-area", "0"},
                                   tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    const auto on = read_image(tmp / "cpp" / "dots.png"), off = read_image(tmp / "off.png");
    ASSERT_TRUE(on && off);
    EXPECT_GT(max_abs_diff(on->pixels, off->pixels), 1) << "the fill must change the output beyond the tolerance";
  }
}

TEST(Parity, TrainedModels) {
  SKIP_WITHOUT_PYTHON();
  const auto dirs = trained_models();
  if (dirs.empty()) GTEST_SKIP() << "no trained models in " << (source_dir() / "models") << " yet";
  for (const auto& dir : dirs) {
    TempDir tmp;
    std::vector<Case> cases = {{"a.png", make_image(64, 48, 31)}, {"b.png", make_image(37, 23, 32)}};
    cv::Mat grey;
    cv::cvtColor(make_image(40, 30, 33), grey, cv::COLOR_RGB2GRAY);
    cases.push_back({"g.png", grey});
    check_parity(tmp, dir, cases);
  }
}

}  // namespace
}  // namespace removetest

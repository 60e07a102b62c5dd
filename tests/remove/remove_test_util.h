#pragma once
// Helpers for the raindrop-remove tests: temporary folders, running the program with its
// output captured, generated test images, reading images back with OpenImageIO (independent
// of the program's own image_io), and where the models are.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "../common/png_bytes.h"
#include "../common/test_images.h"
#include "../common/test_support.h"
#include "raindrop/common/demo.h"

#ifndef RAINDROP_REMOVE_BIN
#error "RAINDROP_REMOVE_BIN must name the raindrop-remove binary"
#endif
#ifndef RAINDROP_SOURCE_DIR
#error "RAINDROP_SOURCE_DIR must name the source tree"
#endif
#ifndef RAINDROP_SHARED_DATA
#define RAINDROP_SHARED_DATA ""
#endif
#ifndef RAINDROP_PYTHON
#define RAINDROP_PYTHON ""
#endif
// Empty where the renderer is not built (-DRAINDROP_BUILD_RENDER=OFF): the tests that render
// their inputs with it skip (REQUIRE_RENDER).
#ifndef RAINDROP_RENDER_BIN
#define RAINDROP_RENDER_BIN ""
#endif
#define REQUIRE_RENDER()                                                                       \
  do {                                                                                         \
    if (std::string(RAINDROP_RENDER_BIN).empty())                                              \
      GTEST_SKIP() << "raindrop-render is not built (RAINDROP_BUILD_RENDER=OFF): test skipped"; \
  } while (0)

namespace removetest {

namespace fs = std::filesystem;
using testsupport::hidden_temporaries;
using testsupport::read_file;
using testsupport::RunResult;
using testsupport::shell_quote;
using testsupport::split_lines;
using testsupport::write_file;

class TempDir : public testsupport::TempDir {
 public:
  TempDir() : testsupport::TempDir("raindrop-remove-") {}
};

inline fs::path remove_bin() { return fs::path(RAINDROP_REMOVE_BIN); }
inline fs::path source_dir() { return fs::path(RAINDROP_SOURCE_DIR); }
inline fs::path smoke_models() { return source_dir() / "tools" / "tests" / "fixtures" / "models-smoke"; }
inline std::string python() { return RAINDROP_PYTHON; }

// Trained model folders present in the source tree (models/<config>/rdn.onnx ...).
inline std::vector<fs::path> trained_models() {
  std::vector<fs::path> dirs;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(source_dir() / "models", ec)) {
    if (e.is_directory() && fs::exists(e.path() / "rdn.onnx") && fs::exists(e.path() / "rrn.onnx") &&
        fs::exists(e.path() / "rfn.onnx"))
      dirs.push_back(e.path());
  }
  std::sort(dirs.begin(), dirs.end());
  return dirs;
}

// Runs `program args...` in `cwd` with `env` assignments ("NAME=value") prepended;
// RAINDROP_MODELS is cleared unless `env` sets it, so the tests do not depend on the caller's.
inline RunResult run_command(const fs::path& program, const std::vector<std::string>& args, const fs::path& cwd,
                             const std::vector<std::string>& env = {}) {
  std::string prefix = "env -u RAINDROP_MODELS ";
  for (const auto& e : env) prefix += shell_quote(e) + " ";
  return testsupport::run_captured(program, args, cwd, prefix);
}

inline RunResult run_remove(const std::vector<std::string>& args, const fs::path& cwd,
                            const std::vector<std::string>& env = {}) {
  return run_command(remove_bin(), args, cwd, env);
}

// ---------------------------------------------------------------------------------------
// Images through OpenImageIO.

using testsupport::Image;
using testsupport::read_image;
using testsupport::write_image;

// A deterministic 8-bit RGB test image of any size: the demo street (structure, edges)
// with seeded bright discs (drop-like blobs) and a little noise.
inline cv::Mat make_image(int width, int height, int seed) {
  // (demo_street needs some room: it loops forever below 18 pixels of height.)
  cv::Mat img = raindrop::demo_street(std::max(width, 64), std::max(height, 64));
  if (img.cols != width || img.rows != height) img = img(cv::Rect(0, 0, width, height)).clone();
  cv::RNG rng(static_cast<std::uint64_t>(7000 + seed));
  for (int i = 0; i < 5; ++i) {
    const cv::Point c(rng.uniform(0, width), rng.uniform(0, height));
    const int r = rng.uniform(1, std::max(2, std::min(width, height) / 5));
    cv::circle(img, c, r, cv::Scalar(rng.uniform(120, 256), rng.uniform(120, 256), rng.uniform(120, 256)), cv::FILLED,
               cv::LINE_AA);
  }
  cv::Mat noise(img.size(), CV_8UC3);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 12);
  cv::add(img, noise, img);
  return img;
}

// " word word ... word", `n` times: the numbers of a key file's line (ROUTER, a wet gate).
inline std::string repeated_words(int n, const std::string& word) {
  std::string s;
  for (int i = 0; i < n; ++i) s += " " + word;
  return s;
}
inline int max_abs_diff(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return 1 << 30;
  cv::Mat d;
  cv::absdiff(a.reshape(1), b.reshape(1), d);
  double mx = 0;
  cv::minMaxLoc(d, nullptr, &mx);
  return static_cast<int>(mx);
}

using testsupport::png_chunk;
using testsupport::png_chunks;
using testsupport::png_declaring;
using testsupport::png_from_chunks;

// `model` (an ONNX file's bytes) with one more metadata entry: a top-level ModelProto field 14
// (tag 0x72), a message {1: key, 2: value}, appended (protobuf reads fields in any order).
inline std::string with_added_metadata(const std::string& model, const std::string& key, const std::string& value) {
  const std::string body = std::string{'\x0a', static_cast<char>(key.size())} + key +
                           std::string{'\x12', static_cast<char>(value.size())} + value;
  EXPECT_LT(body.size(), 128u);
  return model + '\x72' + static_cast<char>(body.size()) + body;
}

}  // namespace removetest

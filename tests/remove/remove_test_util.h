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

#include "../common/test_images.h"
#include "../common/test_support.h"
#include "raindrop/render/demo.h"

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

inline int max_abs_diff(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return 1 << 30;
  cv::Mat d;
  cv::absdiff(a.reshape(1), b.reshape(1), d);
  double mx = 0;
  cv::minMaxLoc(d, nullptr, &mx);
  return static_cast<int>(mx);
}

// CRC-32 (PNG's), for hand-made PNG headers.
inline std::uint32_t crc32(const std::string& bytes) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (unsigned char b : bytes) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return c ^ 0xFFFFFFFFu;
}

inline std::string be32(std::uint32_t v) {
  return std::string{static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8), static_cast<char>(v)};
}

inline std::string png_chunk(const std::string& type, const std::string& data) {
  return be32(static_cast<std::uint32_t>(data.size())) + type + data + be32(crc32(type + data));
}

// A PNG that declares width x height (8-bit RGB) but holds no pixel data.
inline std::string png_declaring(std::uint32_t width, std::uint32_t height) {
  const std::string sig = "\x89PNG\r\n\x1a\n";
  const std::string ihdr = be32(width) + be32(height) + std::string{8, 2, 0, 0, 0};
  // An IDAT (an empty zlib stream) so that libpng's header reading stops there cleanly.
  const std::string idat{'\x78', '\x9c', '\x03', '\x00', '\x00', '\x00', '\x00', '\x01'};
  return sig + png_chunk("IHDR", ihdr) + png_chunk("IDAT", idat) + png_chunk("IEND", "");
}

// A PNG's chunks in order: (type, data).
inline std::vector<std::pair<std::string, std::string>> png_chunks(const std::string& png) {
  std::vector<std::pair<std::string, std::string>> chunks;
  size_t at = 8;
  while (at + 12 <= png.size()) {
    const auto* b = reinterpret_cast<const unsigned char*>(png.data() + at);
    const std::uint32_t n = (std::uint32_t{b[0]} << 24) | (std::uint32_t{b[1]} << 16) | (std::uint32_t{b[2]} << 8) | b[3];
    chunks.emplace_back(png.substr(at + 4, 4), png.substr(at + 8, n));
    at += 12 + n;
  }
  return chunks;
}

// The PNG with the given chunks, CRCs recomputed (so that only the content is wrong).
inline std::string png_from_chunks(const std::vector<std::pair<std::string, std::string>>& chunks) {
  std::string png = "\x89PNG\r\n\x1a\n";
  for (const auto& [type, data] : chunks) png += png_chunk(type, data);
  return png;
}

}  // namespace removetest

#pragma once
// Helpers for the raindrop-remove tests: temporary folders, running the program with its
// output captured, generated test images, reading images back with OpenImageIO (independent
// of the program's own image_io), and where the models are.
#include <gtest/gtest.h>

#include <sys/types.h>
#include <sys/wait.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "raindrop/demo.h"

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

// A fresh folder per test, removed afterwards (kept when RAINDROP_KEEP_TEST_DIRS is set).
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = "raindrop-remove-";
    if (info) name += std::string(info->test_suite_name()) + "-" + info->name() + "-";
    for (char& c : name) {
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-') c = '_';
    }
    std::string templ = (fs::temp_directory_path() / (name + "XXXXXX")).string();
    std::vector<char> buf(templ.begin(), templ.end());
    buf.push_back('\0');
    if (!::mkdtemp(buf.data())) throw std::runtime_error("mkdtemp failed for " + templ);
    path_ = fs::path(buf.data());
  }
  ~TempDir() {
    if (std::getenv("RAINDROP_KEEP_TEST_DIRS")) return;
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }
  fs::path operator/(const std::string& rel) const { return path_ / rel; }

 private:
  fs::path path_;
};

inline std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

inline std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_file(const fs::path& p, const std::string& bytes) {
  if (p.has_parent_path()) fs::create_directories(p.parent_path());
  std::ofstream out(p, std::ios::binary);
  out << bytes;
}

inline std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

struct RunResult {
  int code = -1;
  std::string out, err, command;
  std::string describe() const {
    return "command: " + command + "\nexit code: " + std::to_string(code) + "\n--- stdout ---\n" + out +
           "--- stderr ---\n" + err + "--------------";
  }
};

// Runs `program args...` in `cwd` with `env` assignments ("NAME=value") prepended;
// RAINDROP_MODELS is cleared unless `env` sets it, so the tests do not depend on the caller's.
inline RunResult run_command(const fs::path& program, const std::vector<std::string>& args, const fs::path& cwd,
                             const std::vector<std::string>& env = {}) {
  static int counter = 0;
  const fs::path logs = cwd / "_logs";
  fs::create_directories(logs);
  const std::string tag = std::to_string(counter++);
  const fs::path out_file = logs / ("stdout-" + tag), err_file = logs / ("stderr-" + tag);
  std::string cmd = "cd " + shell_quote(cwd.string()) + " && env -u RAINDROP_MODELS";
  for (const auto& e : env) cmd += " " + shell_quote(e);
  cmd += " " + shell_quote(program.string());
  for (const auto& a : args) cmd += " " + shell_quote(a);
  RunResult r;
  r.command = cmd;
  cmd += " >" + shell_quote(out_file.string()) + " 2>" + shell_quote(err_file.string()) + " </dev/null";
  const int status = std::system(cmd.c_str());
  r.code = (status != -1 && WIFEXITED(status)) ? WEXITSTATUS(status) : -1;
  r.out = read_file(out_file);
  r.err = read_file(err_file);
  return r;
}

inline RunResult run_remove(const std::vector<std::string>& args, const fs::path& cwd,
                            const std::vector<std::string>& env = {}) {
  return run_command(remove_bin(), args, cwd, env);
}

// ---------------------------------------------------------------------------------------
// Images through OpenImageIO.

struct Image {
  int width = 0, height = 0, channels = 0;
  OIIO::TypeDesc format;
  cv::Mat pixels;  // CV_8UC(n) or CV_16UC(n), as stored
};

inline std::optional<Image> read_image(const fs::path& p, std::string* why = nullptr) {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(p.string(), &config);
  if (!in) {
    if (why) *why = OIIO::geterror();
    return std::nullopt;
  }
  const OIIO::ImageSpec& spec = in->spec();
  Image img;
  img.width = spec.width;
  img.height = spec.height;
  img.channels = spec.nchannels;
  img.format = spec.format;
  const bool sixteen = spec.format == OIIO::TypeDesc::UINT16;
  img.pixels.create(img.height, img.width, sixteen ? CV_16UC(img.channels) : CV_8UC(img.channels));
  if (!in->read_image(0, 0, 0, img.channels, sixteen ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::UINT8, img.pixels.data)) {
    if (why) *why = in->geterror();
    return std::nullopt;
  }
  return img;
}

// 8/16-bit, 1-4 channels, RGB(A) order.
inline void write_image(const fs::path& p, const cv::Mat& m) {
  if (p.has_parent_path()) fs::create_directories(p.parent_path());
  auto out = OIIO::ImageOutput::create(p.string());
  ASSERT_TRUE(out) << OIIO::geterror();
  const OIIO::TypeDesc type = m.depth() == CV_16U ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::UINT8;
  OIIO::ImageSpec spec(m.cols, m.rows, m.channels(), type);
  if (m.channels() == 4 || m.channels() == 2) {
    spec.alpha_channel = m.channels() - 1;
    spec.attribute("oiio:UnassociatedAlpha", 1);
  }
  const cv::Mat data = m.isContinuous() ? m : m.clone();
  ASSERT_TRUE(out->open(p.string(), spec)) << out->geterror();
  ASSERT_TRUE(out->write_image(type, data.data)) << out->geterror();
  ASSERT_TRUE(out->close()) << out->geterror();
}

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

// Hidden temporaries left by atomic writes: ".<name>.tmp-<pid>-<n>".
inline std::vector<std::string> hidden_temporaries(const fs::path& dir) {
  std::vector<std::string> found;
  std::error_code ec;
  for (const auto& e : fs::recursive_directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.size() > 1 && name[0] == '.' && name.find(".tmp-") != std::string::npos) found.push_back(name);
  }
  return found;
}

}  // namespace removetest

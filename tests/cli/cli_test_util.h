#pragma once
// Helpers for the end-to-end tests of raindrop-render: temporary folders, running the
// binary with its stdout/stderr captured, reading and writing images with OpenImageIO
// (independently of the renderer's own image_io), manifests and folder snapshots.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "../common/test_images.h"
#include "../common/test_support.h"
#include "raindrop/common/demo.h"

#ifndef RAINDROP_RENDER_BIN
#error "RAINDROP_RENDER_BIN must name the raindrop-render binary"
#endif
#ifndef RAINDROP_SHARED_DATA
#define RAINDROP_SHARED_DATA ""
#endif

namespace clitest {

namespace fs = std::filesystem;
using testsupport::hidden_temporaries;
using testsupport::read_file;
using testsupport::shell_quote;
using testsupport::split_lines;
using testsupport::write_file;

class TempDir : public testsupport::TempDir {
 public:
  TempDir() : testsupport::TempDir("raindrop-cli-") {}
};
using json = nlohmann::json;

inline fs::path render_bin() { return fs::path(RAINDROP_RENDER_BIN); }

// The progress bar writes lines such as "render [####....] 3/8  1.20/s  ETA 0:02".
inline bool is_progress_line(const std::string& line) { return line.rfind("render [", 0) == 0; }

struct RunResult : testsupport::RunResult {
  // stderr without progress-bar lines
  std::vector<std::string> message_lines() const {
    std::vector<std::string> lines;
    for (const auto& l : split_lines(err)) {
      if (!is_progress_line(l)) lines.push_back(l);
    }
    return lines;
  }
};

// Runs raindrop-render with `args` in folder `cwd`; stdout/stderr go to files beside it.
inline RunResult run_render(const std::vector<std::string>& args, const fs::path& cwd) {
  return RunResult{testsupport::run_captured(render_bin(), args, cwd)};
}

// ---------------------------------------------------------------------------------------
// Images through OpenImageIO.

using testsupport::Image;
using testsupport::read_image;
using testsupport::write_image;

// Distinct 8-bit RGB backgrounds: the demo street or checkerboard, tinted and with a few
// seeded discs (compressible, so PNG encoding stays fast).
inline cv::Mat make_background(int width, int height, int seed) {
  cv::Mat img = (seed % 2 == 0) ? raindrop::demo_street(width, height) : raindrop::demo_checkerboard(width, height);
  cv::RNG rng(static_cast<std::uint64_t>(1000 + seed));
  const cv::Scalar tint(rng.uniform(-30, 30), rng.uniform(-30, 30), rng.uniform(-30, 30));
  img += cv::Scalar::all(40);  // room for a negative tint
  img += tint;
  img -= cv::Scalar::all(40);
  for (int i = 0; i < 6; ++i) {
    const cv::Point centre(rng.uniform(0, width), rng.uniform(0, height));
    const int radius = rng.uniform(2, std::max(3, std::min(width, height) / 6));
    cv::circle(img, centre, radius, cv::Scalar(rng.uniform(0, 256), rng.uniform(0, 256), rng.uniform(0, 256)),
               cv::FILLED, cv::LINE_AA);
  }
  return img;
}

// ---------------------------------------------------------------------------------------
// Data-set folders.

inline std::vector<std::string> manifest_lines(const fs::path& out_dir) {
  return split_lines(read_file(out_dir / "manifest.jsonl"));
}

inline std::vector<json> read_manifest(const fs::path& out_dir) {
  std::vector<json> records;
  for (const auto& l : manifest_lines(out_dir)) records.push_back(json::parse(l));
  return records;
}

inline size_t count_newlines(const fs::path& p) {
  const std::string s = read_file(p);
  return static_cast<size_t>(std::count(s.begin(), s.end(), '\n'));
}

// Every regular file under `dir` (recursively, hidden ones included): relative path -> bytes.
inline std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  if (!fs::exists(dir)) return files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) files[fs::relative(e.path(), dir).generic_string()] = read_file(e.path());
  }
  return files;
}

// Regular files under `dir`, recursively (relative paths).
inline std::vector<std::string> list_files(const fs::path& dir) {
  std::vector<std::string> names;
  if (!fs::exists(dir)) return names;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) names.push_back(fs::relative(e.path(), dir).generic_string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// Files in rainy/, clean/ and mask/ (any file, hidden or not).
inline std::vector<std::string> sample_files(const fs::path& out_dir) {
  std::vector<std::string> all;
  for (const char* sub : {"rainy", "clean", "mask"}) {
    for (const auto& f : list_files(out_dir / sub)) all.push_back(std::string(sub) + "/" + f);
  }
  return all;
}

// "N rendered, M already done, K failed" from the summary line; nullopt if absent.
struct Counts {
  long rendered = -1, skipped = -1, failed = -1;
};
inline std::optional<Counts> parse_counts(const std::string& err) {
  for (const auto& line : split_lines(err)) {
    Counts c;
    if (std::sscanf(line.c_str(), "raindrop-render: %ld rendered, %ld already done, %ld failed", &c.rendered,
                    &c.skipped, &c.failed) == 3)
      return c;
  }
  return std::nullopt;
}

// "WxHxC format" for failure messages.
inline std::string image_summary(const std::optional<Image>& img) {
  if (!img) return "undecodable";
  return std::to_string(img->width) + "x" + std::to_string(img->height) + "x" + std::to_string(img->channels) +
         " " + img->format.c_str();
}

// Exit code 1, exactly one non-progress line on stderr (the error), nothing on stdout, and
// no file of any kind under rainy/, clean/ or mask/.
inline void expect_clean_failure(const RunResult& r, const fs::path& out_dir, const std::string& must_mention) {
  EXPECT_EQ(r.code, 1) << r.describe();
  const auto lines = r.message_lines();
  ASSERT_EQ(lines.size(), 1u) << "expected exactly one error line\n" << r.describe();
  EXPECT_EQ(lines[0].rfind("raindrop-render: error: ", 0), 0u) << r.describe();
  if (!must_mention.empty()) {
    EXPECT_NE(lines[0].find(must_mention), std::string::npos) << r.describe();
  }
  EXPECT_EQ(r.out, "") << r.describe();
  EXPECT_TRUE(sample_files(out_dir).empty()) << "files left behind under " << out_dir << ": "
                                            << ::testing::PrintToString(sample_files(out_dir));
}

// A street (256x128) rendered with the paper's imaging model and 20 drops, with or without one
// more scene effect that acts on the rainy image only (sensor, veil): the tests of such effects
// compare the two renders of one seed.
class RainyOnlyEffect : public ::testing::Test {
 protected:
  explicit RainyOnlyEffect(std::string effect) : effect_(std::move(effect)) {}
  void SetUp() override { write_image(tmp / "street.png", make_background(256, 128, 2)); }

  // Renders street.png with the effect's JSON object `settings` ("" for none) into folder
  // `name`; returns its one manifest record.
  json render(const std::string& name, const std::string& settings) {
    const std::string effects = R"("blur": {})" + (settings.empty() ? "" : ", \"" + effect_ + "\": " + settings);
    write_file(tmp / (name + ".json"), "{\"name\": \"" + effect_ + R"(-test", "glass_distance_cm": 20, "drop_count": 20, "effects": {)" +
                                           effects + "}}");
    const auto r = run_render({"-i", "street.png", "--out", name, "--scene", name + ".json", "--seed", "5", "-j", "1", "-q"},
                              tmp.path());
    EXPECT_EQ(r.code, 0) << r.describe();
    const auto records = read_manifest(tmp / name);
    EXPECT_EQ(records.size(), 1u);
    return records.empty() ? json() : records[0];
  }

  // The clean image and the mask of folder `other` are byte for byte those of `plain`, the
  // drops are the same, and the record names the effect and says it applies to the rainy image.
  void expect_only_rainy_changed(const json& plain, const json& rec, const std::string& other) {
    SCOPED_TRACE(other);
    const std::string id = plain.at("id");
    EXPECT_EQ(read_file(tmp / "plain/clean" / (id + ".png")), read_file(tmp / other / "clean" / (id + ".png")));
    EXPECT_EQ(read_file(tmp / "plain/mask" / (id + ".png")), read_file(tmp / other / "mask" / (id + ".png")));
    EXPECT_EQ(plain.at("drops"), rec.at("drops")) << "turning " << effect_ << " on must not change the scene's draws";
    EXPECT_NE(std::find(rec.at("effects").begin(), rec.at("effects").end(), effect_), rec.at("effects").end());
    EXPECT_EQ(rec.at(effect_).at("applies_to"), "rainy");
  }

  TempDir tmp;

 private:
  std::string effect_;
};

}  // namespace clitest

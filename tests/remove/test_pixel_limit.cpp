// The input pixel limit (image_io.h: kMaxImagePixels, 2^26 pixels) in both programs: a PNG of
// a few hundred bytes that declares more is refused from its header with one line, before
// anything is decoded or written; one at the limit passes that check.
#include "remove_test_util.h"

namespace removetest {
namespace {

void expect_limit_refusal(const RunResult& r) {
  EXPECT_EQ(r.code, 1) << r.describe();
  const auto lines = split_lines(r.err);
  ASSERT_EQ(lines.size(), 1u) << r.describe();
  EXPECT_NE(lines[0].find("big.png"), std::string::npos) << r.describe();
  EXPECT_NE(lines[0].find("exceeds the input limit"), std::string::npos) << r.describe();
}

// 16000 x 16000 (256 megapixels): rendering such a file took 3 GB.
TEST(PixelLimit, RenderRefusesADeclared16000Square) {
  REQUIRE_RENDER();
  TempDir tmp;
  write_file(tmp / "big.png", png_declaring(16000, 16000));
  const RunResult r = run_command(RAINDROP_RENDER_BIN, {"-i", "big.png", "--out", "out", "-j", "1"}, tmp.path());
  expect_limit_refusal(r);
  EXPECT_FALSE(fs::exists(tmp / "out"));
}

TEST(PixelLimit, RemoveRefusesADeclared16000Square) {
  TempDir tmp;
  write_file(tmp / "big.png", png_declaring(16000, 16000));
  const RunResult r = run_remove({"big.png", "out.png", "--models", smoke_models().string()}, tmp.path());
  expect_limit_refusal(r);
  EXPECT_FALSE(fs::exists(tmp / "out.png"));
}

// One pixel past the limit is refused; the limit itself passes the size check (and then fails
// for its missing pixel data, which these files do not have).
TEST(PixelLimit, TheBoundary) {
  REQUIRE_RENDER();
  TempDir tmp;
  write_file(tmp / "big.png", png_declaring(8192, 8193));
  expect_limit_refusal(run_command(RAINDROP_RENDER_BIN, {"-i", "big.png", "--out", "out", "-j", "1"}, tmp.path()));
  write_file(tmp / "at.png", png_declaring(8192, 8192));
  const RunResult r = run_command(RAINDROP_RENDER_BIN, {"-i", "at.png", "--out", "out", "-j", "1"}, tmp.path());
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_EQ(r.err.find("limit"), std::string::npos) << r.describe();
  EXPECT_NE(r.err.find("truncated"), std::string::npos) << r.describe();
}

}  // namespace
}  // namespace removetest

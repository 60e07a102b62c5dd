// raindrop-remove keeps the input's depth and channels where the output format can hold them;
// where it cannot (16-bit RGBA written as .jpg), the output is written and one warning line
// says what was lost.
#include "remove_test_util.h"

namespace removetest {
namespace {

cv::Mat rgba16() {
  cv::Mat rgb8 = make_image(40, 30, 3), alpha(30, 40, CV_8U, cv::Scalar(200)), rgba8, out;
  cv::merge(std::vector<cv::Mat>{rgb8, alpha}, rgba8);
  rgba8.convertTo(out, CV_16U, 257.0);
  return out;
}

TEST(FormatLoss, Rgba16AsJpegWarnsOnce) {
  TempDir tmp;
  write_image(tmp / "in.png", rgba16());
  const RunResult r = run_remove({"in.png", "out.jpg", "--models", smoke_models().string()}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto lines = split_lines(r.err);
  ASSERT_EQ(lines.size(), 1u) << "expected one warning line\n" << r.describe();
  EXPECT_EQ(lines[0].rfind("raindrop-remove: warning: 'out.jpg': ", 0), 0u) << r.describe();
  EXPECT_NE(lines[0].find("8 bits"), std::string::npos) << r.describe();
  EXPECT_NE(lines[0].find("alpha"), std::string::npos) << r.describe();
  const auto out = read_image(tmp / "out.jpg");
  ASSERT_TRUE(out);
  EXPECT_EQ(out->format, OIIO::TypeDesc::UINT8);
}

// GIF keeps a palette of 256 colours: written, but not silently.
TEST(FormatLoss, GifSaysItQuantises) {
  TempDir tmp;
  write_image(tmp / "in.png", make_image(40, 30, 3));
  const RunResult r = run_remove({"in.png", "out.gif", "--models", smoke_models().string()}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto lines = split_lines(r.err);
  ASSERT_EQ(lines.size(), 1u) << r.describe();
  EXPECT_NE(lines[0].find("'out.gif': gif holds 256 colours: colours quantised to a palette"), std::string::npos)
      << r.describe();
}

// OpenEXR stores half floats, about 11 bits: a 16-bit input loses depth there (said), an 8-bit
// one does not; both hold linear light (image_io's test checks the values).
TEST(FormatLoss, ExrSaysWhenHalfFloatsLoseDepth) {
  TempDir tmp;
  write_image(tmp / "in16.png", rgba16());
  write_image(tmp / "in8.png", make_image(40, 30, 3));
  RunResult r = run_remove({"in16.png", "out16.exr", "--models", smoke_models().string()}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("stored as half floats (about 11 bits)"), std::string::npos) << r.describe();
  r = run_remove({"in8.png", "out8.exr", "--models", smoke_models().string()}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(r.err, "") << r.describe();
}

TEST(FormatLoss, FormatsThatHoldItSayNothing) {
  TempDir tmp;
  write_image(tmp / "in.png", rgba16());
  for (const std::string out : {"out.png", "out.tif"}) {
    const RunResult r = run_remove({"in.png", out, "--models", smoke_models().string()}, tmp.path());
    EXPECT_EQ(r.code, 0) << r.describe();
    EXPECT_EQ(r.err, "") << r.describe();
  }
}

}  // namespace
}  // namespace removetest

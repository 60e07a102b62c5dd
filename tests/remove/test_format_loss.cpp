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

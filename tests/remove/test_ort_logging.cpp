// When ONNX Runtime fails inside a run (here: an allocation, under an address-space limit), the
// user sees raindrop-remove's one error line, not ONNX Runtime's own coloured log lines first.
#include "remove_test_util.h"

namespace removetest {
namespace {

TEST(OrtLogging, AllocationFailureIsOurOneLine) {
  TempDir tmp;
  // Flat, so the PNG is small; 2000x2000 untiled at full scale needs more than 1.2 GB inside
  // ONNX Runtime with the smoke models, while loading them fits. (`--scale 1`: at the default
  // working scale the networks see a 512-pixel image, which fits, and this test skipped.)
  write_image(tmp / "in.png", cv::Mat(2000, 2000, CV_8UC3, cv::Scalar(90, 120, 150)));
  const std::vector<std::string> args = {"in.png", "out.png", "--tile", "0", "--scale", "1", "-j", "1", "--models",
                                         smoke_models().string()};
  const RunResult r = testsupport::run_captured(remove_bin(), args, tmp.path(), "ulimit -v 1200000 && env -u RAINDROP_MODELS ");
  if (r.code == 0 || r.err.find("inference failed") == std::string::npos)
    GTEST_SKIP() << "this machine did not fail inside ONNX Runtime under the limit\n" << r.describe();
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_EQ(split_lines(r.err).size(), 1u) << "ONNX Runtime's own log lines came first\n" << r.describe();
  EXPECT_EQ(r.err.rfind("raindrop-remove: error: ", 0), 0u) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "out.png"));
}

}  // namespace
}  // namespace removetest

// End-to-end: an input that raindrop-render refuses by its header (depth, channels, size) stops
// the run before anything is written: no output folder, no manifest, no sample, even when the
// refused file comes after good ones and one thread renders them in order.
#include "cli_test_util.h"

namespace clitest {
namespace {

struct Refused {
  std::string name;  // file name, third in the folder's order
  cv::Mat pixels;
};

std::vector<Refused> refused_inputs() {
  const cv::Mat rgb = make_background(96, 64, 3);
  cv::Mat deep, grey, rgba, tiny, linear, five;
  rgb.convertTo(deep, CV_16UC3, 257.0);
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  cv::cvtColor(rgb, rgba, cv::COLOR_RGB2RGBA);
  tiny = rgb(cv::Rect(0, 0, 8, 8)).clone();
  rgb.convertTo(linear, CV_32FC3, 1.0 / 255.0);
  cv::merge(std::vector<cv::Mat>{grey, grey, grey, grey, grey}, five);
  return {{"c_16bit.png", deep}, {"c_grey.png", grey},  {"c_rgba.png", rgba},
          {"c_tiny.png", tiny},  {"c_float.exr", linear}, {"c_five.tif", five}};
}

TEST(RenderRefusal, RefusedThirdInputWritesNothing) {
  for (const auto& bad : refused_inputs()) {
    SCOPED_TRACE(bad.name);
    TempDir tmp;
    write_image(tmp / "in" / "a.png", make_background(96, 64, 0));
    write_image(tmp / "in" / "b.png", make_background(96, 64, 1));
    write_image(tmp / "in" / bad.name, bad.pixels);
    const auto r = run_render({"-i", "in", "--out", "out", "-j", "1"}, tmp.path());
    expect_clean_failure(r, tmp / "out", bad.name);
    EXPECT_FALSE(fs::exists(tmp / "out")) << "a refused run must not make the output folder: "
                                          << ::testing::PrintToString(list_files(tmp / "out"));
  }
}

// An input whose header passes and whose data does not decode (a JPEG cut short): found only
// when it is rendered. When it is the run's only input, the folder the run made goes with the
// empty manifest and folders it had made; a folder with a sample rendered before stays.
TEST(RenderRefusal, AnUndecodableOnlyInputLeavesNoFolderBehind) {
  TempDir tmp;
  write_image(tmp / "in" / "b.jpg", make_background(320, 240, 1));
  const auto size = fs::file_size(tmp / "in" / "b.jpg");
  fs::resize_file(tmp / "in" / "b.jpg", size * 6 / 10);
  auto r = run_render({"-i", "in/b.jpg", "--out", "out", "-j", "1"}, tmp.path());
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_EQ(r.message_lines().size(), 1u) << r.describe();
  EXPECT_NE(r.err.find("b.jpg"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "out")) << ::testing::PrintToString(list_files(tmp / "out"));
  write_image(tmp / "in" / "a.png", make_background(96, 64, 0));  // rendered first at -j1
  r = run_render({"-i", "in", "--out", "out", "-j", "1"}, tmp.path());
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_TRUE(fs::exists(tmp / "out" / "rainy" / "a_v00.png"));
  EXPECT_EQ(read_file(tmp / "out" / "manifest.jsonl").find("b_v00"), std::string::npos);
}

// Into an existing data set: the refusal leaves the folder as it was (the lock file goes too).
TEST(RenderRefusal, RefusedInputLeavesAnExistingFolderAsItWas) {
  TempDir tmp;
  write_image(tmp / "in" / "a.png", make_background(96, 64, 0));
  const auto first = run_render({"-i", "in", "--out", "out", "-j", "1", "-q"}, tmp.path());
  ASSERT_EQ(first.code, 0) << first.describe();
  const auto before = snapshot(tmp / "out");
  cv::Mat grey;
  cv::cvtColor(make_background(96, 64, 1), grey, cv::COLOR_RGB2GRAY);
  write_image(tmp / "in" / "b.png", make_background(96, 64, 2));  // new, rendered first at -j1
  write_image(tmp / "in" / "c_grey.png", grey);
  const auto r = run_render({"-i", "in", "--out", "out", "-j", "1"}, tmp.path());
  EXPECT_EQ(r.code, 1) << r.describe();
  ASSERT_EQ(r.message_lines().size(), 1u) << r.describe();
  EXPECT_NE(r.message_lines()[0].find("c_grey.png"), std::string::npos) << r.describe();
  EXPECT_EQ(snapshot(tmp / "out"), before) << "the refused run changed the existing data set";
}

}  // namespace
}  // namespace clitest

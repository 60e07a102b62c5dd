// End-to-end: a file given to --input that is neither an image (by its extension) nor a text
// list of image paths, such as a GIF or any binary file, is refused with one line that says so.
#include "cli_test_util.h"

namespace clitest {
namespace {

TEST(RenderInputListFile, BinaryFileIsNotReadAsAList) {
  TempDir tmp;
  // Its bytes, NULs included (the length said by the array, not counted by hand).
  static const char kGif[] = "GIF89a\x10\x00\x10\x00\x80\x00\x00\xff\xff\xff\n\x00\x00\x00!\xf9\x04\x01\x00\x00\x00\x00,";
  const std::string bytes(kGif, sizeof kGif - 1);
  write_file(tmp / "anim.gif", bytes);
  const auto r = run_render({"-i", "anim.gif", "--out", "out", "-j", "1"}, tmp.path());
  expect_clean_failure(r, tmp / "out", "anim.gif");
  EXPECT_NE(r.err.find("not a text list"), std::string::npos) << r.describe();
  EXPECT_EQ(r.err.find('\x01'), std::string::npos) << "binary bytes in the message";
  EXPECT_FALSE(fs::exists(tmp / "out"));
}

// A text list is still a list (and its comments and blank lines still ignored).
TEST(RenderInputListFile, TextListStillWorks) {
  TempDir tmp;
  write_image(tmp / "a.png", make_background(96, 64, 0));
  write_file(tmp / "list.txt", "# inputs\n\na.png\r\n");
  const auto r = run_render({"-i", "list.txt", "--out", "out", "-j", "1", "-q"}, tmp.path());
  EXPECT_EQ(r.code, 0) << r.describe();
}

}  // namespace
}  // namespace clitest

// image_files.h: one rule for which files are images, shared by both programs' folder inputs.
#include <fstream>

#include <gtest/gtest.h>

#include "../common/test_support.h"
#include "raindrop/common/error.h"
#include "raindrop/common/image_files.h"

namespace fs = std::filesystem;
using raindrop::has_image_extension;
using raindrop::is_image_name;
using raindrop::list_image_files;

namespace {

void touch(const fs::path& p) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << "x";
}

std::vector<std::string> names(const std::vector<fs::path>& files, const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& f : files) out.push_back(f.lexically_relative(dir).generic_string());
  return out;
}

}  // namespace

TEST(ImageFiles, ExtensionsInAnyCase) {
  for (const char* name : {"a.png", "a.PNG", "a.jpg", "a.JPEG", "a.tif", "a.tiff", "a.exr", "a.bmp", "a.webp"})
    EXPECT_TRUE(has_image_extension(name)) << name;
  for (const char* name : {"a.txt", "a", "a.png.tmp", "a.gif", "a.json", "png"})
    EXPECT_FALSE(has_image_extension(name)) << name;
  EXPECT_EQ(raindrop::image_extensions(), "bmp, exr, jpeg, jpg, png, tif, tiff, webp");
}

TEST(ImageFiles, HiddenFilesAreNotFolderInputs) {
  EXPECT_TRUE(is_image_name("dir/a.png"));
  EXPECT_FALSE(is_image_name("dir/.a.png"));      // a temporary being written
  EXPECT_TRUE(has_image_extension("dir/.a.png"));  // but named on a command line, it is an image
}

TEST(ImageFiles, ListsRecursivelySortedSkippingFolders) {
  testsupport::TempDir tmp("raindrop-common-");
  const fs::path dir = tmp.path() / "in";
  for (const char* f : {"b.png", "a.JPG", "sub/c.exr", "sub/deeper/d.tif", "out/x.png", "out/nested/y.png",
                        ".hidden.png", "notes.txt", "sub/.e.png"})
    touch(dir / f);
  EXPECT_EQ(names(list_image_files(dir, true, {dir / "out"}), dir),
            (std::vector<std::string>{"a.JPG", "b.png", "sub/c.exr", "sub/deeper/d.tif"}));
  EXPECT_EQ(names(list_image_files(dir, false), dir), (std::vector<std::string>{"a.JPG", "b.png"}));
  // The skipped folder named another way ("in/sub/.."-style) is still skipped.
  EXPECT_EQ(names(list_image_files(dir, true, {dir / "sub" / ".." / "out", dir / "sub"}), dir),
            (std::vector<std::string>{"a.JPG", "b.png"}));
  EXPECT_THROW(list_image_files(tmp.path() / "missing", true), raindrop::Error);
}

TEST(ImageFiles, ASymbolicLinkLoopIsSkippedNotTheWholeFolder) {
  // A loop (or a link to itself) cannot be examined: it is neither a folder nor an image, and
  // the folder's images are still listed (it used to stop the walk with 'Too many levels of
  // symbolic links').
  testsupport::TempDir tmp("raindrop-common-");
  const fs::path dir = tmp.path() / "in";
  touch(dir / "a.png");
  touch(dir / "sub/b.png");
  fs::create_directory_symlink("loop2", dir / "loop1");
  fs::create_directory_symlink("loop1", dir / "loop2");
  fs::create_symlink("self.png", dir / "self.png");
  fs::create_directory_symlink("self", dir / "sub" / "self");
  std::vector<fs::path> unfollowed;
  EXPECT_EQ(names(list_image_files(dir, true, {}, &unfollowed), dir), (std::vector<std::string>{"a.png", "sub/b.png"}));
  EXPECT_TRUE(unfollowed.empty());
  EXPECT_EQ(names(list_image_files(dir, false), dir), (std::vector<std::string>{"a.png"}));
}

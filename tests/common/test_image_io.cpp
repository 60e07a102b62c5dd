// Image input conversions that the CLI tests do not reach: float (linear) files.
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "raindrop/common/error.h"
#include "raindrop/common/image_io.h"

using namespace raindrop;

TEST(ImageIo, FloatInputsAreSrgbEncodedWhenConverted) {
  const auto path = std::filesystem::temp_directory_path() / ("raindrop_linear_" + std::to_string(::getpid()) + ".exr");
  const float pixels[4 * 3] = {0.0f, 0.5f, 1.0f, 0.0031308f, 2.0f, -1.0f, 0.2140f, 0.2140f, 0.2140f, 1e9f, 0.0f, 0.5f};
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out);
  OIIO::ImageSpec spec(2, 2, 3, OIIO::TypeDesc::FLOAT);
  ASSERT_TRUE(out->open(path.string(), spec) && out->write_image(OIIO::TypeDesc::FLOAT, pixels) && out->close());
  EXPECT_THROW(read_rgb8(path, false, 1), Error);  // strict mode refuses float input
  const cv::Mat rgb = read_rgb8(path, true, 1);
  auto encode = [](double v) {
    v = std::min(std::max(v, 0.0), 1.0);
    v = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
    return static_cast<int>(std::floor(v * 255 + 0.5));
  };
  for (int i = 0; i < 12; ++i) {
    EXPECT_NEAR(rgb.data[i], encode(pixels[i]), 1) << i;
  }
  EXPECT_EQ(rgb.at<cv::Vec3b>(0, 0)[1], 188);  // linear 0.5 is sRGB 0.7354
  EXPECT_EQ(rgb.at<cv::Vec3b>(1, 0)[0], 127);  // linear 0.214 is sRGB 0.4999 (127.47)
  std::filesystem::remove(path);
}

// A failed rename must report its own error, not that of the clean-up after it (which
// succeeds, so the message read "(Success)").
TEST(ImageIo, FailedRenameReportsItsOwnError) {
  const auto dir = std::filesystem::temp_directory_path() / ("raindrop_rename_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir / "taken.png" / "inside");  // a non-empty folder by the final name
  std::filesystem::create_directories(dir / "taken.txt" / "inside");
  const cv::Mat img(4, 4, CV_8UC3, cv::Scalar(1, 2, 3));
  for (int text = 0; text < 2; ++text) {
    try {
      if (text) {
        write_text_atomic("hello\n", dir / "taken.txt");
      } else {
        write_image_atomic(img, dir / "taken.png");
      }
      ADD_FAILURE() << "writing over a folder succeeded";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("cannot move the finished file into place"), std::string::npos) << what;
      EXPECT_EQ(what.find("Success"), std::string::npos) << what;
      EXPECT_NE(what.find(std::strerror(EISDIR)), std::string::npos) << what;
    }
  }
  size_t left = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) left += e.path().filename().string()[0] == '.';
  EXPECT_EQ(left, 0u) << "temporaries left behind";
  std::filesystem::remove_all(dir);
}

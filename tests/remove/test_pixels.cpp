// pixels.h: rounding and conversions between the image formats and the networks' floats.
#include <cmath>
#include <limits>

#include "raindrop/common/error.h"
#include "raindrop/remove/pixels.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

TEST(Pixels, RoundingAndConversions) {
  // floor(clamp(x) * 255 + 0.5): round half up, clamped, NaN -> 0.
  EXPECT_EQ(to_u8(0.0f), 0);
  EXPECT_EQ(to_u8(1.0f), 255);
  EXPECT_EQ(to_u8(-3.0f), 0);
  EXPECT_EQ(to_u8(7.0f), 255);
  EXPECT_EQ(to_u8(std::numeric_limits<float>::quiet_NaN()), 0);
  EXPECT_EQ(to_u8(0.5f / 255.0f), 1);
  EXPECT_EQ(to_u8(0.49f / 255.0f), 0);
  EXPECT_EQ(to_u8(100.5f / 255.0f), 101) << "half rounds up";
  EXPECT_EQ(to_u8(100.49f / 255.0f), 100);
  EXPECT_EQ(to_u16(1.0f), 65535);
  EXPECT_EQ(to_u16(0.5f), 32768);
  // Every 8-bit value survives the round trip v / 255 -> to_u8.
  for (int v = 0; v < 256; ++v) {
    cv::Mat px(1, 1, CV_8UC3, cv::Scalar(v, v, v));
    const cv::Mat f = to_rgb_float(px, cv::Rect(0, 0, 1, 1));
    ASSERT_EQ(f.at<cv::Vec3f>(0, 0)[0], static_cast<float>(v) / 255.0f);
    ASSERT_EQ(to_u8(f.at<cv::Vec3f>(0, 0)[0]), v);
  }
  // Grey is replicated; RGBA's alpha is not part of the colour.
  cv::Mat grey(1, 1, CV_16UC1, cv::Scalar(65535));
  EXPECT_EQ(to_rgb_float(grey, {0, 0, 1, 1}).at<cv::Vec3f>(0, 0), cv::Vec3f(1, 1, 1));
  cv::Mat rgba(1, 1, CV_8UC4, cv::Scalar(0, 51, 255, 7));
  EXPECT_EQ(to_rgb_float(rgba, {0, 0, 1, 1}).at<cv::Vec3f>(0, 0), cv::Vec3f(0, 0.2f, 1));
  // Grey output is the luma of the RGB result.
  cv::Mat rgb(1, 1, CV_32FC3, cv::Scalar(1.0, 0.0, 0.0));
  cv::Mat out(1, 1, CV_8UC1);
  store_rgb_float(rgb, out, 0);
  EXPECT_EQ(out.at<unsigned char>(0, 0), to_u8(0.299f));
  EXPECT_THROW(check_input_format(cv::Mat()), raindrop::Error);
  EXPECT_THROW(check_input_format(cv::Mat(2, 2, CV_64FC3)), raindrop::Error);
}

}  // namespace
}  // namespace removetest

// JPEG through libjpeg (src/common/jpeg_file.cpp) against OpenImageIO as the reference: the same
// settings (so the same pixels after decoding), the same decoded pixels from any file, the same
// refusal of files that end early, and what JPEG cannot hold reported.
#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include "raindrop/common/error.h"
#include "raindrop/common/image_io.h"
#include "test_images.h"
#include "test_support.h"

using namespace raindrop;
using testsupport::read_image;
using testsupport::street_like;
using testsupport::write_image;
namespace fs = std::filesystem;

namespace {

bool same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

// OpenImageIO's own JPEG round trip in memory at `quality`.
cv::Mat oiio_round_trip(const cv::Mat& rgb, int quality) {
  std::vector<unsigned char> bytes;
  OIIO::Filesystem::IOVecOutput sink(bytes);
  auto out = OIIO::ImageOutput::create("memory.jpg");
  OIIO::ImageSpec spec(rgb.cols, rgb.rows, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("Compression", "jpeg:" + std::to_string(quality));
  EXPECT_TRUE(out->set_ioproxy(&sink) && out->open("memory.jpg", spec) && out->write_image(OIIO::TypeDesc::UINT8, rgb.data) &&
              out->close());
  OIIO::Filesystem::IOMemReader source(bytes.data(), bytes.size());
  auto in = OIIO::ImageInput::create("jpeg");
  OIIO::ImageSpec got;
  cv::Mat decoded(rgb.rows, rgb.cols, CV_8UC3);
  EXPECT_TRUE(in->set_ioproxy(&source) && in->open("memory.jpg", got) &&
              in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, decoded.data));
  return decoded;
}

}  // namespace

TEST(JpegFile, RoundTripMatchesOpenImageIOs) {
  const cv::Mat rgb = street_like(72, 104, 3);
  for (int quality : {30, 60, 95}) {
    const cv::Mat ours = jpeg_round_trip(rgb, quality);
    EXPECT_TRUE(same(ours, oiio_round_trip(rgb, quality))) << "quality " << quality;
    EXPECT_GT(cv::norm(ours, rgb, cv::NORM_INF), 0) << "a lossy codec changed nothing at quality " << quality;
  }
  EXPECT_THROW(jpeg_round_trip(rgb, 0), Error);
  EXPECT_THROW(jpeg_round_trip(rgb, 101), Error);
}

TEST(JpegFile, FilesDecodeAsOpenImageIODecodesThem) {
  testsupport::TempDir tmp("raindrop-jpeg-");
  for (int channels : {1, 3}) {
    SCOPED_TRACE("channels " + std::to_string(channels));
    const cv::Mat m = street_like(45, 67, channels);
    // Written by OpenImageIO (its default quality), read by both.
    write_image(tmp / "theirs.jpg", m);
    std::string why;
    const auto reference = read_image(tmp / "theirs.jpg", &why);
    ASSERT_TRUE(reference) << why;
    EXPECT_TRUE(same(read_image_native(tmp / "theirs.jpg"), reference->pixels));
    // Written by us: the same settings, so the same pixels as OpenImageIO's file.
    EXPECT_EQ(write_image_atomic(m, tmp / "ours.jpeg"), "");
    const auto ours = read_image(tmp / "ours.jpeg", &why);
    ASSERT_TRUE(ours) << why;
    EXPECT_TRUE(same(ours->pixels, reference->pixels)) << "our JPEG settings differ from OpenImageIO's";
  }
}

TEST(JpegFile, WhatJpegCannotHoldIsReported) {
  testsupport::TempDir tmp("raindrop-jpeg-");
  cv::Mat rgba16(20, 24, CV_16UC4, cv::Scalar(257 * 10, 257 * 200, 257 * 90, 65535));
  EXPECT_EQ(write_image_atomic(rgba16, tmp / "a.jpg"), "jpeg cannot hold this 16-bit RGBA image: rounded to 8 bits, alpha dropped");
  cv::Mat ga8(20, 24, CV_8UC2, cv::Scalar(128, 7));
  EXPECT_EQ(write_image_atomic(ga8, tmp / "b.jpg"), "jpeg cannot hold this 8-bit grey+alpha image: alpha dropped");
  const cv::Mat a = read_image_native(tmp / "a.jpg");
  ASSERT_EQ(a.type(), CV_8UC3);
  EXPECT_NEAR(a.at<cv::Vec3b>(10, 10)[1], 200, 2);
  EXPECT_EQ(read_image_native(tmp / "b.jpg").type(), CV_8UC1);
}

// A file cut short decodes to grey rows in libjpeg, with only a warning: refused, like a
// damaged one; the whole file reads.
TEST(JpegFile, FilesThatEndEarlyAreRefused) {
  testsupport::TempDir tmp("raindrop-jpeg-");
  write_image_atomic(street_like(120, 160, 3), tmp / "whole.jpg");
  const std::string bytes = testsupport::read_file(tmp / "whole.jpg");
  for (size_t cut : {bytes.size() / 3, bytes.size() - 2}) {
    SCOPED_TRACE(cut);
    std::ofstream(tmp / "cut.jpg", std::ios::binary) << bytes.substr(0, cut);
    try {
      read_image_native(tmp / "cut.jpg");
      ADD_FAILURE() << "a cut file decoded";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("cannot decode"), std::string::npos) << e.what();
    }
  }
  EXPECT_NO_THROW(read_image_native(tmp / "whole.jpg"));
}

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
using testsupport::write_image;
namespace fs = std::filesystem;

namespace {

// Colour gradients with edges: what a photograph's blocks look like to the codec.
cv::Mat street_like(int rows, int cols, int channels) {
  cv::Mat m(rows, cols, CV_8UC(channels));
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x)
      for (int c = 0; c < channels; ++c)
        m.ptr<uchar>(y)[x * channels + c] = static_cast<uchar>((x * (c + 1) + y * 3 + ((x / 8 + y / 8) % 2) * 60) & 255);
  return m;
}

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

// Damaged files: cut at about 100 lengths, and 300 copies with one byte changed each:
// each read either decodes the image whole or throws raindrop::Error with one line naming the
// file; nothing else escapes, nothing crashes (run under the sanitizers: scripts/test-sanitizers.sh),
// and libpng/libjpeg print nothing of their own.
TEST(ImageFiles, DamagedPngAndJpegFailInOneLine) {
  testsupport::TempDir tmp("raindrop-damaged-");
  const cv::Mat m = street_like(23, 31, 3);
  for (const std::string name : {"a.png", "a.jpg"}) {
    write_image_atomic(m, tmp / name);
    const std::string bytes = testsupport::read_file(tmp / name);
    std::mt19937 rng(11);
    int refused = 0, decoded = 0;
    auto attempt = [&](const std::string& damaged) {
      std::ofstream(tmp / ("bad-" + name), std::ios::binary | std::ios::trunc) << damaged;
      try {
        const cv::Mat got = read_image_native(tmp / ("bad-" + name));
        EXPECT_EQ(got.size(), m.size());
        ++decoded;
      } catch (const Error& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
        EXPECT_NE(what.find("bad-" + name), std::string::npos) << what;
        ++refused;
      }
    };
    testing::internal::CaptureStderr();
    for (size_t cut = 0; cut < bytes.size(); cut += std::max<size_t>(1, bytes.size() / 97)) attempt(bytes.substr(0, cut));
    for (int i = 0; i < 300; ++i) {
      std::string damaged = bytes;
      damaged[rng() % damaged.size()] ^= static_cast<char>(1 + rng() % 255);  // never the same byte
      attempt(damaged);
    }
    const std::string printed = testing::internal::GetCapturedStderr();
    EXPECT_EQ(printed, "") << name << ": a library printed on its own";
    EXPECT_GT(refused, 90) << name;  // every cut file at least
    if (name == "a.png") {
      EXPECT_EQ(decoded, 0) << "every changed byte of a PNG breaks a CRC";
    } else {
      EXPECT_GT(decoded, 0) << "a changed byte inside a JPEG's entropy-coded data still decodes";
    }
  }
}

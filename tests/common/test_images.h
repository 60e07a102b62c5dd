#pragma once
// Images through OpenImageIO for the end-to-end tests of both programs: reading what a program
// wrote exactly as stored, and writing fixtures of any depth and channel count.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>

#include <OpenImageIO/imageio.h>
#include <opencv2/core.hpp>

namespace testsupport {

struct Image {
  int width = 0, height = 0, channels = 0;
  OIIO::TypeDesc format;  // as stored
  cv::Mat pixels;         // CV_8UC(channels) or CV_16UC(channels), as stored (alpha not premultiplied)
};

// Decodes the whole file in its stored format (which catches truncation); std::nullopt (and
// *why) if it cannot be opened or fully decoded, or is neither 8- nor 16-bit with 1-4 channels.
inline std::optional<Image> read_image(const std::filesystem::path& p, std::string* why = nullptr) {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(p.string(), &config);
  if (!in) {
    if (why) *why = OIIO::geterror();
    return std::nullopt;
  }
  const OIIO::ImageSpec& spec = in->spec();
  Image img;
  img.width = spec.width;
  img.height = spec.height;
  img.channels = spec.nchannels;
  img.format = spec.format;
  const bool eight = spec.format == OIIO::TypeDesc::UINT8, sixteen = spec.format == OIIO::TypeDesc::UINT16;
  if (!(eight || sixteen) || img.width <= 0 || img.height <= 0 || img.channels < 1 || img.channels > 4) {
    if (why) *why = "unexpected geometry or pixel format " + std::string(spec.format.c_str());
    return std::nullopt;
  }
  img.pixels.create(img.height, img.width, sixteen ? CV_16UC(img.channels) : CV_8UC(img.channels));
  if (!in->read_image(0, 0, 0, img.channels, spec.format, img.pixels.data)) {
    if (why) *why = in->geterror();
    return std::nullopt;
  }
  return img;
}

// Colour gradients with edges: what a photograph's blocks look like to the codec.
inline cv::Mat street_like(int rows, int cols, int channels) {
  cv::Mat m(rows, cols, CV_8UC(channels));
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x)
      for (int c = 0; c < channels; ++c)
        m.ptr<uchar>(y)[x * channels + c] = static_cast<uchar>((x * (c + 1) + y * 3 + ((x / 8 + y / 8) % 2) * 60) & 255);
  return m;
}

// Writes an 8-bit (CV_8U), 16-bit (CV_16U) or float (CV_32F) image with any channel count in
// RGB(A) order (2 and 4 channels: the last is an unassociated alpha), as stored: for the
// refusals too (float, five channels).
inline void write_image(const std::filesystem::path& p, const cv::Mat& m) {
  if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path());
  auto out = OIIO::ImageOutput::create(p.string());
  ASSERT_TRUE(out) << OIIO::geterror();
  const OIIO::TypeDesc type = m.depth() == CV_32F   ? OIIO::TypeDesc::FLOAT
                              : m.depth() == CV_16U ? OIIO::TypeDesc::UINT16
                                                    : OIIO::TypeDesc::UINT8;
  OIIO::ImageSpec spec(m.cols, m.rows, m.channels(), type);
  if (m.channels() == 4 || m.channels() == 2) {
    spec.alpha_channel = m.channels() - 1;
    spec.attribute("oiio:UnassociatedAlpha", 1);
  }
  const cv::Mat data = m.isContinuous() ? m : m.clone();
  ASSERT_TRUE(out->open(p.string(), spec)) << out->geterror();
  ASSERT_TRUE(out->write_image(type, data.data)) << out->geterror();
  ASSERT_TRUE(out->close()) << out->geterror();
}

// A minimal ICC profile that libpng accepts: the 128-byte header (size, version 4.3, a display
// device, `space` ("RGB " or "GRAY"), XYZ connection space, "acsp", the D50 illuminant) and an
// empty tag table, then `filler` bytes of padding that tell profiles apart.
inline std::string test_icc_profile(const char* space, int filler) {
  std::string p(132 + 4 * static_cast<size_t>(filler), '\0');
  const auto put32 = [&p](size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) p[at + i] = static_cast<char>(v >> (24 - 8 * i));
  };
  put32(0, static_cast<std::uint32_t>(p.size()));
  put32(8, 0x04300000);
  std::memcpy(&p[12], "mntr", 4);
  std::memcpy(&p[16], space, 4);
  std::memcpy(&p[20], "XYZ ", 4);
  std::memcpy(&p[36], "acsp", 4);
  put32(68, 0x0000F6D6);  // D50: X 0.9642, Y 1.0, Z 0.8249 (s15Fixed16)
  put32(72, 0x00010000);
  put32(76, 0x0000D32D);
  for (int i = 0; i < filler; ++i) put32(132 + 4 * static_cast<size_t>(i), static_cast<std::uint32_t>(i * 2654435761u));
  return p;
}

}  // namespace testsupport

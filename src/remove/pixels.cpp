#include "raindrop/remove/pixels.h"

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "raindrop/common/error.h"

namespace raindrop::removal {
namespace {

const std::array<float, 256>& lut8() {
  static const std::array<float, 256> lut = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[i] = static_cast<float>(i) / 255.0f;
    return t;
  }();
  return lut;
}

const std::vector<float>& lut16() {
  static const std::vector<float> lut = [] {
    std::vector<float> t(65536);
    for (int i = 0; i < 65536; ++i) t[i] = static_cast<float>(i) / 65535.0f;
    return t;
  }();
  return lut;
}

template <class T, class F>
void convert_rows(const cv::Mat& image, const cv::Rect& roi, cv::Mat& out, F&& value) {
  const int nc = image.channels();
  for (int y = 0; y < roi.height; ++y) {
    const T* src = image.ptr<T>(roi.y + y) + static_cast<size_t>(roi.x) * nc;
    float* dst = out.ptr<float>(y);
    for (int x = 0; x < roi.width; ++x, src += nc, dst += 3) {
      if (nc <= 2) {
        dst[0] = dst[1] = dst[2] = value(src[0]);
      } else {
        dst[0] = value(src[0]);
        dst[1] = value(src[1]);
        dst[2] = value(src[2]);
      }
    }
  }
}

}  // namespace

float clamp01(float v) {
  // Written so that NaN fails both comparisons and ends at 0.
  if (!(v > 0.0f)) return 0.0f;
  return v < 1.0f ? v : 1.0f;
}

unsigned char to_u8(float v) { return static_cast<unsigned char>(std::floor(clamp01(v) * 255.0f + 0.5f)); }
unsigned short to_u16(float v) { return static_cast<unsigned short>(std::floor(clamp01(v) * 65535.0f + 0.5f)); }

void check_input_format(const cv::Mat& image) {
  if (image.empty()) throw Error("empty image");
  const int d = image.depth(), nc = image.channels();
  if (d != CV_8U && d != CV_16U && d != CV_32F)
    throw Error("unsupported pixel type (expected 8-bit, 16-bit or float channels)");
  if (nc < 1 || nc > 4) throw Error(std::to_string(nc) + " channels are not supported (1-4: grey, grey+alpha, RGB, RGBA)");
}

cv::Mat to_rgb_float(const cv::Mat& image, const cv::Rect& roi) {
  CV_Assert((roi & cv::Rect(0, 0, image.cols, image.rows)) == roi);
  cv::Mat out(roi.height, roi.width, CV_32FC3);
  switch (image.depth()) {
    case CV_8U: {
      const auto& t = lut8();
      convert_rows<unsigned char>(image, roi, out, [&t](unsigned char v) { return t[v]; });
      break;
    }
    case CV_16U: {
      const auto& t = lut16();
      convert_rows<unsigned short>(image, roi, out, [&t](unsigned short v) { return t[v]; });
      break;
    }
    case CV_32F: convert_rows<float>(image, roi, out, [](float v) { return clamp01(v); }); break;
    default: throw Error("unsupported pixel type");
  }
  return out;
}

void store_rgb_float(const cv::Mat& rgb, cv::Mat& output, cv::Point corner) {
  const cv::Rect region(corner, rgb.size());
  CV_Assert(rgb.type() == CV_32FC3 && (region & cv::Rect(0, 0, output.cols, output.rows)) == region);
  const int nc = output.channels(), depth = output.depth(), y0 = corner.y;
  for (int y = 0; y < rgb.rows; ++y) {
    const float* src = rgb.ptr<float>(y);
    for (int x = corner.x; x < corner.x + rgb.cols; ++x, src += 3) {
      float v[3];
      if (nc <= 2) {
        v[0] = luma(clamp01(src[0]), clamp01(src[1]), clamp01(src[2]));
      } else {
        v[0] = src[0], v[1] = src[1], v[2] = src[2];
      }
      const int colours = nc <= 2 ? 1 : 3;
      for (int c = 0; c < colours; ++c) {
        const size_t at = static_cast<size_t>(x) * nc + c;
        if (depth == CV_8U) {
          output.ptr<unsigned char>(y0 + y)[at] = to_u8(v[c]);
        } else if (depth == CV_16U) {
          output.ptr<unsigned short>(y0 + y)[at] = to_u16(v[c]);
        } else {
          output.ptr<float>(y0 + y)[at] = clamp01(v[c]);
        }
      }
    }
  }
}

void copy_alpha(const cv::Mat& input, cv::Mat& output) {
  const int nc = input.channels();
  if (nc != 2 && nc != 4) return;
  CV_Assert(input.type() == output.type() && input.size() == output.size());
  const int from_to[] = {nc - 1, nc - 1};
  cv::mixChannels(&input, 1, &output, 1, from_to, 1);
}

}  // namespace raindrop::removal

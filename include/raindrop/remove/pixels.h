#pragma once
// The conversions between the images people have and what the networks see.
//
// The networks see RGB in [0, 1] (docs/CONTRACTS.md section 2). Inputs may be 8- or 16-bit
// (or float, through the library), with 1-4 channels:
//   grey        -> replicated to RGB (what the Python reference's cv2.IMREAD_COLOR does);
//                  the output is converted back with the luma Y = 0.299 R + 0.587 G + 0.114 B
//                  (the weights of the evaluation protocol and of cv::COLOR_RGB2GRAY),
//                  computed on the float output before rounding;
//   grey+alpha  -> as grey, alpha copied through unchanged;
//   RGB         -> as is;
//   RGBA        -> RGB (alpha ignored, not composited: PNG alpha is unassociated), alpha
//                  copied through unchanged.
// 8-bit values are v / 255 in float32 (correctly rounded, as numpy's division), 16-bit ones
// v / 65535; the output is floor(clamp(x, 0, 1) * max + 0.5), max = 255 or 65535 (round half
// up, as tools/raindrop_tools/imageio.py's to_uint8). Float images (CV_32F) are clamped to
// [0, 1] on the way in and out, without quantisation.
#include <opencv2/core.hpp>

namespace raindrop::removal {

// The luma Y = 0.299 R + 0.587 G + 0.114 B of RGB in [0, 1], summed in that order.
inline float luma(float r, float g, float b) { return (0.299f * r + 0.587f * g) + 0.114f * b; }

// Throws raindrop::Error unless the image is CV_8U/CV_16U/CV_32F with 1-4 channels.
void check_input_format(const cv::Mat& image);

// The pixels of `roi` (inside the image) as CV_32FC3 RGB in [0, 1]. NaN float inputs become 0.
cv::Mat to_rgb_float(const cv::Mat& image, const cv::Rect& roi);

// Writes float RGB pixels (CV_32FC3, values clamped here; NaN -> 0) into `output`, which has
// the input's type, with their top-left corner at `corner`; colour channels only (alpha is
// copied separately with copy_alpha).
void store_rgb_float(const cv::Mat& rgb, cv::Mat& output, cv::Point corner);
// The same for whole rows [y0, y0 + rgb.rows).
inline void store_rgb_float(const cv::Mat& rgb, cv::Mat& output, int y0) { store_rgb_float(rgb, output, cv::Point(0, y0)); }

// Copies the alpha channel of `input` (2 or 4 channels) into `output`; no-op otherwise.
void copy_alpha(const cv::Mat& input, cv::Mat& output);

// floor(clamp(v, 0, 1) * 255 + 0.5) in float32; NaN -> 0.
unsigned char to_u8(float v);
unsigned short to_u16(float v);
float clamp01(float v);

}  // namespace raindrop::removal

#pragma once
// JPEG through libjpeg(-turbo) directly, for grey and colour (YCbCr or RGB) files: loading
// OpenImageIO for them costs raindrop-remove 200 ms of start-up (image_io.cpp). CMYK and YCCK
// files go to OpenImageIO. Written files and the in-memory round trip use OpenImageIO's settings
// (libjpeg's standard tables, 4:2:0 chroma, quality 98 unless given), so the pixels match what
// OpenImageIO made of them. Internal to raindrop_common.
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace raindrop::jpeg {

// OpenImageIO's default quality for JPEG output.
inline constexpr int kDefaultQuality = 98;

struct Info {
  int width = 0, height = 0;
  int channels = 0;  // as decoded: 1 (grey) or 3 (RGB)
  bool native = false;  // decodes here (grey, YCbCr or RGB); otherwise through OpenImageIO
};

// Whether the file starts with a JPEG start-of-image marker.
bool has_signature(const unsigned char* first3);

// Files are read upright: an EXIF Orientation tag is applied as OpenCV's imread applies it
// (exif_orientation.h), so read_info's width and height and decode's pixels are those of the
// image as shown.
//
// The file's header, without decoding pixels. Throws raindrop::Error naming the file if libjpeg
// cannot read it.
Info read_info(const std::filesystem::path& path);

// The pixels of a native file: CV_8UC1 or CV_8UC3 (RGB order). Throws raindrop::Error naming
// the file on any error, and on the warnings that mean missing or damaged pixels (libjpeg would
// fill them with grey: a file cut short, data that ends early); a few stray bytes before a
// marker, which damage nothing, are accepted.
// With `icc`, also the ICC profile its APP2 markers hold ("" when none).
cv::Mat decode(const std::filesystem::path& path, std::string* icc = nullptr);

// Writes `image` (CV_8UC1 or CV_8UC3) as a baseline JPEG of `quality` (1-100).
// With a non-empty `icc` (an ICC profile), APP2 markers hold it.
void encode(const cv::Mat& image, std::FILE* file, int quality, const std::filesystem::path& name,
            const std::string& icc = {});

// The same in memory, and back.
std::vector<unsigned char> encode(const cv::Mat& image, int quality);
cv::Mat decode(const std::vector<unsigned char>& bytes);

}  // namespace raindrop::jpeg

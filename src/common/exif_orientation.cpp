#include "exif_orientation.h"

#include <cstdint>
#include <cstring>

namespace raindrop::exif {

int orientation(const unsigned char* data, std::size_t size) {
  constexpr std::size_t kPrefix = 6;  // "Exif\0\0"
  if (!data || size < kPrefix + 8 || std::memcmp(data, "Exif\0\0", kPrefix) != 0) return 0;
  const unsigned char* tiff = data + kPrefix;
  const std::size_t n = size - kPrefix;
  bool little;
  if (tiff[0] == 'I' && tiff[1] == 'I')
    little = true;
  else if (tiff[0] == 'M' && tiff[1] == 'M')
    little = false;
  else
    return 0;
  // Callers check that [at, at + 2) or [at, at + 4) lies inside the TIFF data.
  auto u16 = [&](std::size_t at) -> std::uint32_t {
    return little ? tiff[at] | tiff[at + 1] << 8 : tiff[at] << 8 | tiff[at + 1];
  };
  auto u32 = [&](std::size_t at) -> std::uint32_t {
    return little ? u16(at) | u16(at + 2) << 16 : u16(at) << 16 | u16(at + 2);
  };
  if (u16(2) != 42) return 0;
  const std::size_t ifd = u32(4);
  if (ifd > n || n - ifd < 2) return 0;
  const std::size_t entries = u16(ifd);
  for (std::size_t i = 0; i < entries; ++i) {
    const std::size_t at = ifd + 2 + 12 * i;
    if (at > n || n - at < 12) return 0;
    if (u16(at) != 0x0112) continue;
    // The value field holds it: a SHORT (type 3) in its first two bytes, a LONG (4) in all four.
    const std::uint32_t type = u16(at + 2);
    if (type != 3 && type != 4) return 0;
    const std::uint32_t value = type == 3 ? u16(at + 8) : u32(at + 8);
    return value >= 1 && value <= 8 ? static_cast<int>(value) : 0;
  }
  return 0;
}

void make_upright(cv::Mat& image, int orientation) {
  // OpenCV's ExifTransform (imgcodecs/src/loadsave.cpp), step for step.
  switch (orientation) {
    case 2: cv::flip(image, image, 1); break;
    case 3: cv::flip(image, image, -1); break;
    case 4: cv::flip(image, image, 0); break;
    case 5: cv::transpose(image, image); break;
    case 6: cv::transpose(image, image); cv::flip(image, image, 1); break;
    case 7: cv::transpose(image, image); cv::flip(image, image, -1); break;
    case 8: cv::transpose(image, image); cv::flip(image, image, 0); break;
    default: break;
  }
}

}  // namespace raindrop::exif

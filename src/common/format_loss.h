#pragma once
// What writing an image in a format lost, in write_image_atomic's words (image_io.h), e.g.
// "jpeg cannot hold this 16-bit RGBA image: rounded to 8 bits, alpha dropped"; "" when nothing.
// Shared by image_io.cpp (PNG, JPEG) and the OpenImageIO plugin (every other format). Internal
// to raindrop_common.
#include <string>

namespace raindrop {

// `depth_lost`: what happened to the depth ("rounded to 8 bits"), or "" when it was kept.
inline std::string format_loss(const std::string& format, int bits, int channels, const std::string& depth_lost,
                               bool alpha_lost) {
  if (depth_lost.empty() && !alpha_lost) return "";
  static const char* const kChannels[] = {"", "grey", "grey+alpha", "RGB", "RGBA"};
  return format + " cannot hold this " + std::to_string(bits) + "-bit " + kChannels[channels] + " image: " +
         depth_lost + (!depth_lost.empty() && alpha_lost ? ", " : "") +
         (alpha_lost ? "alpha dropped" : "");
}

}  // namespace raindrop

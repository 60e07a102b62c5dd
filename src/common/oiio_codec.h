#pragma once
// The OpenImageIO side of image_io.cpp: every format other than the PNG and JPEG files that
// png_file and jpeg_file read and write themselves. It lives in a plugin (raindrop_oiio.so,
// built from src/oiio) that is opened on first use, because linking OpenImageIO makes every
// program load 260 shared libraries at start (200 ms before main on a 2-core machine), most of
// them for formats a street photograph never comes in. Internal to raindrop_common.
#include <filesystem>
#include <string>

#include <opencv2/core.hpp>

#include "raindrop/common/image_io.h"

namespace raindrop::oiio {

// The plugin's entry points. Each throws raindrop::Error with a one-line message naming the file.
struct Codec {
  // kInterface of the build the plugin comes from: a plugin from another build (a stale
  // lib/raindrop) is refused instead of being called with the wrong layout.
  int interface;
  // Opens the file and returns its header (format: OpenImageIO's name for it).
  ImageHeader (*read_header)(const std::filesystem::path& path);
  // The whole image as stored: CV_8UC(n), CV_16UC(n) or, for float files, CV_32FC(n), n = 1-4,
  // RGB(A) order, alpha unassociated. Any error the decoder records is a failed decode.
  cv::Mat (*decode)(const std::filesystem::path& path);
  // Writes `image` (CV_8U/CV_16U, 1-4 channels) to `file` in the format `name`'s extension
  // names (never PNG or JPEG, which image_io.cpp writes itself). Returns what the format could not hold ("" when nothing), as write_image_atomic does.
  std::string (*encode)(const cv::Mat& image, const std::filesystem::path& file, const std::filesystem::path& name);
  // Throws unless OpenImageIO has a writer for `name`'s extension.
  void (*check_writable_format)(const std::filesystem::path& name);
};

// Changes whenever Codec or ImageHeader does.
inline constexpr int kInterface = 1;

// The plugin's one exported symbol returns its Codec. The name carries the interface too, so
// that a plugin from before the interface field fails at dlsym instead of being misread.
inline constexpr const char* kEntryPoint = "raindrop_oiio_codec_v1";
inline constexpr const char* kPluginName = "raindrop_oiio.so";

// The loaded plugin: found beside the program (the build tree), then in ../lib/raindrop (an
// installed tree), or at $RAINDROP_OIIO_PLUGIN when set. Throws raindrop::Error saying that
// `what` needs OpenImageIO and why the plugin did not load; a failure is remembered.
const Codec& codec(const std::string& what);

}  // namespace raindrop::oiio

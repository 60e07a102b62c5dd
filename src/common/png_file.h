#pragma once
// PNG through libpng directly, for the formats the programs meet every day (8- and 16-bit grey,
// grey+alpha, RGB and RGBA): loading OpenImageIO for them costs raindrop-remove 200 ms of start-up
// (image_io.cpp). Everything else a PNG can hold (palettes, 1-4-bit grey, tRNS transparency) goes
// to OpenImageIO, as every other format does. Internal to raindrop_common.
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

namespace raindrop::png {

// What the file's IHDR and chunk list say.
struct Info {
  std::uint32_t width = 0, height = 0;
  int depth = 0;        // bits per sample as stored (1, 2, 4, 8, 16)
  int colour_type = 0;  // 0 grey, 2 RGB, 3 palette, 4 grey+alpha, 6 RGBA
  int channels = 0;     // as decoded: a palette becomes RGB, tRNS adds alpha (OpenImageIO's rule)
  bool has_trns = false;
  bool interlaced = false;
  // This file's pixels decode here (decode()); otherwise through OpenImageIO.
  bool native() const { return (depth == 8 || depth == 16) && colour_type != 3 && !has_trns; }
  // The IDAT chunks' bytes, joined, kept by check(..., check_data = true) for a native()
  // non-interlaced file, so that decode() inflates them without reading the file again.
  std::string image_data;
  // The iCCP chunk's data as stored (profile name, 0, compression method, zlib stream), or empty.
  std::string iccp;
  // The file asks to be shown as sRGB, as an 8-bit image written here is: an sRGB chunk before
  // the image data (which overrides gAMA and cHRM), or none of gAMA, cHRM, iCCP and cICP.
  bool shown_as_srgb = true;
  // Every ancillary chunk is one that changes nothing a reader shows of an opaque image beyond
  // its colour space (sRGB, gAMA, cHRM, sBIT, bKGD, pHYs, tIME, tEXt, zTXt, iTXt): none that
  // turns it (eXIf's orientation), animates it (acTL, fcTL, fdAT) or is unknown here.
  bool plain_ancillaries = true;
  // The whole file's bytes, kept by check(..., keep_file = true).
  std::string file;
};

// The ICC profile an iCCP chunk holds (inflated), or "" when there is none, it does not inflate
// (a damaged profile is dropped, not an error: the pixels are intact) or it would be longer than
// `limit` bytes (inflating stops there: a small chunk can inflate to gigabytes).
std::string icc_profile(const Info& info, std::size_t limit);

// Whether the file starts with PNG's signature.
bool has_signature(const unsigned char* first8);

// Checks the file's structure and returns its header. Throws raindrop::Error naming the file for
// what libpng would otherwise print to stderr itself (through OpenImageIO) or fail on: IHDR first
// and valid, every chunk within the file with a valid CRC, no unknown critical chunk, a palette
// before the data where needed, IEND at the end, chunks in an order libpng takes, and (when
// `check_data`, for a file that is not native(): OpenImageIO's libpng decodes it and would print)
// image data that inflates to every declared row with valid filter types. A native() file's data
// is left to decode(), whose error handler reports the same faults in one line. A declared size
// over kMaxImagePixels is returned without inflating anything (the caller refuses it).
// `keep_file`: also keep the file's bytes in Info::file.
Info check(const std::filesystem::path& path, std::uintmax_t size, bool check_data, bool keep_file = false);

// The pixels of a native() file: CV_8UC(n) or CV_16UC(n), n = info.channels, RGB(A) order,
// alpha as stored. With info.image_data, inflated by libdeflate and unfiltered here (a 2048x1024
// frame in about half libpng's time); any fault there, and every other file, goes to libpng, so
// that damaged files get libpng's verdict. Throws raindrop::Error naming the file on any libpng
// error (nothing printed).
// `from_image_data`, if given: set to whether the pixels came from info.image_data (the bytes
// check() read), not from libpng reading the file again.
cv::Mat decode(const std::filesystem::path& path, const Info& info, bool* from_image_data = nullptr);

// decode()'s own path: info.image_data inflated by libdeflate and unfiltered (every filter type,
// every native depth and channel count); nullopt where there is no such data (header-only
// check, interlaced) or anything is amiss (a stream that does not inflate to exactly the
// declared rows, a bad checksum, an unknown filter type), which decode() then leaves to libpng
// and its messages.
std::optional<cv::Mat> decode_image_data(const Info& info);

// Writes `image` (CV_8U or CV_16U, 1-4 channels) as PNG to `file`: with zlib level `level`
// (0-9) and libpng's adaptive row filters, (kPngRunLength) zlib's run-length strategy with
// Paeth filters, or (kPngFast) Paeth filters deflated by libdeflate. Throws raindrop::Error
// naming `name`.
// With a non-empty `icc` (an ICC profile), an iCCP chunk holds it.
void encode(const cv::Mat& image, std::FILE* file, int level, const std::filesystem::path& name,
            const std::string& icc = {});

}  // namespace raindrop::png

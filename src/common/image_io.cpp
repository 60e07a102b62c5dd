#include "raindrop/common/image_io.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <system_error>
#include <vector>

#include <unistd.h>

#include "format_loss.h"
#include "jpeg_file.h"
#include "oiio_codec.h"
#include "png_file.h"
#include "raindrop/common/error.h"
#include "raindrop/common/image_files.h"
#include "raindrop/common/srgb_curve.h"

namespace raindrop {
namespace fs = std::filesystem;
namespace {

// 16-bit samples rounded to 8 bits: round(v / 257), 65535 -> 255 (as OpenImageIO converts).
cv::Mat round_to_8_bits(const cv::Mat& sixteen) {
  cv::Mat eight;
  sixteen.convertTo(eight, CV_8U, 1.0 / 257.0);
  return eight;
}

// Where a file's pixels come from: libpng and libjpeg directly for everyday PNG and JPEG files,
// OpenImageIO's plugin (oiio_codec.h) for everything else.
enum class Route { png, jpeg, oiio };

struct Opened {
  Route route = Route::oiio;
  ImageHeader header;
  png::Info png;
};

// The file's header, from the codec its first bytes call for. `check_data`: true for a file
// that is about to be decoded, so that the image data of a PNG that OpenImageIO decodes is
// checked row by row first (below); false reads the header alone. Throws a one-line
// Error naming the file for a missing, empty, unreadable or oversized image.
Opened open_image(const fs::path& path, bool check_data = true, bool keep_png_file = false) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(quoted(path) + ": no such file");
  if (fs::is_directory(path, ec)) throw Error(quoted(path) + ": is a folder, not an image");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec || size == 0) throw Error(quoted(path) + ": file is empty");
  unsigned char first[8] = {0};
  {
    std::ifstream f(path, std::ios::binary);
    if (!f) throw Error(quoted(path) + ": cannot open (" + std::strerror(errno) + ")");
    f.read(reinterpret_cast<char*>(first), sizeof first);
    if (f.gcount() < static_cast<std::streamsize>(std::min<std::uintmax_t>(size, sizeof first)))
      throw Error(quoted(path) + ": cannot read (" + (errno ? std::strerror(errno) : "it is shorter than its size") + ")");
  }
  Opened o;
  if (size >= 8 && png::has_signature(first)) {
    // Every chunk is checked (whole, CRCs, order), so that a cut or damaged file is named as
    // such. The image data is inflated and checked row by row only where OpenImageIO decodes it
    // (png::check): its libpng would print its complaints to stderr. png_file decodes with its
    // own error handler, which reports the same problems in one line (and checking first would
    // inflate the image twice: a 2048x1024 frame decoded in 65 ms, 46 without; docs/RESULTS.md
    // section 1).
    o.png = png::check(path, size, check_data, keep_png_file);
    if (o.png.native()) {
      o.route = Route::png;
      o.header = {static_cast<int>(o.png.width), static_cast<int>(o.png.height), o.png.channels, o.png.depth, false, "png"};
    }
  } else if (size >= 3 && jpeg::has_signature(first)) {
    const jpeg::Info info = jpeg::read_info(path);
    if (info.native) {
      o.route = Route::jpeg;
      o.header = {info.width, info.height, info.channels, 8, false, "jpeg"};
    }
  }
  if (o.route == Route::oiio) o.header = oiio::codec(quoted(path) + ": reading this file").read_header(path);
  const ImageHeader& h = o.header;
  if (h.width <= 0 || h.height <= 0 || h.channels <= 0) throw Error(quoted(path) + ": image has no pixels");
  // From the header, before any pixel is decoded or allocated (image_io.h: kMaxImagePixels).
  if (static_cast<double>(h.width) * h.height > kMaxImagePixels)
    throw Error(quoted(path) + ": image is " + std::to_string(h.width) + "x" + std::to_string(h.height) +
                ", which exceeds the input limit of 2^26 pixels (67 megapixels, e.g. 8192x8192)");
  return o;
}

// A colour profile carried from input to output: one that is an ICC profile by its header (the
// 'acsp' signature, a size field of at least the header's 128 bytes and its tag count and at
// most what is stored: some monitor profiles understate it by a few dozen bytes of padding, which
// Little CMS accepts) and at most kMaxCarriedProfile bytes, carried as stored. Anything else is
// left behind: a fuzzer's 9 MB "profile" made outputs that OpenCV (and so the Python tools) and
// Pillow refuse to read (Pillow reads 1 MiB); real profiles are kilobytes, rarely a few hundred.
constexpr std::size_t kMaxCarriedProfile = 1 << 20;
bool carried_profile(const std::string& icc) {
  if (icc.size() < 132 || icc.size() > kMaxCarriedProfile || icc.compare(36, 4, "acsp") != 0) return false;
  std::uint32_t declared = 0;
  for (int i = 0; i < 4; ++i) declared = declared << 8 | static_cast<unsigned char>(icc[i]);
  return declared >= 132 && declared <= icc.size();
}

// The whole image as stored: CV_8U, CV_16U or (float files) CV_32F, with the header's channels.
// `from_bytes_read`, if given: set to whether a PNG's pixels came from the bytes open_image read
// (not from libpng reading the file again, as it does where our own decoding gives up).
cv::Mat decode(const fs::path& path, const Opened& o, std::string* icc = nullptr, bool* from_bytes_read = nullptr) {
  if (from_bytes_read) *from_bytes_read = false;
  cv::Mat image = o.route == Route::png    ? png::decode(path, o.png, from_bytes_read)
                  : o.route == Route::jpeg ? jpeg::decode(path, icc)
                                           : oiio::codec(quoted(path) + ": reading this file").decode(path);
  if (icc && o.route == Route::png) *icc = png::icc_profile(o.png, kMaxCarriedProfile);  // longer is not carried
  if (icc && !carried_profile(*icc)) icc->clear();
  if (image.cols != o.header.width || image.rows != o.header.height || image.channels() != o.header.channels)
    throw Error(quoted(path) + ": cannot decode (the pixels do not match the header)");
  return image;
}

// What read_rgb8 refuses, from the header alone: too small, and without `convert` anything
// but 8-bit RGB; with it, more than 4 channels.
void check_rgb8_spec(const fs::path& path, const ImageHeader& h, bool convert, int min_size) {
  const int w = h.width, hh = h.height, nc = h.channels;
  if (w < min_size || hh < min_size)
    throw Error(quoted(path) + ": image is " + std::to_string(w) + "x" + std::to_string(hh) +
                ", smaller than the " + std::to_string(min_size) + "x" + std::to_string(min_size) + " minimum");
  // Before the strict checks: --convert cannot help with more than 4 channels.
  if (nc < 1 || nc > 4)
    throw Error(quoted(path) + ": " + std::to_string(nc) + " channels are not supported (grey, grey+alpha, RGB or RGBA)");
  if (!convert) {
    if (h.bits != 8 || h.is_float)
      throw Error(quoted(path) + ": " + std::to_string(h.bits) + (h.is_float ? "-bit float" : "-bit") +
                  " image; only 8-bit RGB is rendered as is (pass --convert to round it to 8 bits)");
    if (nc != 3)
      throw Error(quoted(path) + ": " + std::to_string(nc) + "-channel image (" +
                  (nc == 1 ? "grey" : nc == 4 ? "RGBA" : "grey+alpha") +
                  "); only RGB is rendered as is (pass --convert to make it RGB)");
  }
}

std::string temp_name_for(const fs::path& path) {
  static std::atomic<unsigned> counter{0};
  return "." + temporary_stem(path.filename().string()) + ".tmp-" + std::to_string(::getpid()) + "-" +
         std::to_string(counter++);
}

// The hidden temporary a file is written to beside its final name, in the same folder (so that
// the rename into place never crosses file systems).
fs::path temporary_beside(const fs::path& path) {
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  return dir / temp_name_for(path);
}

// Renames the finished temporary over `path`; on failure removes it and reports the
// rename's own error (a clean-up sharing its error_code reported "Success").
void move_into_place(const fs::path& tmp, const fs::path& path) {
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw Error(quoted(path) + ": cannot move the finished file into place (" + ec.message() + ")");
  }
}

}  // namespace

std::string temporary_stem(const std::string& file_name) {
  // ".<stem>.tmp-<pid up to 10 digits>-<counter up to 10 digits>" within the limit.
  constexpr std::size_t kSuffix = 1 + 5 + 10 + 1 + 10;
  return file_name.substr(0, kMaxFileNameBytes - kSuffix);
}

std::optional<TemporaryName> parse_temporary_name(const std::string& name) {
  const auto tmp = name.rfind(".tmp-");
  if (name.size() < 2 || name[0] != '.' || tmp == std::string::npos || tmp < 2) return std::nullopt;
  const std::string tail = name.substr(tmp + 5);
  const auto dash = tail.find('-');
  const auto digits = [](const std::string& t) {
    return !t.empty() && t.size() <= 10 &&
           std::all_of(t.begin(), t.end(), [](unsigned char c) { return std::isdigit(c) != 0; });
  };
  if (dash == std::string::npos || !digits(tail.substr(0, dash)) || !digits(tail.substr(dash + 1))) return std::nullopt;
  return TemporaryName{name.substr(1, tmp - 1), std::stol(tail.substr(0, dash))};
}

void check_file_name_length(const fs::path& path) {
  const std::size_t bytes = path.filename().string().size();
  if (bytes > kMaxFileNameBytes)
    throw Error(quoted(path) + ": cannot write (the file name is " + std::to_string(bytes) + " bytes, longer than the " +
                std::to_string(kMaxFileNameBytes) + " a file system takes)");
}

ImageHeader read_header(const fs::path& path) { return open_image(path).header; }

void check_rgb8_header(const fs::path& path, bool convert, int min_size) {
  check_rgb8_spec(path, open_image(path, /*check_data=*/false).header, convert, min_size);
}

cv::Mat read_rgb8(const fs::path& path, bool convert, int min_size, std::string* stored_png) {
  Opened o = open_image(path, true, stored_png != nullptr);
  check_rgb8_spec(path, o.header, convert, min_size);
  bool from_bytes_read = false;
  const cv::Mat stored = decode(path, o, nullptr, &from_bytes_read);
  if (stored_png) {
    // 8-bit RGB as stored (no palette, no transparency), shown as sRGB and nothing else asked of
    // a reader (no orientation, no animation): the bytes decode to exactly the pixels returned,
    // and look as they do written here. Decoded from these very bytes: not where libpng read the
    // file again (an interlaced file, or data our decoder gave up on), which may have changed.
    const bool as_is = o.route == Route::png && o.png.colour_type == 2 && o.png.depth == 8 && !o.png.has_trns &&
                       from_bytes_read && o.png.shown_as_srgb && o.png.plain_ancillaries;
    stored_png->clear();
    if (as_is) stored_png->swap(o.png.file);
  }
  const int w = stored.cols, h = stored.rows, nc = stored.channels();
  cv::Mat raw;
  if (stored.depth() == CV_32F) {
    // Float files (EXR, HDR) hold linear light: encode with the sRGB transfer curve, as the
    // 8-bit frames the renderer otherwise reads are encoded (alpha stays linear).
    raw.create(h, w, CV_8UC(nc));
    const int colour = nc == 2 || nc == 4 ? nc - 1 : nc;
    for (int y = 0; y < h; ++y) {
      const float* src = stored.ptr<float>(y);
      auto* dst = raw.ptr<std::uint8_t>(y);
      for (int i = 0; i < w * nc; ++i) {
        float v = std::isfinite(src[i]) ? std::min(std::max(src[i], 0.0f), 1.0f) : 0.0f;
        if (i % nc < colour) v = static_cast<float>(linear_to_srgb(v));
        dst[i] = static_cast<std::uint8_t>(std::floor(v * 255.0f + 0.5f));
      }
    }
  } else if (stored.depth() == CV_16U) {
    raw = round_to_8_bits(stored);
  } else {
    raw = stored;
  }
  if (nc == 3) return raw;
  cv::Mat rgb(h, w, CV_8UC3);
  const int from_to_grey[] = {0, 0, 0, 1, 0, 2};
  const int from_to_rgb[] = {0, 0, 1, 1, 2, 2};
  cv::mixChannels(&raw, 1, &rgb, 1, nc <= 2 ? from_to_grey : from_to_rgb, 3);
  return rgb;
}

namespace {

// What read_image_native refuses from the header alone.
void check_native_spec(const fs::path& path, const ImageHeader& header, int min_size) {
  const int w = header.width, h = header.height, nc = header.channels;
  if (w < min_size || h < min_size)
    throw Error(quoted(path) + ": image is " + std::to_string(w) + "x" + std::to_string(h) +
                ", smaller than the " + std::to_string(min_size) + "x" + std::to_string(min_size) + " minimum");
  if (nc < 1 || nc > 4) throw Error(quoted(path) + ": " + std::to_string(nc) + " channels are not supported");
  // Float files (EXR, float TIFF) hold linear light, which 16 bits cannot keep without a
  // transfer curve of our choosing, and which the networks never saw.
  if (header.is_float)
    throw Error(quoted(path) + ": " + std::to_string(header.bits) +
                "-bit float image (linear light); only 8- and 16-bit images are taken (convert it to PNG or TIFF first)");
}

}  // namespace

std::int64_t check_native_header(const fs::path& path, int min_size) {
  const auto header = open_image(path, /*check_data=*/false).header;
  check_native_spec(path, header, min_size);
  return static_cast<std::int64_t>(header.width) * header.height;
}

cv::Mat read_image_native(const fs::path& path, int min_size, std::string* icc_profile) {
  const Opened o = open_image(path);
  check_native_spec(path, o.header, min_size);
  if (icc_profile) icc_profile->clear();
  return decode(path, o, icc_profile);
}

namespace {

bool is_png_name(const fs::path& p) { return lowercase_extension(p) == ".png"; }
bool is_jpeg_name(const fs::path& p) {
  const std::string ext = lowercase_extension(p);
  return ext == ".jpg" || ext == ".jpeg";
}

// `image` as JPEG can hold it (8 bits, grey or RGB), and what that lost, in write_image_atomic's words.
cv::Mat for_jpeg(const cv::Mat& image, std::string* lost) {
  const int nc = image.channels();
  const bool depth = image.depth() == CV_16U, alpha = nc == 2 || nc == 4;
  cv::Mat eight = depth ? round_to_8_bits(image) : image;
  if (alpha) {
    cv::Mat colour(eight.rows, eight.cols, CV_8UC(nc - 1));
    const int from_to[] = {0, 0, 1, 1, 2, 2};
    cv::mixChannels(&eight, 1, &colour, 1, from_to, nc - 1);
    eight = colour;
  }
  *lost = format_loss("jpeg", depth ? 16 : 8, nc, depth ? "rounded to 8 bits" : "", alpha);
  return eight;
}

// Writes a PNG or JPEG to `tmp` with libpng or libjpeg; removes it and throws on any failure.
std::string write_native(const cv::Mat& image, const fs::path& tmp, const fs::path& path, int png_level,
                         const std::string& icc) {
  std::FILE* file = std::fopen(tmp.c_str(), "wb");
  if (!file) throw Error(quoted(path) + ": cannot write (" + std::strerror(errno) + ")");
  std::string lost;
  std::error_code ec;
  try {
    if (is_png_name(path)) {
      png::encode(image, file, png_level, path, icc);
    } else {
      jpeg::encode(for_jpeg(image, &lost), file, jpeg::kDefaultQuality, path, icc);
    }
  } catch (...) {
    std::fclose(file);
    fs::remove(tmp, ec);
    throw;
  }
  // A full disk shows only here: the last buffered block fails to reach the file.
  const bool flushed = std::fflush(file) == 0 && !std::ferror(file);
  const int err = errno;
  if (std::fclose(file) != 0 || !flushed) {
    const int why = flushed ? errno : err;
    fs::remove(tmp, ec);
    throw Error(quoted(path) + ": cannot write (" + std::strerror(why) + ")");
  }
  return lost;
}

}  // namespace

namespace {

// Writes `image` for `path` (whose extension picks the format) into the file `tmp`; removes
// `tmp` and throws on any failure. Returns what the format lost (write_image_atomic).
std::string write_image_file(const cv::Mat& image, const fs::path& tmp, const fs::path& path, int png_level,
                             const std::string& icc = {}) {
  CV_Assert((image.depth() == CV_8U || image.depth() == CV_16U) && image.channels() >= 1 && image.channels() <= 4);
  std::string lost;
  if (is_png_name(path) || is_jpeg_name(path)) {
    lost = write_native(image, tmp, path, png_level, icc);
  } else {
    const oiio::Codec& codec = oiio::codec(quoted(path) + ": writing this format");
    try {
      lost = codec.encode(image, tmp, path);
    } catch (...) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw;
    }
  }
  return lost;
}

}  // namespace

std::string write_image_atomic(const cv::Mat& image, const fs::path& path, int png_level, const std::string& icc_profile) {
  const fs::path tmp = temporary_beside(path);
  const std::string lost = write_image_file(image, tmp, path, png_level, icc_profile);
  move_into_place(tmp, path);
  return lost;
}

StagedImages::~StagedImages() {
  std::error_code ec;
  for (const auto& [tmp, path] : pending_) fs::remove(tmp, ec);
}

std::string StagedImages::stage(const cv::Mat& image, const fs::path& path, int png_level,
                                const std::string& icc_profile) {
  const fs::path tmp = temporary_beside(path);
  const std::string lost = write_image_file(image, tmp, path, png_level, icc_profile);
  pending_.emplace_back(tmp, path);
  return lost;
}

bool StagedImages::stage_jpeg_as_it_was(const fs::path& from, const cv::Mat& pixels, const fs::path& path) {
  const std::string ext = lowercase_extension(path);
  if (ext != ".jpg" && ext != ".jpeg" && ext != ".jpe") return false;
  std::ifstream in(from, std::ios::binary);
  if (!in) return false;
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad() || bytes.size() < 3 || !jpeg::has_signature(bytes.data())) return false;
  try {
    const cv::Mat decoded = jpeg::decode(bytes);
    if (decoded.size() != pixels.size() || decoded.type() != pixels.type() || cv::norm(decoded, pixels, cv::NORM_INF) != 0)
      return false;
  } catch (const Error&) {  // not one libjpeg decodes itself (CMYK): written from its pixels
    return false;
  }
  const fs::path tmp = temporary_beside(path);
  {
    std::ofstream f(tmp, std::ios::binary);
    if (f) f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    if (f) f.close();  // an error that shows only at close (a network file system) counts too
    if (!f) {
      const int err = errno;  // before the clean-up can change it
      std::error_code ignored;
      fs::remove(tmp, ignored);
      throw Error(quoted(path) + ": cannot write (" + std::strerror(err) + ")");
    }
  }
  pending_.emplace_back(tmp, path);
  return true;
}

void StagedImages::commit() {
  // Last staged first: the first (a program's main output) replaces its file only after the
  // others are in place.
  while (!pending_.empty()) {
    const auto [tmp, path] = pending_.back();
    pending_.pop_back();
    move_into_place(tmp, path);  // removes tmp on failure; the destructor removes the rest
  }
}

int parse_png_level(const std::string& text) {
  if (text == "fast") return kPngFast;
  if (text == "rle") return kPngRunLength;
  if (text.size() == 1 && text[0] >= '0' && text[0] <= '9') return text[0] - '0';
  throw Error("PNG level must be fast, rle or 0-9, got '" + text + "'");
}

std::string png_level_name(int png_level) {
  return png_level == kPngFast ? "fast" : png_level == kPngRunLength ? "rle" : std::to_string(png_level);
}

cv::Mat jpeg_round_trip(const cv::Mat& rgb, int quality) {
  CV_Assert(rgb.type() == CV_8UC3);
  if (quality < 1 || quality > 100) throw Error("JPEG quality must be 1-100, got " + std::to_string(quality));
  cv::Mat decoded = jpeg::decode(jpeg::encode(rgb, quality));
  if (decoded.size() != rgb.size() || decoded.type() != rgb.type()) throw Error("JPEG decoding failed (size or channels changed)");
  return decoded;
}

void check_image_destination(const fs::path& path, bool folder_may_be_created) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw Error(quoted(path) + ": cannot write (it is a folder)");
  check_file_name_length(path);
  if (!is_png_name(path) && !is_jpeg_name(path))
    oiio::codec(quoted(path) + ": writing this format").check_writable_format(path);
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw Error(quoted(path) + ": cannot write (" + quoted(dir) + " is not a folder)");
  if (!fs::exists(dir, ec)) {
    if (folder_may_be_created) return;
    throw Error(quoted(path) + ": cannot write (folder " + quoted(dir) + " does not exist)");
  }
  // The file is written beside its final name and renamed over it: the folder must be
  // writable, and an existing read-only file is not replaced behind its owner's back.
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw Error(quoted(path) + ": cannot write (folder " + quoted(dir) + ": " + std::strerror(errno) + ")");
  check_replaceable(path);
}

void check_replaceable(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return;
  // The mode first, so that every user reads the same message: root passes access() for every
  // file, and a mode without any write bit still says "keep this".
  const fs::perms p = fs::status(path, ec).permissions();
  const fs::perms any_write = fs::perms::owner_write | fs::perms::group_write | fs::perms::others_write;
  if (!ec && fs::is_regular_file(path, ec) && (p & any_write) == fs::perms::none)
    throw Error(quoted(path) + ": read-only (no write permission for anyone); make it writable, or remove it");
  if (::access(path.c_str(), W_OK) != 0) throw Error(quoted(path) + ": cannot write (" + std::strerror(errno) + ")");
}

void ensure_writable_dir(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw Error("output folder " + quoted(dir) + " cannot be created (" + (ec ? ec.message() : "not a folder") + ")");
  const fs::path probe = temporary_beside(dir / "probe");
  {
    std::ofstream f(probe);
    if (!f || !(f << "ok") || !f.flush()) {
      const int err = errno;  // before the clean-up can change it
      fs::remove(probe, ec);
      throw Error("output folder " + quoted(dir) + " is not writable (" + std::strerror(err) + ")");
    }
  }
  fs::remove(probe, ec);
}

void copy_file_atomic(const fs::path& from, const fs::path& to) {
  const fs::path tmp = temporary_beside(to);
  std::error_code ec;
  if (!fs::copy_file(from, tmp, fs::copy_options::overwrite_existing, ec)) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw Error(quoted(to) + ": cannot copy " + quoted(from) + " there (" + ec.message() + ")");
  }
  move_into_place(tmp, to);
}

void write_text_atomic(const std::string& text, const fs::path& path) {
  const fs::path tmp = temporary_beside(path);
  std::error_code ec;
  {
    std::ofstream f(tmp, std::ios::binary);
    if (!f || !(f << text) || !f.flush()) {
      const int err = errno;  // before the clean-up can change it
      fs::remove(tmp, ec);
      throw Error(quoted(path) + ": cannot write (" + std::strerror(err) + ")");
    }
  }
  move_into_place(tmp, path);
}

}  // namespace raindrop

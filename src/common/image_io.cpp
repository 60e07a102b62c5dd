#include "raindrop/common/image_io.h"

#include <atomic>
#include <cerrno>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <system_error>
#include <vector>

#include <unistd.h>
#include <zlib.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include "raindrop/common/error.h"

namespace raindrop {
namespace fs = std::filesystem;
namespace {

// First line of an OIIO error message (they can be multi-line).
std::string first_line(std::string s) {
  const auto nl = s.find('\n');
  if (nl != std::string::npos) s.resize(nl);
  return s.empty() ? "unknown error" : s;
}

std::uint32_t be32(const unsigned char* p) {
  return (static_cast<std::uint32_t>(p[0]) << 24) | (static_cast<std::uint32_t>(p[1]) << 16) |
         (static_cast<std::uint32_t>(p[2]) << 8) | p[3];
}

// The rows of a PNG's filtered image data, in stream order: `count` rows of `bytes` bytes
// each (the filter-type byte included) per segment; Adam7 has one segment per non-empty pass.
struct RowRun {
  std::uint64_t count, bytes;
};

std::vector<RowRun> png_rows(std::uint32_t width, std::uint32_t height, int bits_per_pixel, bool adam7) {
  auto row_bytes = [&](std::uint64_t w) { return 1 + (w * bits_per_pixel + 7) / 8; };
  if (!adam7) return {{height, row_bytes(width)}};
  static const int kPass[7][4] = {{0, 0, 8, 8}, {4, 0, 8, 8}, {0, 4, 4, 8}, {2, 0, 4, 4},
                                  {0, 2, 2, 4}, {1, 0, 2, 2}, {0, 1, 1, 2}};  // x0, y0, dx, dy
  std::vector<RowRun> runs;
  for (const auto& p : kPass) {
    const std::uint64_t w = width > static_cast<std::uint32_t>(p[0]) ? (width - p[0] + p[2] - 1) / p[2] : 0;
    const std::uint64_t h = height > static_cast<std::uint32_t>(p[1]) ? (height - p[1] + p[3] - 1) / p[3] : 0;
    if (w > 0 && h > 0) runs.push_back({h, row_bytes(w)});
  }
  return runs;
}

// Inflates the image data and checks every row's filter type (0-4) and that the stream holds
// all rows: what libpng would otherwise find (and print) while decoding.
void check_png_image_data(const fs::path& path, const std::string& idat, const std::vector<RowRun>& rows) {
  z_stream z{};
  if (::inflateInit(&z) != Z_OK) throw Error(quoted(path) + ": cannot check the PNG data (zlib: out of memory)");
  std::vector<unsigned char> out(1 << 16);
  size_t fed = 0, run = 0;
  std::uint64_t row = 0, left_in_row = 0;  // position in the expected rows
  bool done = rows.empty(), end = false;
  int ret = Z_OK;
  while (true) {
    if (z.avail_in == 0 && fed < idat.size()) {
      const size_t n = std::min<size_t>(idat.size() - fed, 1u << 30);
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(idat.data() + fed));
      z.avail_in = static_cast<uInt>(n);
      fed += n;
    }
    z.next_out = out.data();
    z.avail_out = static_cast<uInt>(out.size());
    ret = ::inflate(&z, Z_NO_FLUSH);
    const size_t produced = out.size() - z.avail_out;
    for (size_t i = 0; i < produced && !done;) {
      if (left_in_row == 0) {  // a row starts with its filter type
        if (out[i] > 4) {
          ::inflateEnd(&z);
          throw Error(quoted(path) + ": corrupt PNG (bad filter type " + std::to_string(out[i]) + " in the image data)");
        }
        left_in_row = rows[run].bytes;
      }
      const std::uint64_t step = std::min<std::uint64_t>(left_in_row, produced - i);
      i += step;
      left_in_row -= step;
      if (left_in_row == 0 && ++row == rows[run].count) {
        row = 0;
        done = ++run == rows.size();
      }
    }
    end = ret == Z_STREAM_END;
    // Stop at the last row, as libpng does (data past it is ignored, and a stream that
    // inflates far beyond the declared size costs nothing), at the end of the stream, or
    // when zlib can make no progress (Z_BUF_ERROR: the data ran out) or finds an error.
    if (done || ret != Z_OK) break;
  }
  const std::string why = z.msg ? z.msg : "";
  ::inflateEnd(&z);
  if (ret != Z_OK && ret != Z_STREAM_END && ret != Z_BUF_ERROR)
    throw Error(quoted(path) + ": corrupt PNG (bad compressed image data" + (why.empty() ? "" : ": " + why) + ")");
  // A stream cut short after the last row is harmless to libpng; fewer rows than declared is not.
  if (!done) throw Error(quoted(path) + ": truncated PNG (the image data " + (end ? "ends" : "is cut off") +
                         " before the last row)");
}

// libpng reports malformed files by printing "libpng error: ..." to stderr itself before
// OIIO sees the error, which would break the one-line-error rule. So a PNG is checked first:
// IHDR first and valid, every chunk within the file with a valid CRC, no unknown critical
// chunk, a palette before the data where needed, IEND at the end, and image data that
// inflates to every declared row with valid filter types (unless `check_data` is false: a
// header check, which leaves the data to the decode).
void check_png_structure(const fs::path& path, std::uintmax_t size, bool check_data) {
  std::ifstream f(path, std::ios::binary);
  unsigned char signature[8] = {0};
  f.read(reinterpret_cast<char*>(signature), 8);
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (!f || std::memcmp(signature, kPng, 8) != 0) return;  // not a PNG: OIIO decides
  std::vector<unsigned char> data(size - 8);
  f.read(reinterpret_cast<char*>(data.data()), static_cast<std::streamsize>(data.size()));
  size_t at = 0;
  bool first = true, palette = false;
  std::string idat;
  std::vector<unsigned char> ihdr;
  while (true) {
    if (at + 12 > data.size()) throw Error(quoted(path) + ": truncated PNG (ends inside a chunk, no IEND)");
    const std::uint32_t length = be32(&data[at]);
    if (length > data.size() - at - 12) throw Error(quoted(path) + ": truncated PNG (a chunk runs past the end of the file)");
    const std::string type(reinterpret_cast<const char*>(&data[at + 4]), 4);
    const std::uint32_t crc = static_cast<std::uint32_t>(
        ::crc32(::crc32(0L, Z_NULL, 0), &data[at + 4], static_cast<uInt>(4 + length)));
    if (crc != be32(&data[at + 8 + length])) throw Error(quoted(path) + ": corrupt PNG (CRC error in a " + type + " chunk)");
    if (first && type != "IHDR") throw Error(quoted(path) + ": corrupt PNG (first chunk is " + type + ", not IHDR)");
    const bool critical = std::isupper(static_cast<unsigned char>(type[0]));
    if (critical && type != "IHDR" && type != "PLTE" && type != "IDAT" && type != "IEND")
      throw Error(quoted(path) + ": corrupt PNG (unknown critical chunk " + type + ")");
    if (first) ihdr.assign(&data[at + 8], &data[at + 8] + length);
    first = false;
    palette = palette || (type == "PLTE" && idat.empty());
    if (type == "IDAT") idat.append(reinterpret_cast<const char*>(&data[at + 8]), length);
    if (type == "IEND") break;
    at += 12 + length;
  }
  if (idat.empty()) throw Error(quoted(path) + ": corrupt PNG (no image data)");
  const std::string bad_ihdr = quoted(path) + ": corrupt PNG (invalid IHDR: ";
  if (ihdr.size() != 13) throw Error(bad_ihdr + "length " + std::to_string(ihdr.size()) + ", not 13)");
  const std::uint32_t width = be32(&ihdr[0]), height = be32(&ihdr[4]);
  const int depth = ihdr[8], colour = ihdr[9];
  // libpng's own limits: 2^31 - 1 by the format, 1000000 a side by default (PNG_USER_WIDTH_MAX).
  if (width == 0 || height == 0 || width > 1000000 || height > 1000000)
    throw Error(bad_ihdr + "size " + std::to_string(width) + "x" + std::to_string(height) +
                ", each side must be 1 to 1000000)");
  static const std::map<int, std::pair<int, std::set<int>>> kColour = {  // channels, allowed depths
      {0, {1, {1, 2, 4, 8, 16}}}, {2, {3, {8, 16}}}, {3, {1, {1, 2, 4, 8}}}, {4, {2, {8, 16}}}, {6, {4, {8, 16}}}};
  const auto c = kColour.find(colour);
  if (c == kColour.end()) throw Error(bad_ihdr + "colour type " + std::to_string(colour) + ")");
  if (c->second.second.count(depth) == 0)
    throw Error(bad_ihdr + "bit depth " + std::to_string(depth) + " with colour type " + std::to_string(colour) + ")");
  if (ihdr[10] != 0 || ihdr[11] != 0 || ihdr[12] > 1)
    throw Error(bad_ihdr + "compression, filter or interlace method)");
  if (colour == 3 && !palette) throw Error(quoted(path) + ": corrupt PNG (palette image without a PLTE before its data)");
  // A declared size past the pixel limit is refused by open_input before anything is inflated.
  if (static_cast<double>(width) * height > kMaxImagePixels || !check_data) return;
  check_png_image_data(path, idat, png_rows(width, height, c->second.first * depth, ihdr[12] == 1));
}

// `check_data`: false opens for the header alone (a PNG's image data is then checked by the
// decode, not here).
std::unique_ptr<OIIO::ImageInput> open_input(const fs::path& path, OIIO::ImageSpec* spec, bool check_data = true) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(quoted(path) + ": no such file");
  if (fs::is_directory(path, ec)) throw Error(quoted(path) + ": is a folder, not an image");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec || size == 0) throw Error(quoted(path) + ": file is empty");
  check_png_structure(path, size, check_data);
  // Keep colour values as stored when there is alpha (PNG is unassociated).
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(path.string(), &config);
  if (!in) throw Error(quoted(path) + ": not a readable image (" + first_line(OIIO::geterror()) + ")");
  *spec = in->spec();
  if (spec->width <= 0 || spec->height <= 0 || spec->nchannels <= 0)
    throw Error(quoted(path) + ": image has no pixels");
  // From the header, before any pixel is decoded or allocated (image_io.h: kMaxImagePixels).
  if (static_cast<double>(spec->width) * spec->height > kMaxImagePixels)
    throw Error(quoted(path) + ": image is " + std::to_string(spec->width) + "x" + std::to_string(spec->height) +
                ", which exceeds the input limit of 2^26 pixels (67 megapixels, e.g. 8192x8192)");
  return in;
}

// Decodes the whole image. A decoder can report a problem and still return success: libjpeg
// only warns at a premature end of file and fills the missing rows with grey, which OIIO
// records as an error on the ImageInput. Any recorded error is a failed decode.
void read_pixels(OIIO::ImageInput& in, const fs::path& path, int channels, OIIO::TypeDesc type, void* data) {
  const bool ok = in.read_image(0, 0, 0, channels, type, data);
  if (!ok || in.has_error()) throw Error(quoted(path) + ": cannot decode (" + first_line(in.geterror()) + ")");
}

// What read_rgb8 refuses, from the header alone: too small, and without `convert` anything
// but 8-bit RGB; with it, more than 4 channels.
void check_rgb8_spec(const fs::path& path, const OIIO::ImageSpec& spec, bool convert, int min_size) {
  const int w = spec.width, h = spec.height, nc = spec.nchannels;
  if (w < min_size || h < min_size)
    throw Error(quoted(path) + ": image is " + std::to_string(w) + "x" + std::to_string(h) +
                ", smaller than the " + std::to_string(min_size) + "x" + std::to_string(min_size) + " minimum");
  // Before the strict checks: --convert cannot help with more than 4 channels.
  if (nc < 1 || nc > 4)
    throw Error(quoted(path) + ": " + std::to_string(nc) + " channels are not supported (grey, grey+alpha, RGB or RGBA)");
  if (!convert) {
    if (spec.format != OIIO::TypeDesc::UINT8)
      throw Error(quoted(path) + ": " + std::to_string(spec.format.size() * 8) +
                  (spec.format.is_floating_point() ? "-bit float" : "-bit") + " image; only 8-bit RGB is rendered as is (pass --convert to round it to 8 bits)");
    if (nc != 3)
      throw Error(quoted(path) + ": " + std::to_string(nc) + "-channel image (" +
                  (nc == 1 ? "grey" : nc == 4 ? "RGBA" : "grey+alpha") +
                  "); only RGB is rendered as is (pass --convert to make it RGB)");
  }
}

std::string temp_name_for(const fs::path& path) {
  static std::atomic<unsigned> counter{0};
  return "." + path.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
         std::to_string(counter++);
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

ImageHeader read_header(const fs::path& path) {
  OIIO::ImageSpec spec;
  auto in = open_input(path, &spec);
  ImageHeader h;
  h.width = spec.width;
  h.height = spec.height;
  h.channels = spec.nchannels;
  h.bits = static_cast<int>(spec.format.size() * 8);
  h.is_float = spec.format.basetype == OIIO::TypeDesc::FLOAT || spec.format.basetype == OIIO::TypeDesc::HALF ||
               spec.format.basetype == OIIO::TypeDesc::DOUBLE;
  h.format = in->format_name();
  in->close();
  return h;
}

void check_rgb8_header(const fs::path& path, bool convert, int min_size) {
  OIIO::ImageSpec spec;
  auto in = open_input(path, &spec, /*check_data=*/false);
  check_rgb8_spec(path, spec, convert, min_size);
  in->close();
}

cv::Mat read_rgb8(const fs::path& path, bool convert, int min_size) {
  OIIO::ImageSpec spec;
  auto in = open_input(path, &spec);
  check_rgb8_spec(path, spec, convert, min_size);
  const int w = spec.width, h = spec.height, nc = spec.nchannels;
  cv::Mat raw(h, w, CV_8UC(nc));
  const bool is_float = spec.format.basetype == OIIO::TypeDesc::FLOAT || spec.format.basetype == OIIO::TypeDesc::HALF ||
                        spec.format.basetype == OIIO::TypeDesc::DOUBLE;
  if (is_float) {
    // Float files (EXR, HDR) hold linear light: encode with the sRGB transfer curve, as the
    // 8-bit frames the renderer otherwise reads are encoded (alpha stays linear).
    cv::Mat linear(h, w, CV_32FC(nc));
    read_pixels(*in, path, nc, OIIO::TypeDesc::FLOAT, linear.data);
    const int colour = nc == 2 || nc == 4 ? nc - 1 : nc;
    for (int y = 0; y < h; ++y) {
      const float* src = linear.ptr<float>(y);
      auto* dst = raw.ptr<std::uint8_t>(y);
      for (int i = 0; i < w * nc; ++i) {
        float v = std::isfinite(src[i]) ? std::min(std::max(src[i], 0.0f), 1.0f) : 0.0f;
        if (i % nc < colour) v = v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
        dst[i] = static_cast<std::uint8_t>(std::floor(v * 255.0f + 0.5f));
      }
    }
  } else {
    read_pixels(*in, path, nc, OIIO::TypeDesc::UINT8, raw.data);  // 16-bit data rounded to 8 bits
  }
  in->close();
  if (nc == 3) return raw;
  cv::Mat rgb(h, w, CV_8UC3);
  const int from_to_grey[] = {0, 0, 0, 1, 0, 2};
  const int from_to_rgb[] = {0, 0, 1, 1, 2, 2};
  cv::mixChannels(&raw, 1, &rgb, 1, nc <= 2 ? from_to_grey : from_to_rgb, 3);
  return rgb;
}

cv::Mat read_image_native(const fs::path& path, int min_size) {
  OIIO::ImageSpec spec;
  auto in = open_input(path, &spec);
  const int w = spec.width, h = spec.height, nc = spec.nchannels;
  if (w < min_size || h < min_size)
    throw Error(quoted(path) + ": image is " + std::to_string(w) + "x" + std::to_string(h) +
                ", smaller than the " + std::to_string(min_size) + "x" + std::to_string(min_size) + " minimum");
  if (nc < 1 || nc > 4) throw Error(quoted(path) + ": " + std::to_string(nc) + " channels are not supported");
  // Float files (EXR, float TIFF) hold linear light, which 16 bits cannot keep without a
  // transfer curve of our choosing, and which the networks never saw.
  if (spec.format.is_floating_point())
    throw Error(quoted(path) + ": " + std::to_string(spec.format.size() * 8) +
                "-bit float image (linear light); only 8- and 16-bit images are taken (convert it to PNG or TIFF first)");
  const bool eight = spec.format == OIIO::TypeDesc::UINT8 || spec.format == OIIO::TypeDesc::INT8;
  cv::Mat img(h, w, eight ? CV_8UC(nc) : CV_16UC(nc));
  read_pixels(*in, path, nc, eight ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::UINT16, img.data);
  in->close();
  return img;
}

std::string write_image_atomic(const cv::Mat& image, const fs::path& path, int png_level) {
  CV_Assert(image.depth() == CV_8U || image.depth() == CV_16U);
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const fs::path tmp = dir / temp_name_for(path);
  // The plugin is chosen from the final name's extension, then opened on the temporary name.
  auto out = OIIO::ImageOutput::create(path.string());
  if (!out) throw Error(quoted(path) + ": cannot write this format (" + first_line(OIIO::geterror()) + ")");
  const cv::Mat data = image.isContinuous() ? image : image.clone();
  OIIO::ImageSpec spec(data.cols, data.rows, data.channels(),
                       data.depth() == CV_8U ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::UINT16);
  if (data.channels() == 4) spec.alpha_channel = 3;
  spec.attribute("png:compressionLevel", std::min(std::max(png_level, 0), 9));
  if (data.channels() == 4 || data.channels() == 2) spec.attribute("oiio:UnassociatedAlpha", 1);
  bool ok = out->open(tmp.string(), spec);
  // What the format cannot hold, known once its writer has opened: it lowers its own spec's
  // depth (JPEG, BMP, WebP store 8 bits) and says whether it stores alpha (JPEG does not).
  std::string lost;
  if (ok) {
    const bool depth = out->spec().format.size() < spec.format.size();
    const bool alpha = (data.channels() == 2 || data.channels() == 4) && !out->supports("alpha");
    static const char* const kChannels[] = {"", "grey", "grey+alpha", "RGB", "RGBA"};
    if (depth || alpha)
      lost = std::string(out->format_name()) + " cannot hold this " + std::to_string(spec.format.size() * 8) + "-bit " +
             kChannels[data.channels()] + " image: " + (depth ? "rounded to 8 bits" : "") +
             (depth && alpha ? ", " : "") + (alpha ? "alpha dropped" : "");
  }
  ok = ok && out->write_image(spec.format, data.data);
  ok = out->close() && ok;
  std::error_code ec;
  if (!ok) {
    const std::string why = first_line(out->geterror());
    fs::remove(tmp, ec);
    throw Error(quoted(path) + ": cannot write (" + why + ")");
  }
  move_into_place(tmp, path);
  return lost;
}

cv::Mat jpeg_round_trip(const cv::Mat& rgb, int quality) {
  CV_Assert(rgb.type() == CV_8UC3);
  if (quality < 1 || quality > 100) throw Error("JPEG quality must be 1-100, got " + std::to_string(quality));
  const cv::Mat data = rgb.isContinuous() ? rgb : rgb.clone();
  std::vector<unsigned char> bytes;
  {
    OIIO::Filesystem::IOVecOutput sink(bytes);
    auto out = OIIO::ImageOutput::create("memory.jpg");
    if (!out) throw Error("no JPEG writer (" + first_line(OIIO::geterror()) + ")");
    OIIO::ImageSpec spec(data.cols, data.rows, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("Compression", "jpeg:" + std::to_string(quality));
    bool ok = out->set_ioproxy(&sink) && out->open("memory.jpg", spec);
    ok = ok && out->write_image(OIIO::TypeDesc::UINT8, data.data);
    ok = out->close() && ok;
    if (!ok) throw Error("JPEG encoding failed (" + first_line(out->geterror()) + ")");
  }
  // The reader by format name: made from a file name, it would look for the file on disk.
  OIIO::Filesystem::IOMemReader source(bytes.data(), bytes.size());
  auto in = OIIO::ImageInput::create("jpeg");
  if (!in) throw Error("no JPEG reader (" + first_line(OIIO::geterror()) + ")");
  OIIO::ImageSpec spec;
  cv::Mat decoded(data.rows, data.cols, CV_8UC3);
  const bool ok = in->set_ioproxy(&source) && in->open("memory.jpg", spec) && spec.width == data.cols &&
                  spec.height == data.rows && spec.nchannels == 3 &&
                  in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, decoded.data);
  if (!ok) throw Error("JPEG decoding failed (" + first_line(in->geterror()) + ")");
  in->close();
  return decoded;
}

void check_image_destination(const fs::path& path, bool folder_may_be_created) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw Error(quoted(path) + ": cannot write (it is a folder)");
  if (!OIIO::ImageOutput::create(path.string()))
    throw Error(quoted(path) + ": cannot write this format (" + first_line(OIIO::geterror()) + ")");
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
  if (fs::exists(path, ec) && ::access(path.c_str(), W_OK) != 0)
    throw Error(quoted(path) + ": cannot write (" + std::strerror(errno) + ")");
}

void ensure_writable_dir(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw Error("output folder " + quoted(dir) + " cannot be created (" + (ec ? ec.message() : "not a folder") + ")");
  const fs::path probe = dir / temp_name_for(dir / "probe");
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

void write_text_atomic(const std::string& text, const fs::path& path) {
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const fs::path tmp = dir / temp_name_for(path);
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

#include "png_file.h"
#include "png_unfilter.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <libdeflate.h>
#include <png.h>
#include <zlib.h>

#include "raindrop/common/error.h"
#include "raindrop/common/image_io.h"

namespace raindrop::png {
namespace fs = std::filesystem;
namespace {

// libpng's limit on a side by default (PNG_USER_WIDTH_MAX; the format allows 2^31 - 1): what
// check() accepts, decode() asks libpng to accept, and encode() writes.
constexpr std::uint32_t kMaxSide = 1000000;

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
  bool done = rows.empty(), end = false, extra = false;
  int ret = Z_OK;
  // Hands zlib the next part of the image data once it has used up what it had (at most 1 GiB
  // at a time: avail_in is 32 bits); false when it has used up all of it.
  const auto feed = [&] {
    if (z.avail_in > 0) return true;
    if (fed == idat.size()) return false;
    const size_t n = std::min<size_t>(idat.size() - fed, 1u << 30);
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(idat.data() + fed));
    z.avail_in = static_cast<uInt>(n);
    fed += n;
    return true;
  };
  while (true) {
    feed();
    z.next_out = out.data();
    z.avail_out = static_cast<uInt>(out.size());
    ret = ::inflate(&z, Z_NO_FLUSH);
    const size_t produced = out.size() - z.avail_out;
    size_t i = 0;
    for (; i < produced && !done;) {
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
    extra = done && i < produced;
    // Stop at the last row, as libpng does (data past it is ignored, and a stream that
    // inflates far beyond the declared size costs nothing), at the end of the stream, or
    // when zlib can make no progress (Z_BUF_ERROR: the data ran out) or finds an error.
    if (done || ret != Z_OK) break;
  }
  // After the last row libpng (png_read_finish_IDAT) reads on until the stream ends or gives a
  // byte more (ignored); image data that runs out before either fails there with "Not enough
  // image data", which OpenImageIO's libpng prints: a stream cut inside its Adler-32, or one
  // never finished (a flushed but unterminated deflate stream). One byte of output is enough.
  while (done && !end && !extra && (ret == Z_OK || ret == Z_BUF_ERROR)) {
    if (!feed()) {
      ::inflateEnd(&z);
      throw Error(quoted(path) + ": truncated PNG (the image data ends before its compressed stream does)");
    }
    z.next_out = out.data();
    z.avail_out = 1;
    ret = ::inflate(&z, Z_NO_FLUSH);
    // A damaged tail (a wrong Adler-32) is a benign error to libpng after the last row.
    if (ret != Z_OK && ret != Z_STREAM_END && ret != Z_BUF_ERROR) ret = Z_STREAM_END;
    end = ret == Z_STREAM_END;
    extra = z.avail_out == 0;
  }
  const std::string why = z.msg ? z.msg : "";
  ::inflateEnd(&z);
  if (ret != Z_OK && ret != Z_STREAM_END && ret != Z_BUF_ERROR)
    throw Error(quoted(path) + ": corrupt PNG (bad compressed image data" + (why.empty() ? "" : ": " + why) + ")");
  // Fewer rows than declared (a stream that ends or is cut off before the last row).
  if (!done) throw Error(quoted(path) + ": truncated PNG (the image data " + (end ? "ends" : "is cut off") +
                         " before the last row)");
}

}  // namespace

bool has_signature(const unsigned char* first8) {
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  return std::memcmp(first8, kPng, 8) == 0;
}

Info check(const fs::path& path, std::uintmax_t size, bool check_data, bool keep_file) {
  std::ifstream f(path, std::ios::binary);
  // The whole file in one string (kept as Info::file without a copy where asked); a file shorter
  // than `size` by now reads as zeros past its end, which the chunk checks then refuse.
  std::string file(static_cast<std::size_t>(size), '\0');
  f.read(file.data(), static_cast<std::streamsize>(size));
  if (size < 8 || f.gcount() < 8 || !has_signature(reinterpret_cast<const unsigned char*>(file.data())))
    throw Error(quoted(path) + ": not a PNG file");
  const unsigned char* const data = reinterpret_cast<const unsigned char*>(file.data()) + 8;
  const std::size_t data_size = static_cast<std::size_t>(size) - 8;
  size_t at = 0;
  bool first = true, palette = false, trns = false, idat_ended = false;
  bool srgb = false, gamma_or_primaries = false, profile = false, plain = true;
  std::string idat, previous, iccp;
  std::size_t idat_bytes = 0;
  std::vector<unsigned char> ihdr;
  while (true) {
    if (at + 12 > data_size) throw Error(quoted(path) + ": truncated PNG (ends inside a chunk, no IEND)");
    const std::uint32_t length = be32(&data[at]);
    if (length > data_size - at - 12) throw Error(quoted(path) + ": truncated PNG (a chunk runs past the end of the file)");
    const std::string type(reinterpret_cast<const char*>(&data[at + 4]), 4);
    const std::uint32_t crc = libdeflate_crc32(0, &data[at + 4], 4 + length);
    if (crc != be32(&data[at + 8 + length])) throw Error(quoted(path) + ": corrupt PNG (CRC error in a " + type + " chunk)");
    if (first && type != "IHDR") throw Error(quoted(path) + ": corrupt PNG (first chunk is " + type + ", not IHDR)");
    const bool critical = std::isupper(static_cast<unsigned char>(type[0]));
    if (critical && type != "IHDR" && type != "PLTE" && type != "IDAT" && type != "IEND")
      throw Error(quoted(path) + ": corrupt PNG (unknown critical chunk " + type + ")");
    // What libpng refuses (and, decoding through OpenImageIO, prints) in a file whose chunks are
    // all intact: the image data split by another chunk, a second IHDR or PLTE, a palette of
    // no entries, more than 256, or a length that is not whole entries.
    const std::string corrupt = quoted(path) + ": corrupt PNG (";
    if (!first && type == "IHDR") throw Error(corrupt + "a second IHDR chunk)");
    if (type == "PLTE" && palette) throw Error(corrupt + "a second PLTE chunk)");
    if (type == "PLTE" && (length == 0 || length % 3 != 0 || length > 3 * 256))
      throw Error(corrupt + "a palette of " + std::to_string(length) + " bytes, not 1-256 entries of 3)");
    if (type == "IDAT" && idat_ended) throw Error(corrupt + "the image data is split by a " + previous + " chunk)");
    idat_ended = idat_ended || (previous == "IDAT" && type != "IDAT");
    previous = type;
    if (first) ihdr.assign(&data[at + 8], &data[at + 8] + length);
    first = false;
    if (type == "PLTE" && idat_bytes > 0) throw Error(corrupt + "the palette comes after the image data)");
    palette = palette || type == "PLTE";
    trns = trns || type == "tRNS";
    srgb = srgb || (type == "sRGB" && idat_bytes == 0);  // after the data, readers ignore it
    static const std::set<std::string> kPlain = {"IHDR", "PLTE", "IDAT", "IEND", "sRGB", "gAMA", "cHRM", "iCCP",
                                                 "cICP", "sBIT", "bKGD", "pHYs", "tIME", "tEXt", "zTXt", "iTXt",
                                                 "tRNS"};
    plain = plain && kPlain.count(type) > 0;  // the colour chunks and tRNS are judged apart
    gamma_or_primaries = gamma_or_primaries || type == "gAMA" || type == "cHRM";
    profile = profile || type == "iCCP" || type == "cICP";
    if (type == "IDAT") {
      idat_bytes += length;
      // Joined only for a check that reads them: a header check copied a frame's data for nothing.
      if (check_data) idat.append(reinterpret_cast<const char*>(&data[at + 8]), length);
    }
    if (type == "iCCP" && iccp.empty()) iccp.assign(reinterpret_cast<const char*>(&data[at + 8]), length);
    if (type == "IEND") break;
    at += 12 + length;
  }
  if (idat_bytes == 0) throw Error(quoted(path) + ": corrupt PNG (no image data)");
  const std::string bad_ihdr = quoted(path) + ": corrupt PNG (invalid IHDR: ";
  if (ihdr.size() != 13) throw Error(bad_ihdr + "length " + std::to_string(ihdr.size()) + ", not 13)");
  const std::uint32_t width = be32(&ihdr[0]), height = be32(&ihdr[4]);
  const int depth = ihdr[8], colour = ihdr[9];
  if (width == 0 || height == 0 || width > kMaxSide || height > kMaxSide)
    throw Error(bad_ihdr + "size " + std::to_string(width) + "x" + std::to_string(height) +
                ", each side must be 1 to " + std::to_string(kMaxSide) + ")");
  static const std::map<int, std::pair<int, std::set<int>>> kColour = {  // channels, allowed depths
      {0, {1, {1, 2, 4, 8, 16}}}, {2, {3, {8, 16}}}, {3, {1, {1, 2, 4, 8}}}, {4, {2, {8, 16}}}, {6, {4, {8, 16}}}};
  const auto c = kColour.find(colour);
  if (c == kColour.end()) throw Error(bad_ihdr + "colour type " + std::to_string(colour) + ")");
  if (c->second.second.count(depth) == 0)
    throw Error(bad_ihdr + "bit depth " + std::to_string(depth) + " with colour type " + std::to_string(colour) + ")");
  if (ihdr[10] != 0 || ihdr[11] != 0 || ihdr[12] > 1)
    throw Error(bad_ihdr + "compression, filter or interlace method)");
  if (colour == 3 && !palette) throw Error(quoted(path) + ": corrupt PNG (palette image without a PLTE before its data)");
  Info info;
  info.width = width;
  info.height = height;
  info.depth = depth;
  info.colour_type = colour;
  info.has_trns = trns;
  info.channels = (colour == 3 ? 3 : c->second.first) + (trns && (colour == 0 || colour == 2 || colour == 3) ? 1 : 0);
  info.interlaced = ihdr[12] == 1;
  info.iccp = std::move(iccp);
  info.shown_as_srgb = !profile && (srgb || !gamma_or_primaries);
  info.plain_ancillaries = plain;
  if (keep_file) info.file = std::move(file);  // `data` is not read after this
  // A declared size past the pixel limit is refused by the caller before anything is inflated.
  if (static_cast<double>(width) * height > kMaxImagePixels || !check_data) return info;
  if (info.native()) {
    if (!info.interlaced) info.image_data = std::move(idat);
    return info;
  }
  check_png_image_data(path, idat, png_rows(width, height, c->second.first * depth, ihdr[12] == 1));
  return info;
}

std::string icc_profile(const Info& info, std::size_t limit) {
  // Profile name (1-79 bytes), a zero, the compression method (0: zlib), the zlib stream.
  const std::size_t name_end = info.iccp.find('\0');
  if (name_end == std::string::npos || name_end == 0 || name_end > 79 || name_end + 2 > info.iccp.size() ||
      info.iccp[name_end + 1] != 0)
    return {};
  z_stream z{};
  if (::inflateInit(&z) != Z_OK) return {};
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(info.iccp.data() + name_end + 2));
  z.avail_in = static_cast<uInt>(info.iccp.size() - name_end - 2);
  std::string profile;
  char buffer[1 << 16];
  int rc = Z_OK;
  while (rc == Z_OK && profile.size() <= limit) {
    z.next_out = reinterpret_cast<Bytef*>(buffer);
    z.avail_out = sizeof buffer;
    rc = ::inflate(&z, Z_NO_FLUSH);
    profile.append(buffer, sizeof buffer - z.avail_out);
  }
  ::inflateEnd(&z);
  return rc == Z_STREAM_END && profile.size() <= limit ? profile : std::string();
}

namespace {

// libpng reports errors through these instead of printing them: the message is kept for the
// Error, and control returns to the setjmp in decode() or encode(). Warnings (a bad ancillary
// chunk, an unknown sRGB profile) change nothing in the pixels and are dropped.
struct ErrorSink {
  char message[256] = "unknown libpng error";
};

[[noreturn]] void on_error(png_structp png, png_const_charp message) {
  auto* sink = static_cast<ErrorSink*>(png_get_error_ptr(png));
  std::snprintf(sink->message, sizeof sink->message, "%s", message ? message : "unknown libpng error");
  png_longjmp(png, 1);
}

void on_warning(png_structp, png_const_charp) {}

// libpng's own writer loses errno (a full disk reads "Write Error"): this one keeps it.
void write_data(png_structp png, png_bytep data, size_t length) {
  auto* file = static_cast<std::FILE*>(png_get_io_ptr(png));
  if (std::fwrite(data, 1, length, file) != length) png_error(png, std::strerror(errno));
}

void flush_data(png_structp png) {
  if (std::fflush(static_cast<std::FILE*>(png_get_io_ptr(png))) != 0) png_error(png, std::strerror(errno));
}

// PNG stores 16-bit samples big-endian; cv::Mat holds them in the machine's order.
void swap_16_bit_samples(png_structp png) {
#if __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  png_set_swap(png);
#else
  (void)png;
#endif
}

int colour_type_for(int channels) {
  static const int kType[5] = {-1, PNG_COLOR_TYPE_GRAY, PNG_COLOR_TYPE_GRAY_ALPHA, PNG_COLOR_TYPE_RGB,
                               PNG_COLOR_TYPE_RGB_ALPHA};
  return kType[channels];
}

}  // namespace

std::optional<cv::Mat> decode_image_data(const Info& info) {
  if (info.image_data.empty() || info.interlaced || !info.native()) return std::nullopt;
  const std::size_t sample = info.depth / 8, bpp = sample * static_cast<std::size_t>(info.channels);
  const std::size_t stride = bpp * info.width;
  // Uninitialised: a successful inflate writes every byte (exactly raw_size, checked below).
  const std::size_t raw_size = (stride + 1) * info.height;
  std::unique_ptr<std::uint8_t[]> raw(new std::uint8_t[raw_size]);
  libdeflate_decompressor* inflater = libdeflate_alloc_decompressor();
  if (!inflater) return std::nullopt;
  const libdeflate_result result = libdeflate_zlib_decompress(inflater, info.image_data.data(), info.image_data.size(),
                                                              raw.get(), raw_size, nullptr);
  libdeflate_free_decompressor(inflater);
  if (result != LIBDEFLATE_SUCCESS) return std::nullopt;
  cv::Mat image(static_cast<int>(info.height), static_cast<int>(info.width),
                info.depth == 16 ? CV_16UC(info.channels) : CV_8UC(info.channels));
  const bool swap = sample == 2 && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__;
  if (!unfilter(raw.get(), stride, bpp, info.width, info.height, swap, image)) return std::nullopt;
  return image;
}

cv::Mat decode(const fs::path& path, const Info& info, bool* from_image_data) {
  CV_Assert(info.native());
  if (from_image_data) *from_image_data = false;
  if (std::optional<cv::Mat> image = decode_image_data(info)) {
    if (from_image_data) *from_image_data = true;
    return *image;
  }
  // Everything with a destructor exists before setjmp: a longjmp skips no C++ frame.
  cv::Mat image(static_cast<int>(info.height), static_cast<int>(info.width),
                info.depth == 16 ? CV_16UC(info.channels) : CV_8UC(info.channels));
  std::vector<png_bytep> rows(image.rows);
  for (int y = 0; y < image.rows; ++y) rows[y] = image.ptr(y);
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) throw Error(quoted(path) + ": cannot open (" + std::strerror(errno) + ")");
  ErrorSink sink;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &sink, on_error, on_warning);
  png_infop png_info = png ? png_create_info_struct(png) : nullptr;
  volatile bool ok = false;
  if (png && png_info && setjmp(png_jmpbuf(png)) == 0) {
    png_init_io(png, file);
    png_set_user_limits(png, kMaxSide, kMaxSide);
    png_read_info(png, png_info);
    if (info.depth == 16) swap_16_bit_samples(png);
    png_set_interlace_handling(png);
    png_read_update_info(png, png_info);
    if (png_get_rowbytes(png, png_info) != image.step[0] || png_get_image_width(png, png_info) != info.width ||
        png_get_image_height(png, png_info) != info.height)
      png_error(png, "the image changed while it was read");
    png_read_image(png, rows.data());
    png_read_end(png, nullptr);
    ok = true;
  }
  png_destroy_read_struct(png ? &png : nullptr, png_info ? &png_info : nullptr, nullptr);
  std::fclose(file);
  if (!ok) {
    // The words check() uses for the same fault, which libpng calls "Not enough image data".
    if (std::strcmp(sink.message, "Not enough image data") == 0)
      throw Error(quoted(path) + ": truncated PNG (the image data ends before the last row)");
    throw Error(quoted(path) + ": cannot decode (" + sink.message + ")");
  }
  return image;
}

namespace {

// Paeth residuals of one row of `bytes` bytes with `bpp` bytes per pixel against the row above
// (all zero for the first row, where Paeth is the Sub filter). The predictor reads only unfiltered
// bytes, so there is no dependency between iterations and the compiler vectorises the loop
// (in a scratch timing at -O3, 6 ms for a 2048x1024 RGB frame).
inline __attribute__((always_inline)) void paeth_row_any(const std::uint8_t* __restrict row,
                                                         const std::uint8_t* __restrict above,
                                                         std::uint8_t* __restrict out, std::size_t bytes, std::size_t bpp) {
  for (std::size_t i = 0; i < bpp && i < bytes; ++i) out[i] = static_cast<std::uint8_t>(row[i] - above[i]);
  for (std::size_t i = bpp; i < bytes; ++i)
    out[i] = static_cast<std::uint8_t>(row[i] - paeth_predictor(row[i - bpp], above[i], above[i - bpp]));
}

void paeth_row_sse2(const std::uint8_t* row, const std::uint8_t* above, std::uint8_t* out, std::size_t bytes,
                    std::size_t bpp) {
  paeth_row_any(row, above, out, bytes, bpp);
}

#if defined(__x86_64__) && defined(__GNUC__)
// The same loop vectorised for AVX2 and AVX-512 (integer arithmetic: the same bytes), chosen
// when first called. Not with target_clones: its resolver runs while the program is loaded,
// before libraindrop_hide_avx512.so (README) hides those features, and it would fix the
// processor's features for every later check in the program.
__attribute__((target("avx2"))) void paeth_row_avx2(const std::uint8_t* row, const std::uint8_t* above,
                                                    std::uint8_t* out, std::size_t bytes, std::size_t bpp) {
  paeth_row_any(row, above, out, bytes, bpp);
}
__attribute__((target("avx512f,avx512bw"))) void paeth_row_avx512(const std::uint8_t* row, const std::uint8_t* above,
                                                                  std::uint8_t* out, std::size_t bytes,
                                                                  std::size_t bpp) {
  paeth_row_any(row, above, out, bytes, bpp);
}
#endif

using PaethRow = void (*)(const std::uint8_t*, const std::uint8_t*, std::uint8_t*, std::size_t, std::size_t);

PaethRow paeth_row_for_this_cpu() {
#if defined(__x86_64__) && defined(__GNUC__)
  if (simd_level() == 2) return paeth_row_avx512;
  if (simd_level() == 1) return paeth_row_avx2;
#endif
  return paeth_row_sse2;
}

void paeth_row(const std::uint8_t* row, const std::uint8_t* above, std::uint8_t* out, std::size_t bytes,
               std::size_t bpp) {
  static const PaethRow chosen = paeth_row_for_this_cpu();
  chosen(row, above, out, bytes, bpp);
}

void put32(std::uint8_t* out, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) out[k] = static_cast<std::uint8_t>(v >> (24 - 8 * k));
}

// Writes one chunk straight to the file: length, type, data, CRC of type and data. False when
// the file refuses a byte (errno says why).
bool write_chunk(std::FILE* file, const char* type, const std::uint8_t* data, std::size_t length) {
  std::uint8_t head[8], crc[4];
  put32(head, static_cast<std::uint32_t>(length));
  std::memcpy(head + 4, type, 4);
  std::uint32_t sum = libdeflate_crc32(0, type, 4);
  if (length > 0) sum = libdeflate_crc32(sum, data, length);  // (a null buffer would restart the sum)
  put32(crc, sum);
  return std::fwrite(head, 1, 8, file) == 8 && (length == 0 || std::fwrite(data, 1, length, file) == length) &&
         std::fwrite(crc, 1, 4, file) == 4;
}

// kPngFast: every row Paeth-filtered, the whole image deflated in one call by libdeflate at its
// level 1, and the chunks written here (libpng's writer can only use zlib). On a 2048x1024
// street frame 2.05x faster than kPngRunLength for 13% more bytes: the size of zlib level 3 (the
// default before run-length) and 8% over level 6 (docs/RESULTS.md section 1).
// An iCCP chunk's data for `icc`: a name, a zero, method 0 (zlib), the profile deflated.
std::vector<std::uint8_t> iccp_chunk(const std::string& icc, const fs::path& name) {
  static const char kName[] = "ICC profile";
  uLongf bound = ::compressBound(static_cast<uLong>(icc.size()));
  std::vector<std::uint8_t> chunk(sizeof kName + 1 + bound);
  std::memcpy(chunk.data(), kName, sizeof kName);  // with its terminating zero
  chunk[sizeof kName] = 0;                         // compression method: zlib
  if (::compress2(chunk.data() + sizeof kName + 1, &bound, reinterpret_cast<const Bytef*>(icc.data()),
                  static_cast<uLong>(icc.size()), 6) != Z_OK)
    throw Error(quoted(name) + ": cannot write (the colour profile does not compress)");
  chunk.resize(sizeof kName + 1 + bound);
  return chunk;
}

void encode_fast(const cv::Mat& image, std::FILE* file, const fs::path& name, const std::string& icc) {
  // What libpng's writer refuses, and check() would refuse on reading the file back.
  if (image.empty() || static_cast<std::uint32_t>(image.cols) > kMaxSide || static_cast<std::uint32_t>(image.rows) > kMaxSide)
    throw Error(quoted(name) + ": cannot write (a PNG's sides are 1 to " + std::to_string(kMaxSide) + " pixels; this image is " +
                std::to_string(image.cols) + "x" + std::to_string(image.rows) + ")");
  const std::size_t sample = image.depth() == CV_16U ? 2 : 1;
  const std::size_t bpp = sample * static_cast<std::size_t>(image.channels());
  const std::size_t stride = bpp * static_cast<std::size_t>(image.cols);
  // Uninitialised, as `deflated` below (every byte read is written first): a std::vector's zeros
  // were a pass over memory the size of the image, a percent of a frame's time (perf).
  const std::size_t filtered_size = (stride + 1) * static_cast<std::size_t>(image.rows);
  std::unique_ptr<std::uint8_t[]> filtered(new std::uint8_t[filtered_size]);
  // PNG's 16-bit samples are big-endian: such rows are converted first, into two row buffers.
  std::vector<std::uint8_t> zero(stride, 0), big[2];
  const bool swap = sample == 2 && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__;
  if (swap) big[0].resize(stride), big[1].resize(stride);
  const std::uint8_t* above = zero.data();
  for (int y = 0; y < image.rows; ++y) {
    const std::uint8_t* row = image.ptr<std::uint8_t>(y);
    if (swap) {
      copy_swapping_16_bit(row, big[y & 1].data(), stride);
      row = big[y & 1].data();
    }
    std::uint8_t* out = filtered.get() + static_cast<std::size_t>(y) * (stride + 1);
    out[0] = 4;  // Paeth
    paeth_row(row, above, out + 1, stride, bpp);
    above = row;
  }
  libdeflate_compressor* compressor = libdeflate_alloc_compressor(1);
  if (!compressor) throw Error(quoted(name) + ": cannot write (out of memory)");
  const std::size_t deflated_bound = libdeflate_zlib_compress_bound(compressor, filtered_size);
  std::unique_ptr<std::uint8_t[]> deflated(new std::uint8_t[deflated_bound]);
  const std::size_t deflated_size =
      libdeflate_zlib_compress(compressor, filtered.get(), filtered_size, deflated.get(), deflated_bound);
  libdeflate_free_compressor(compressor);
  if (deflated_size == 0) throw Error(quoted(name) + ": cannot write (compression failed)");

  filtered.reset();  // not needed any more: the file is written from `deflated`

  static const std::uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::uint8_t ihdr[13];
  put32(ihdr, static_cast<std::uint32_t>(image.cols));
  put32(ihdr + 4, static_cast<std::uint32_t>(image.rows));
  ihdr[8] = static_cast<std::uint8_t>(8 * sample);
  ihdr[9] = static_cast<std::uint8_t>(colour_type_for(image.channels()));
  ihdr[10] = ihdr[11] = ihdr[12] = 0;  // deflate, adaptive filtering, no interlace
  bool ok = std::fwrite(kSignature, 1, 8, file) == 8 && write_chunk(file, "IHDR", ihdr, sizeof ihdr);
  if (ok && !icc.empty()) {  // before the image data, as the format requires
    const std::vector<std::uint8_t> chunk = iccp_chunk(icc, name);
    ok = write_chunk(file, "iCCP", chunk.data(), chunk.size());
  }
  constexpr std::size_t kIdatBytes = 1 << 20;  // chunks of 1 MiB, as encoders commonly write
  for (std::size_t at = 0; ok && at < deflated_size; at += kIdatBytes)
    ok = write_chunk(file, "IDAT", deflated.get() + at, std::min(kIdatBytes, deflated_size - at));
  ok = ok && write_chunk(file, "IEND", nullptr, 0) && std::fflush(file) == 0;
  if (!ok) throw Error(quoted(name) + ": cannot write (" + std::strerror(errno) + ")");
}

}  // namespace

void encode(const cv::Mat& image, std::FILE* file, int level, const fs::path& name, const std::string& icc) {
  CV_Assert((image.depth() == CV_8U || image.depth() == CV_16U) && image.channels() >= 1 && image.channels() <= 4);
  if (level == kPngFast) return encode_fast(image, file, name, icc);
  std::vector<png_bytep> rows(image.rows);
  for (int y = 0; y < image.rows; ++y) rows[y] = const_cast<png_bytep>(image.ptr(y));
  ErrorSink sink;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &sink, on_error, on_warning);
  png_infop png_info = png ? png_create_info_struct(png) : nullptr;
  volatile bool ok = false;
  if (png && png_info && setjmp(png_jmpbuf(png)) == 0) {
    png_set_write_fn(png, file, write_data, flush_data);
    if (level == kPngRunLength) {
      png_set_compression_strategy(png, Z_RLE);
      png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_PAETH);
    } else {
      png_set_compression_level(png, std::min(std::max(level, 0), 9));
    }
    png_set_IHDR(png, png_info, static_cast<png_uint_32>(image.cols), static_cast<png_uint_32>(image.rows),
                 image.depth() == CV_16U ? 16 : 8, colour_type_for(image.channels()), PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    if (!icc.empty())
      png_set_iCCP(png, png_info, "ICC profile", PNG_COMPRESSION_TYPE_BASE,
                   reinterpret_cast<png_const_bytep>(icc.data()), static_cast<png_uint_32>(icc.size()));
    png_write_info(png, png_info);
    if (image.depth() == CV_16U) swap_16_bit_samples(png);
    png_write_image(png, rows.data());
    png_write_end(png, nullptr);
    ok = true;
  }
  png_destroy_write_struct(png ? &png : nullptr, png_info ? &png_info : nullptr);
  if (!ok) throw Error(quoted(name) + ": cannot write (" + sink.message + ")");
}

}  // namespace raindrop::png

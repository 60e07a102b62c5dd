#include "png_file.h"

#include <algorithm>
#include <atomic>
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
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif
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

std::string icc_profile(const Info& info) {
  // Profile name (1-79 bytes), a zero, the compression method (0: zlib), the zlib stream.
  const std::size_t name_end = info.iccp.find('\0');
  if (name_end == std::string::npos || name_end == 0 || name_end > 79 || name_end + 2 > info.iccp.size() ||
      info.iccp[name_end + 1] != 0)
    return {};
  z_stream z{};
  if (::inflateInit(&z) != Z_OK) return {};
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(info.iccp.data() + name_end + 2));
  z.avail_in = static_cast<uInt>(info.iccp.size() - name_end - 2);
  constexpr std::size_t kMaxProfile = std::size_t{64} << 20;
  std::string profile;
  char buffer[1 << 16];
  int rc = Z_OK;
  while (rc == Z_OK && profile.size() <= kMaxProfile) {
    z.next_out = reinterpret_cast<Bytef*>(buffer);
    z.avail_out = sizeof buffer;
    rc = ::inflate(&z, Z_NO_FLUSH);
    profile.append(buffer, sizeof buffer - z.avail_out);
  }
  ::inflateEnd(&z);
  return rc == Z_STREAM_END && profile.size() <= kMaxProfile ? profile : std::string();
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

// Copies `bytes` bytes of 16-bit samples, swapping each sample's two bytes (PNG's big-endian
// order to or from the order of a little-endian machine's cv::Mat).
void copy_swapping_16_bit(const std::uint8_t* from, std::uint8_t* to, std::size_t bytes) {
  for (std::size_t i = 0; i < bytes; i += 2) to[i] = from[i + 1], to[i + 1] = from[i];
}

int colour_type_for(int channels) {
  static const int kType[5] = {-1, PNG_COLOR_TYPE_GRAY, PNG_COLOR_TYPE_GRAY_ALPHA, PNG_COLOR_TYPE_RGB,
                               PNG_COLOR_TYPE_RGB_ALPHA};
  return kType[channels];
}

int paeth_predictor(int a, int b, int c) {
  const int pa = std::abs(b - c), pb = std::abs(a - c), pc = std::abs(a + b - 2 * c);
  const int b_or_c = pb <= pc ? b : c;  // two selects the compiler makes branch-free
  return pa <= pb && pa <= pc ? a : b_or_c;
}

// Undoes the Paeth filter of one row, `src` (filtered) into `dst` (which may be `src`), a pixel
// at a time: each of the BPP byte chains depends on its own left neighbour only, so the BPP
// chains run side by side (in a scratch timing of a 2048x1024 RGB frame: 13 ms, against 21 for
// the plain byte loop).
template <std::size_t BPP>
void unpaeth(const std::uint8_t* src, std::uint8_t* dst, const std::uint8_t* above, std::size_t stride) {
  int left[BPP] = {0}, upper_left[BPP] = {0};  // zeros before the first pixel: Paeth is then Up
  for (std::size_t i = 0; i < stride; i += BPP) {
    for (std::size_t k = 0; k < BPP; ++k) {
      const int up = above[i + k];
      left[k] = static_cast<std::uint8_t>(src[i + k] + paeth_predictor(left[k], up, upper_left[k]));
      dst[i + k] = static_cast<std::uint8_t>(left[k]);
      upper_left[k] = up;
    }
  }
}

// Pixels [x0, x1) of a Paeth row, src into dst, the pixels before x0 (and above them) already
// undone: unpaeth's arithmetic from a given start, for the corners that unpaeth_band leaves.
template <std::size_t BPP>
void unpaeth_range(const std::uint8_t* src, std::uint8_t* dst, const std::uint8_t* above, std::size_t x0,
                   std::size_t x1) {
  for (std::size_t x = x0; x < x1; ++x) {
    for (std::size_t k = 0; k < BPP; ++k) {
      const std::size_t i = x * BPP + k;
      const int left = x > 0 ? dst[i - BPP] : 0, upper_left = x > 0 ? above[i - BPP] : 0;
      dst[i] = static_cast<std::uint8_t>(src[i] + paeth_predictor(left, above[i], upper_left));
    }
  }
}

#if defined(__x86_64__) && defined(__GNUC__)
// A pixel's BPP bytes as the low bytes of an int (no byte past them read).
template <std::size_t BPP>
inline int band_pixel(const std::uint8_t* p) {
  std::uint32_t v = 0;
  std::memcpy(&v, p, BPP);
  return static_cast<int>(v);
}

// Four consecutive Paeth rows of BPP (3 or 4) bytes per pixel, `width` >= 4 pixels, undone at
// once as a wavefront, from `src` (the filtered rows, `src_pitch` bytes from one to the next)
// into `dst` (`dst_pitch`): at step t, row k undoes its pixel t - k, whose left neighbour row k
// made one step before and whose upper neighbours row k - 1 made one and two steps before. The
// four rows' chains of dependent steps then run side by side in one AVX2 register (four slots of
// four 16-bit lanes, a pixel's bytes), where one row's chain left the processor waiting on each
// step's latency. Every lane does unpaeth's integer arithmetic: the same bytes. The corners where
// a row has no pixel at a step (its first 3 - k pixels and last k) are unpaeth_range's; slot 0
// reads its upper neighbours from `above`, the row over the band, four bytes at a time (for BPP
// 3 the fourth is ignored: lanes do not mix), so `above` needs a byte after its last pixel. Each
// slot stores exactly its pixel's bytes.
template <std::size_t BPP>
__attribute__((target("avx2"), always_inline)) inline void unpaeth_band4_avx2(const std::uint8_t* src,
                                                                             std::size_t src_pitch, std::uint8_t* dst,
                                                                             std::size_t dst_pitch,
                                                                             const std::uint8_t* above,
                                                                             std::size_t width) {
  static_assert(BPP == 3 || BPP == 4, "a pixel per slot of four lanes");
  const std::uint8_t* in[4] = {src, src + src_pitch, src + 2 * src_pitch, src + 3 * src_pitch};
  std::uint8_t* out[4] = {dst, dst + dst_pitch, dst + 2 * dst_pitch, dst + 3 * dst_pitch};
  for (int k = 0; k < 3; ++k)
    unpaeth_range<BPP>(in[k], out[k], k == 0 ? above : out[k - 1], 0, static_cast<std::size_t>(3 - k));
  // Slot k's pixel 2 - k (prev) and 1 - k (prev2), those before the first step t = 3.
  __m256i prev = _mm256_cvtepu8_epi16(
      _mm_setr_epi32(band_pixel<BPP>(out[0] + 2 * BPP), band_pixel<BPP>(out[1] + BPP), band_pixel<BPP>(out[2]), 0));
  __m256i prev2 = _mm256_cvtepu8_epi16(_mm_setr_epi32(band_pixel<BPP>(out[0] + BPP), band_pixel<BPP>(out[1]), 0, 0));
  // Row k's filtered pixel t - k lies at src + t BPP + k (src_pitch - BPP): one gather for the four.
  const __m128i offsets = _mm_setr_epi32(0, static_cast<int>(src_pitch - BPP), static_cast<int>(2 * (src_pitch - BPP)),
                                         static_cast<int>(3 * (src_pitch - BPP)));
  const __m256i low_byte = _mm256_set1_epi16(0xff);
  for (std::size_t t = 3; t < width; ++t) {
    // Four bytes a slot: for BPP 3 the fourth is the next pixel's first (or the next row's filter
    // type), ignored.
    const __m256i x =
        _mm256_cvtepu8_epi16(_mm_i32gather_epi32(reinterpret_cast<const int*>(src + t * BPP), offsets, 1));
    // Upper neighbours: slot k - 1's last two outputs moved up a slot; slot 0's from `above`,
    // read four bytes at once: a pixel assembled from narrower loads stalled the chain on a store
    // that could not be forwarded.
    std::int32_t up, up_left;
    std::memcpy(&up, above + t * BPP, 4);
    std::memcpy(&up_left, above + (t - 1) * BPP, 4);
    const __m256i b = _mm256_blend_epi32(_mm256_permute4x64_epi64(prev, _MM_SHUFFLE(2, 1, 0, 0)),
                                         _mm256_cvtepu8_epi16(_mm_cvtsi32_si128(up)), 0x03);
    const __m256i c = _mm256_blend_epi32(_mm256_permute4x64_epi64(prev2, _MM_SHUFFLE(2, 1, 0, 0)),
                                         _mm256_cvtepu8_epi16(_mm_cvtsi32_si128(up_left)), 0x03);
    const __m256i a = prev;
    const __m256i b_c = _mm256_sub_epi16(b, c), a_c = _mm256_sub_epi16(a, c);
    const __m256i pa = _mm256_abs_epi16(b_c), pb = _mm256_abs_epi16(a_c), pc = _mm256_abs_epi16(_mm256_add_epi16(b_c, a_c));
    // a where pa <= pb and pa <= pc; else b where pb <= pc; else c.
    const __m256i not_a = _mm256_or_si256(_mm256_cmpgt_epi16(pa, pb), _mm256_cmpgt_epi16(pa, pc));
    const __m256i b_or_c = _mm256_blendv_epi8(b, c, _mm256_cmpgt_epi16(pb, pc));
    const __m256i predictor = _mm256_blendv_epi8(a, b_or_c, not_a);
    const __m256i result = _mm256_and_si256(_mm256_add_epi16(x, predictor), low_byte);
    const __m128i bytes = _mm_packus_epi16(_mm256_castsi256_si128(result), _mm256_extracti128_si256(result, 1));
    const std::uint32_t v0 = static_cast<std::uint32_t>(_mm_cvtsi128_si32(bytes));
    const std::uint32_t v1 = static_cast<std::uint32_t>(_mm_extract_epi32(bytes, 1));
    const std::uint32_t v2 = static_cast<std::uint32_t>(_mm_extract_epi32(bytes, 2));
    const std::uint32_t v3 = static_cast<std::uint32_t>(_mm_extract_epi32(bytes, 3));
    std::memcpy(out[0] + t * BPP, &v0, BPP);
    std::memcpy(out[1] + (t - 1) * BPP, &v1, BPP);
    std::memcpy(out[2] + (t - 2) * BPP, &v2, BPP);
    std::memcpy(out[3] + (t - 3) * BPP, &v3, BPP);
    prev2 = prev;
    prev = result;
  }
  for (int k = 1; k < 4; ++k)
    unpaeth_range<BPP>(in[k], out[k], out[k - 1], width - static_cast<std::size_t>(k), width);
}

__attribute__((target("avx2"))) void unpaeth_band3(const std::uint8_t* src, std::size_t src_pitch, std::uint8_t* dst,
                                                   std::size_t dst_pitch, const std::uint8_t* above,
                                                   std::size_t width) {
  unpaeth_band4_avx2<3>(src, src_pitch, dst, dst_pitch, above, width);
}
__attribute__((target("avx2"))) void unpaeth_band4(const std::uint8_t* src, std::size_t src_pitch, std::uint8_t* dst,
                                                   std::size_t dst_pitch, const std::uint8_t* above,
                                                   std::size_t width) {
  unpaeth_band4_avx2<4>(src, src_pitch, dst, dst_pitch, above, width);
}

// The same with eight rows in one AVX-512 register (eight slots), for processors that have it:
// twice the rows per step of the same chain. `width` >= 8.
// GCC 12 warns that the "undefined" register its own AVX-512 headers pass to the permute and the
// narrowing (_mm512_undefined_epi32) may be used uninitialised: a false positive, silenced here only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
template <std::size_t BPP>
__attribute__((target("avx512f,avx512bw"), always_inline)) inline void unpaeth_band8_avx512(
    const std::uint8_t* src, std::size_t src_pitch, std::uint8_t* dst, std::size_t dst_pitch, const std::uint8_t* above,
    std::size_t width) {
  static_assert(BPP == 3 || BPP == 4, "a pixel per slot of four lanes");
  constexpr int R = 8;
  const std::uint8_t* in[R];
  std::uint8_t* out[R];
  for (int k = 0; k < R; ++k) in[k] = src + k * src_pitch, out[k] = dst + k * dst_pitch;
  for (int k = 0; k + 1 < R; ++k)
    unpaeth_range<BPP>(in[k], out[k], k == 0 ? above : out[k - 1], 0, static_cast<std::size_t>(R - 1 - k));
  alignas(32) std::int32_t w1[R], w2[R], offsets_of[R];
  for (int k = 0; k < R; ++k) {
    w1[k] = R - 2 - k >= 0 ? band_pixel<BPP>(out[k] + (R - 2 - k) * BPP) : 0;
    w2[k] = R - 3 - k >= 0 ? band_pixel<BPP>(out[k] + (R - 3 - k) * BPP) : 0;
    offsets_of[k] = static_cast<std::int32_t>(k * (src_pitch - BPP));
  }
  __m512i prev = _mm512_cvtepu8_epi16(_mm256_load_si256(reinterpret_cast<const __m256i*>(w1)));
  __m512i prev2 = _mm512_cvtepu8_epi16(_mm256_load_si256(reinterpret_cast<const __m256i*>(w2)));
  const __m256i offsets = _mm256_load_si256(reinterpret_cast<const __m256i*>(offsets_of));
  const __m512i up_a_slot = _mm512_setr_epi64(0, 0, 1, 2, 3, 4, 5, 6);
  const __m512i low_byte = _mm512_set1_epi16(0xff);
  alignas(32) std::uint32_t v[R];
  for (std::size_t t = R - 1; t < width; ++t) {
    const __m512i x =
        _mm512_cvtepu8_epi16(_mm256_i32gather_epi32(reinterpret_cast<const int*>(src + t * BPP), offsets, 1));
    std::int32_t up, up_left;
    std::memcpy(&up, above + t * BPP, 4);
    std::memcpy(&up_left, above + (t - 1) * BPP, 4);
    const __m512i b = _mm512_mask_blend_epi64(0x01, _mm512_permutexvar_epi64(up_a_slot, prev),
                                              _mm512_cvtepu8_epi16(_mm256_castsi128_si256(_mm_cvtsi32_si128(up))));
    const __m512i c = _mm512_mask_blend_epi64(0x01, _mm512_permutexvar_epi64(up_a_slot, prev2),
                                              _mm512_cvtepu8_epi16(_mm256_castsi128_si256(_mm_cvtsi32_si128(up_left))));
    const __m512i a = prev;
    const __m512i b_c = _mm512_sub_epi16(b, c), a_c = _mm512_sub_epi16(a, c);
    const __m512i pa = _mm512_abs_epi16(b_c), pb = _mm512_abs_epi16(a_c), pc = _mm512_abs_epi16(_mm512_add_epi16(b_c, a_c));
    // a where pa <= pb and pa <= pc; else b where pb <= pc; else c.
    const __mmask32 not_a = _mm512_cmpgt_epi16_mask(pa, pb) | _mm512_cmpgt_epi16_mask(pa, pc);
    const __m512i b_or_c = _mm512_mask_blend_epi16(_mm512_cmpgt_epi16_mask(pb, pc), b, c);
    const __m512i predictor = _mm512_mask_blend_epi16(not_a, a, b_or_c);
    const __m512i result = _mm512_and_si512(_mm512_add_epi16(x, predictor), low_byte);
    _mm256_store_si256(reinterpret_cast<__m256i*>(v), _mm512_cvtepi16_epi8(result));
    for (int k = 0; k < R; ++k) std::memcpy(out[k] + (t - k) * BPP, &v[k], BPP);
    prev2 = prev;
    prev = result;
  }
  for (int k = 1; k < R; ++k)
    unpaeth_range<BPP>(in[k], out[k], out[k - 1], width - static_cast<std::size_t>(k), width);
}

__attribute__((target("avx512f,avx512bw"))) void unpaeth_band8_3(const std::uint8_t* src, std::size_t src_pitch,
                                                                 std::uint8_t* dst, std::size_t dst_pitch,
                                                                 const std::uint8_t* above, std::size_t width) {
  unpaeth_band8_avx512<3>(src, src_pitch, dst, dst_pitch, above, width);
}
__attribute__((target("avx512f,avx512bw"))) void unpaeth_band8_4(const std::uint8_t* src, std::size_t src_pitch,
                                                                 std::uint8_t* dst, std::size_t dst_pitch,
                                                                 const std::uint8_t* above, std::size_t width) {
  unpaeth_band8_avx512<4>(src, src_pitch, dst, dst_pitch, above, width);
}
#pragma GCC diagnostic pop
#endif

std::atomic<int> paeth_bands_limit{2};

// The widest bands this processor runs, at most what a test allowed: 0 none, 1 four rows (AVX2),
// 2 eight rows (AVX-512).
int paeth_bands() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const int widest = __builtin_cpu_supports("avx512bw") ? 2 : __builtin_cpu_supports("avx2") ? 1 : 0;
  return std::min(widest, paeth_bands_limit.load(std::memory_order_relaxed));
#else
  return 0;
#endif
}

}  // namespace

int limit_paeth_bands(int level) {
  paeth_bands_limit.store(level, std::memory_order_relaxed);
#if defined(__x86_64__) && defined(__GNUC__)
  return __builtin_cpu_supports("avx512bw") ? 2 : __builtin_cpu_supports("avx2") ? 1 : 0;
#else
  return 0;
#endif
}

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
  // Each row undone against the one above (zeros above the first). 8-bit rows go from `raw`
  // straight into the image's rows (a copy afterwards was 3% of a 512x256 render's time, perf);
  // 16-bit rows are undone in place and then copied with their bytes swapped where the machine
  // is little-endian (PNG's samples are big-endian).
  cv::Mat image(static_cast<int>(info.height), static_cast<int>(info.width),
                info.depth == 16 ? CV_16UC(info.channels) : CV_8UC(info.channels));
  const bool swap = sample == 2 && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__;
  auto source_row = [&](std::size_t y) { return raw.get() + y * (stride + 1) + 1; };
  auto output_row = [&](std::size_t y) { return swap ? source_row(y) : image.ptr<std::uint8_t>(static_cast<int>(y)); };
  // Zeros over the first row, with bytes to spare: unpaeth_band reads four bytes a pixel, one
  // past the last pixel of an RGB row (where an image row has the next row's first byte).
  const std::vector<std::uint8_t> zero(stride + 4, 0);
  const std::uint8_t* above = zero.data();
  // Runs of eight or four Paeth rows of 8-bit RGB or RGBA (most rows of most photographs' PNGs) as
  // bands, where the processor has the registers for them.
  const int bands = !swap && (bpp == 3 || bpp == 4) ? paeth_bands() : 0;
  auto paeth_run = [&](std::size_t y, std::size_t n) {  // rows y .. y + n - 1 all Paeth
    if (y + n > info.height || info.width < n) return false;
    for (std::size_t k = 0; k < n; ++k)
      if (raw[(y + k) * (stride + 1)] != 4) return false;
    return true;
  };
  for (std::size_t y = 0; y < info.height; ++y) {
    const std::uint8_t* src = source_row(y);
    std::uint8_t* dst = output_row(y);
    const std::uint8_t type = src[-1];
#if defined(__x86_64__) && defined(__GNUC__)
    if (type == 4 && bands >= 2 && paeth_run(y, 8)) {
      (bpp == 3 ? unpaeth_band8_3 : unpaeth_band8_4)(src, stride + 1, dst, image.step[0], above, info.width);
      y += 7;
      above = output_row(y);
      continue;
    }
    if (type == 4 && bands >= 1 && paeth_run(y, 4)) {
      (bpp == 3 ? unpaeth_band3 : unpaeth_band4)(src, stride + 1, dst, image.step[0], above, info.width);
      y += 3;
      above = output_row(y);
      continue;
    }
#endif
    switch (type) {
      case 0:
        if (dst != src) std::memcpy(dst, src, stride);
        break;
      case 1:
        for (std::size_t i = 0; i < bpp && i < stride; ++i) dst[i] = src[i];
        for (std::size_t i = bpp; i < stride; ++i) dst[i] = static_cast<std::uint8_t>(src[i] + dst[i - bpp]);
        break;
      case 2:
        for (std::size_t i = 0; i < stride; ++i) dst[i] = static_cast<std::uint8_t>(src[i] + above[i]);
        break;
      case 3:
        for (std::size_t i = 0; i < bpp && i < stride; ++i) dst[i] = static_cast<std::uint8_t>(src[i] + (above[i] >> 1));
        for (std::size_t i = bpp; i < stride; ++i)
          dst[i] = static_cast<std::uint8_t>(src[i] + ((dst[i - bpp] + above[i]) >> 1));
        break;
      case 4:
        switch (bpp) {
          case 1: unpaeth<1>(src, dst, above, stride); break;
          case 2: unpaeth<2>(src, dst, above, stride); break;
          case 3: unpaeth<3>(src, dst, above, stride); break;
          case 4: unpaeth<4>(src, dst, above, stride); break;
          case 6: unpaeth<6>(src, dst, above, stride); break;
          default: unpaeth<8>(src, dst, above, stride); break;  // 16-bit RGBA
        }
        break;
      default:
        return std::nullopt;
    }
    above = dst;
  }
  if (swap)
    for (std::size_t y = 0; y < info.height; ++y)
      copy_swapping_16_bit(source_row(y), image.ptr<std::uint8_t>(static_cast<int>(y)), stride);
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
  if (__builtin_cpu_supports("avx512bw")) return paeth_row_avx512;
  if (__builtin_cpu_supports("avx2")) return paeth_row_avx2;
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

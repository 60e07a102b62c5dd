// PNG through libpng (src/common/png_file.cpp) against OpenImageIO as the reference: what one
// writes the other reads back exactly, for every depth and channel count the programs write; the
// PNGs libpng is not asked to decode (palettes, low bit depths, tRNS) reach OpenImageIO's plugin
// and come back as OpenImageIO reads them.
#include <gtest/gtest.h>
#include <png.h>
#include <zlib.h>

#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <cstring>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <random>
#include <set>

#include "raindrop/common/error.h"
#include "raindrop/common/image_io.h"
#include "../../src/common/png_file.h"  // decode_image_data, our decoding path on its own
#include "../../src/common/png_unfilter.h"  // limit_paeth_bands
#include "test_images.h"
#include "png_bytes.h"
#include "test_support.h"

namespace fs = std::filesystem;

using namespace raindrop;
using testsupport::read_image;
using testsupport::write_image;

namespace {

cv::Mat random_image(int rows, int cols, int depth, int channels, unsigned seed) {
  cv::Mat m(rows, cols, CV_MAKETYPE(depth, channels));
  std::mt19937 rng(seed);
  if (depth == CV_8U) {
    for (auto it = m.datastart; it != m.dataend; ++it) *const_cast<uchar*>(it) = static_cast<uchar>(rng());
  } else {
    for (int y = 0; y < rows; ++y)
      for (int i = 0; i < cols * channels; ++i) m.ptr<std::uint16_t>(y)[i] = static_cast<std::uint16_t>(rng());
  }
  return m;
}

bool same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

// A PNG that only a full decoder takes: written with libpng's low-level calls.
// `filters`: libpng's row filter choice (PNG_FILTER_* flags; 0: its default).
void write_png_raw(const fs::path& p, int width, int height, int depth, int colour_type, bool trns, bool interlace,
                   const std::vector<png_byte>& packed_rows, int filters = 0) {
  std::FILE* f = std::fopen(p.c_str(), "wb");
  ASSERT_TRUE(f);
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  ASSERT_EQ(setjmp(png_jmpbuf(png)), 0);
  png_init_io(png, f);
  if (filters != 0) png_set_filter(png, PNG_FILTER_TYPE_BASE, filters);
  png_set_IHDR(png, info, width, height, depth, colour_type, interlace ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  std::vector<png_color> palette;
  if (colour_type == PNG_COLOR_TYPE_PALETTE) {
    for (int i = 0; i < 16; ++i) palette.push_back({png_byte(i * 16), png_byte(255 - i * 16), png_byte(i * 7)});
    png_set_PLTE(png, info, palette.data(), 16);
  }
  png_byte alpha[16];
  png_color_16 key{};
  key.gray = 3;
  key.red = 10;
  key.green = 20;
  key.blue = 30;
  for (int i = 0; i < 16; ++i) alpha[i] = png_byte(i * 17);
  if (trns) png_set_tRNS(png, info, alpha, colour_type == PNG_COLOR_TYPE_PALETTE ? 16 : 0, &key);
  png_write_info(png, info);
  const size_t row_bytes = png_get_rowbytes(png, info);
  std::vector<png_bytep> rows(height);
  for (int y = 0; y < height; ++y) rows[y] = const_cast<png_bytep>(packed_rows.data()) + y * row_bytes;
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  std::fclose(f);
}

// What read_image_native says of a file it should refuse: its error, or "decoded" when it
// read the file (for the refusal tests, which look for their phrase in it).
std::string read_error(const fs::path& file) {
  try {
    read_image_native(file);
    return "decoded";
  } catch (const Error& e) {
    return e.what();
  }
}

}  // namespace

TEST(PngFile, WrittenFilesReadBackExactlyInBothLibraries) {
  testsupport::TempDir tmp("raindrop-png-");
  int seed = 1;
  for (int depth : {CV_8U, CV_16U}) {
    for (int channels = 1; channels <= 4; ++channels) {
      SCOPED_TRACE("depth " + std::to_string(depth) + ", channels " + std::to_string(channels));
      const cv::Mat m = random_image(37, 53, depth, channels, seed++);
      // Ours written (the default, and each of our own writers at odd sizes), both read.
      const auto ours = tmp / ("ours" + std::to_string(seed) + ".png");
      EXPECT_EQ(write_image_atomic(m, ours), "");
      std::string why;
      const auto by_oiio = read_image(ours, &why);
      ASSERT_TRUE(by_oiio) << why;
      EXPECT_TRUE(same(by_oiio->pixels, m)) << "OpenImageIO reads our PNG differently";
      EXPECT_TRUE(same(read_image_native(ours), m)) << "we read our PNG differently";
      for (int level : {kPngFast, kPngRunLength}) {
        for (const cv::Size size : {cv::Size(1, 1), cv::Size(1, 9), cv::Size(7, 1), cv::Size(2, 3), cv::Size(33, 17)}) {
          const cv::Mat small = random_image(size.height, size.width, depth, channels, seed++);
          const auto file = tmp / ("small" + std::to_string(seed) + ".png");
          write_image_atomic(small, file, level);
          // Our own decoding path reads it (not only libpng behind it).
          EXPECT_TRUE(png::decode_image_data(png::check(file, fs::file_size(file), true)).has_value());
          const auto read = read_image(file, &why);
          ASSERT_TRUE(read) << why;
          EXPECT_TRUE(same(read->pixels, small)) << png_level_name(level) << " " << size;
          EXPECT_TRUE(same(read_image_native(file), small)) << png_level_name(level) << " " << size;
        }
      }
      // OpenImageIO's written, we read.
      const auto theirs = tmp / ("theirs" + std::to_string(seed) + ".png");
      write_image(theirs, m);
      EXPECT_TRUE(same(read_image_native(theirs), m)) << "we read OpenImageIO's PNG differently";
    }
  }
}

TEST(PngFile, SixteenBitsRoundToEightWhenConverted) {
  testsupport::TempDir tmp("raindrop-png-");
  cv::Mat m(16, 16, CV_16UC3);
  for (int i = 0; i < 16 * 16 * 3; ++i) reinterpret_cast<std::uint16_t*>(m.data)[i] = static_cast<std::uint16_t>(i * 85);
  write_image_atomic(m, tmp / "a.png");
  const cv::Mat rgb = read_rgb8(tmp / "a.png", true);
  for (int i = 0; i < 16 * 16 * 3; ++i) {
    const int v = i * 85;
    ASSERT_EQ(rgb.data[i], (v * 255 + 32767) / 65535) << i;  // round(v * 255 / 65535)
  }
}

// Palettes, 1-4-bit grey and tRNS transparency are decoded by OpenImageIO's plugin: the same
// channels and values as OpenImageIO itself gives, through both readers the programs use.
TEST(PngFile, PalettesLowDepthsAndTransparencyReadAsOpenImageIOReadsThem) {
  testsupport::TempDir tmp("raindrop-png-");
  struct Case {
    const char* name;
    int depth, colour_type;
    bool trns, interlace;
    int samples;  // per pixel, as stored
  };
  const Case cases[] = {{"palette4", 4, PNG_COLOR_TYPE_PALETTE, false, false, 1},
                        {"palette4_trns", 4, PNG_COLOR_TYPE_PALETTE, true, false, 1},
                        {"grey1", 1, PNG_COLOR_TYPE_GRAY, false, false, 1},
                        {"grey2_interlaced", 2, PNG_COLOR_TYPE_GRAY, false, true, 1},
                        {"grey8_trns", 8, PNG_COLOR_TYPE_GRAY, true, false, 1},
                        {"rgb8_trns", 8, PNG_COLOR_TYPE_RGB, true, false, 3},
                        {"rgb16_interlaced", 16, PNG_COLOR_TYPE_RGB, false, true, 3}};
  const int w = 19, h = 11;
  std::mt19937 rng(7);
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const size_t row_bytes = (static_cast<size_t>(w) * c.samples * c.depth + 7) / 8;
    std::vector<png_byte> data(row_bytes * h);
    for (auto& b : data) b = static_cast<png_byte>(rng());
    // (4-bit palette indices: every nibble is within the 16-entry palette.)
    const auto file = tmp / (std::string(c.name) + ".png");
    write_png_raw(file, w, h, c.depth, c.colour_type, c.trns, c.interlace, data);
    std::string why;
    const auto reference = read_image(file, &why);
    ASSERT_TRUE(reference) << why;
    const cv::Mat ours = read_image_native(file);
    EXPECT_TRUE(same(ours, reference->pixels)) << "channels " << ours.channels() << " vs " << reference->channels;
    // The header-only check agrees with the decode on what the file holds.
    if (reference->channels == 3 && reference->format == OIIO::TypeDesc::UINT8) {
      EXPECT_NO_THROW(check_rgb8_header(file, false, 1));
    }
  }
}

// Every compression setting decodes to the same pixels; each one reaches the encoder (the files differ).
TEST(PngFile, CompressionSettingsChangeBytesNotPixels) {
  testsupport::TempDir tmp("raindrop-png-");
  cv::Mat m(128, 256, CV_8UC3);  // smooth gradients with a little texture: compressible
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x) m.at<cv::Vec3b>(y, x) = cv::Vec3b(x, y * 2, ((x * 7) ^ (y * 3)) & 15);
  const cv::Mat m16 = random_image(40, 30, CV_16U, 4, 3);
  std::set<std::string> contents;
  for (int level : {kPngFast, kPngRunLength, 1, 9}) {
    SCOPED_TRACE(png_level_name(level));
    write_image_atomic(m, tmp / "a.png", level);
    write_image_atomic(m16, tmp / "b.png", level);
    EXPECT_TRUE(same(read_image_native(tmp / "a.png"), m));
    EXPECT_TRUE(same(read_image_native(tmp / "b.png"), m16));
    contents.insert(testsupport::read_file(tmp / "a.png"));
  }
  EXPECT_EQ(contents.size(), 4u) << "two settings wrote the same file";
  EXPECT_EQ(kDefaultPngLevel, kPngFast);
}

// The fast writer's file, chunk by chunk: the signature, IHDR with the image's size, depth and
// colour type, IDAT chunks of at most 1 MiB whose zlib stream inflates to one Paeth filter byte
// (4) and the row's residuals per row, IEND, every CRC valid.
TEST(PngFile, TheFastWriterWritesPaethRowsInValidChunks) {
  testsupport::TempDir tmp("raindrop-png-");
  const cv::Mat m = random_image(700, 600, CV_8U, 3, 11);  // 1.26 MB incompressible: two IDAT chunks
  write_image_atomic(m, tmp / "f.png", kPngFast);
  const std::string bytes = testsupport::read_file(tmp / "f.png");
  ASSERT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  auto be32 = [&](std::size_t at) {
    return static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at])) << 24 |
           static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 1])) << 16 |
           static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 2])) << 8 |
           static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 3]));
  };
  std::vector<std::string> types;
  std::string idat;
  std::size_t at = 8;
  while (at < bytes.size()) {
    const std::uint32_t length = be32(at);
    const std::string type = bytes.substr(at + 4, 4);
    types.push_back(type);
    const auto* p = reinterpret_cast<const Bytef*>(bytes.data() + at + 4);
    EXPECT_EQ(crc32(0, p, length + 4), be32(at + 8 + length)) << type;
    if (type == "IHDR") {
      EXPECT_EQ(be32(at + 8), 600u);
      EXPECT_EQ(be32(at + 12), 700u);
      EXPECT_EQ(bytes[at + 16], 8);  // bits per sample
      EXPECT_EQ(bytes[at + 17], 2);  // RGB
    }
    if (type == "IDAT") {
      EXPECT_LE(length, 1u << 20);
      idat += bytes.substr(at + 8, length);
    }
    at += 12 + length;
  }
  EXPECT_EQ(at, bytes.size());
  EXPECT_EQ(types, (std::vector<std::string>{"IHDR", "IDAT", "IDAT", "IEND"}));
  std::vector<unsigned char> raw((600 * 3 + 1) * 700 + 1);
  uLongf raw_size = raw.size();
  ASSERT_EQ(uncompress(raw.data(), &raw_size, reinterpret_cast<const Bytef*>(idat.data()), idat.size()), Z_OK);
  ASSERT_EQ(raw_size, (600u * 3 + 1) * 700);
  for (int y = 0; y < 700; ++y) ASSERT_EQ(raw[y * (600 * 3 + 1)], 4) << "row " << y;
}

TEST(PngFile, LevelNamesParse) {
  EXPECT_EQ(parse_png_level("fast"), kPngFast);
  EXPECT_EQ(png_level_name(kPngFast), "fast");
  EXPECT_EQ(parse_png_level("rle"), kPngRunLength);
  EXPECT_EQ(parse_png_level("0"), 0);
  EXPECT_EQ(parse_png_level("9"), 9);
  for (const char* bad : {"", "10", "-1", "RLE", "3 "}) EXPECT_THROW(parse_png_level(bad), Error) << bad;
  EXPECT_EQ(png_level_name(parse_png_level("rle")), "rle");
  EXPECT_EQ(png_level_name(4), "4");
}

// A write that the file system refuses part-way (here: a file size limit, as a full disk does
// with ENOSPC) names the cause, for PNG and JPEG alike, and leaves no file behind.
TEST(PngFile, AFailedWriteSaysWhy) {
  testsupport::TempDir tmp("raindrop-png-");
  const cv::Mat m = random_image(300, 400, CV_8U, 3, 5);  // incompressible: far over the limit
  for (const char* name : {"big.png", "big.jpg"}) {
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      std::signal(SIGXFSZ, SIG_IGN);  // the write fails with EFBIG instead of killing the process
      const rlimit limit{20000, 20000};
      ::setrlimit(RLIMIT_FSIZE, &limit);
      int code = 1;
      try {
        write_image_atomic(m, tmp / name);
      } catch (const Error& e) {
        const std::string what = e.what();
        code = what.find(std::strerror(EFBIG)) != std::string::npos && what.find(name) != std::string::npos ? 0 : 2;
        if (code) std::fprintf(stderr, "%s\n", e.what());
      }
      std::_Exit(code);
    }
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0) << name << ": 1 = written despite the limit, 2 = the error does not say why";
    std::size_t left = 0;
    for (const auto& e : fs::directory_iterator(tmp.path())) left += e.path().filename() != "." ? 1 : 0;
    EXPECT_EQ(left, 0u) << name << ": a file was left behind";
  }
}

namespace {

struct Chunk {
  std::string type, data;
};

std::vector<Chunk> chunks_of(const std::string& file) {
  std::vector<Chunk> chunks;
  for (auto& [type, data] : testsupport::png_chunks(file)) chunks.push_back({type, data});
  return chunks;
}

// The file again, every CRC correct: only the structure is wrong.
std::string file_of(const std::vector<Chunk>& chunks) {
  std::vector<std::pair<std::string, std::string>> pairs;
  for (const Chunk& c : chunks) pairs.emplace_back(c.type, c.data);
  return testsupport::png_from_chunks(pairs);
}

}  // namespace

// Intact chunks in an order or number libpng refuses: refused before libpng sees them (through
// OpenImageIO, for a palette image, libpng printed "libpng error: ..." on its own), in one line.
TEST(PngFile, MisplacedChunksFailInOneLine) {
  testsupport::TempDir tmp("raindrop-png-");
  // libpng's writer (rle) splits the data into 8 KiB chunks; incompressible: several IDATs
  write_image_atomic(random_image(90, 90, CV_8U, 3, 8), tmp / "rgb.png", kPngRunLength);
  std::vector<png_byte> indices(300 * 150);  // 4-bit, random: incompressible too
  std::mt19937 rng(3);
  for (auto& b : indices) b = static_cast<png_byte>(rng());
  write_png_raw(tmp / "palette.png", 300, 300, 4, PNG_COLOR_TYPE_PALETTE, false, false, indices);
  for (const std::string base : {"rgb.png", "palette.png"}) {
    const std::vector<Chunk> good = chunks_of(testsupport::read_file(tmp / base));
    ASSERT_NO_THROW(read_image_native(tmp / base)) << base;
    size_t first_idat = 0, idats = 0;
    for (size_t i = 0; i < good.size(); ++i) {
      if (good[i].type == "IDAT" && idats++ == 0) first_idat = i;
    }
    ASSERT_GE(idats, 2u) << base << ": the test needs the image data in several chunks";
    std::vector<std::pair<std::string, std::vector<Chunk>>> cases;
    auto with = [&](const std::string& why, size_t at, const Chunk& extra, int copies = 1) {
      std::vector<Chunk> c = good;
      c.insert(c.begin() + static_cast<std::ptrdiff_t>(at), static_cast<size_t>(copies), extra);
      cases.emplace_back(why, c);
    };
    with("image data split", first_idat + 1, {"tEXt", std::string("Comment\0split", 13)});
    with("second IHDR", 1, good[0]);
    with("palette of 5 bytes", first_idat, {"PLTE", "12345"});
    with("palette of 300 entries", first_idat, {"PLTE", std::string(900, 'x')});
    with("two more palettes", first_idat, {"PLTE", "abc"}, 2);
    for (const auto& [why, c] : cases) {
      SCOPED_TRACE(base + ": " + why);
      std::ofstream(tmp / "bad.png", std::ios::binary | std::ios::trunc) << file_of(c);
      testing::internal::CaptureStderr();
      const std::string error = read_error(tmp / "bad.png");
      EXPECT_NE(error.find("corrupt PNG"), std::string::npos) << error;
      EXPECT_THROW(check_rgb8_header(tmp / "bad.png", true, 1), Error);
      EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
    }
  }
}

// Image data that holds every row but whose compressed stream never ends (its Adler-32 cut by
// 1-5 bytes, or a flushed deflate stream never finished): libpng reads on after the last row
// and fails with "Not enough image data", which OpenImageIO's libpng printed on its own line
// before ours (palette and low-depth files go through it; a fuzzer found it). Refused by the
// header check now, in one line; the same data complete decodes, in both paths.
TEST(PngFile, AnUnfinishedImageDataStreamFailsInOneLine) {
  testsupport::TempDir tmp("raindrop-png-");
  const int w = 37, h = 29;
  std::mt19937 rng(11);
  std::string palette_rows, rgb_rows;
  for (int y = 0; y < h; ++y) {
    palette_rows += '\0';
    rgb_rows += '\0';
    for (int x = 0; x < w; ++x) palette_rows += static_cast<char>(rng() % 4);
    for (int i = 0; i < 3 * w; ++i) rgb_rows += static_cast<char>(rng());
  }
  const std::string palette = std::string("\x10\x20\x30\x80\x90\xa0\xff\x00\x00\x00\xff\x00", 12);
  auto deflate = [](const std::string& raw, bool finish) {
    z_stream z{};
    EXPECT_EQ(deflateInit(&z, 6), Z_OK);
    std::string out(compressBound(static_cast<uLong>(raw.size())) + 64, '\0');
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(raw.data()));
    z.avail_in = static_cast<uInt>(raw.size());
    z.next_out = reinterpret_cast<Bytef*>(out.data());
    z.avail_out = static_cast<uInt>(out.size());
    EXPECT_EQ(::deflate(&z, finish ? Z_FINISH : Z_FULL_FLUSH), finish ? Z_STREAM_END : Z_OK);
    out.resize(out.size() - z.avail_out);
    deflateEnd(&z);
    return out;
  };
  for (const bool is_palette : {true, false}) {
    const std::string ihdr = testsupport::be32(w) + testsupport::be32(h) +
                             std::string{8, static_cast<char>(is_palette ? 3 : 2), 0, 0, 0};
    const std::string& rows = is_palette ? palette_rows : rgb_rows;
    auto file = [&](const std::string& idat) {
      std::vector<std::pair<std::string, std::string>> chunks = {{"IHDR", ihdr}};
      if (is_palette) chunks.push_back({"PLTE", palette});
      chunks.push_back({"IDAT", idat});
      chunks.push_back({"IEND", ""});
      return testsupport::png_from_chunks(chunks);
    };
    const std::string whole = deflate(rows, true);
    std::ofstream(tmp / "whole.png", std::ios::binary | std::ios::trunc) << file(whole);
    EXPECT_NO_THROW(read_image_native(tmp / "whole.png")) << (is_palette ? "palette" : "RGB");
    std::vector<std::pair<std::string, std::string>> cases;
    for (int cut = 1; cut <= 5; ++cut) cases.emplace_back("cut by " + std::to_string(cut), whole.substr(0, whole.size() - cut));
    cases.emplace_back("flushed, never finished", deflate(rows, false));
    for (const auto& [why, idat] : cases) {
      SCOPED_TRACE(std::string(is_palette ? "palette, " : "RGB, ") + why);
      std::ofstream(tmp / "bad.png", std::ios::binary | std::ios::trunc) << file(idat);
      testing::internal::CaptureStderr();
      const std::string error = read_error(tmp / "bad.png");
      EXPECT_NE(error.find("truncated PNG"), std::string::npos) << error;
      EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
    }
  }
}

// Our own decoding path (libdeflate and our unfiltering, png_file.h: decode_image_data) on
// files libpng wrote with each of the five row filters forced, at every native depth and
// channel count (1-8 bytes per pixel), on smooth and random content, at widths that leave a
// partial last pixel run: the same pixels as written, through decode_image_data itself (so
// that a fault there is not hidden by the fallback to libpng) and through read_image_native.
TEST(PngFile, OurDecoderUndoesEveryRowFilter) {
  testsupport::TempDir tmp("raindrop-png-");
  const int filters[] = {PNG_FILTER_NONE, PNG_FILTER_SUB, PNG_FILTER_UP, PNG_FILTER_AVG, PNG_FILTER_PAETH};
  int seed = 40;
  for (int depth : {CV_8U, CV_16U}) {
    for (int channels = 1; channels <= 4; ++channels) {
      cv::Mat m = random_image(23, 31, depth, channels, seed++);
      cv::Mat smooth(m.size(), m.type());
      for (int y = 0; y < m.rows; ++y)
        for (int x = 0; x < m.cols * channels; ++x) {
          if (depth == CV_8U) smooth.ptr<uchar>(y)[x] = static_cast<uchar>(3 * x + 5 * y);
          else smooth.ptr<std::uint16_t>(y)[x] = static_cast<std::uint16_t>(700 * x + 1300 * y);
        }
      for (const cv::Mat& image : {m, smooth}) {
        for (int filter : filters) {
          SCOPED_TRACE("depth " + std::to_string(depth) + ", channels " + std::to_string(channels) + ", filter " +
                       std::to_string(filter));
          const auto file = tmp / "f.png";
          std::vector<png_byte> bytes;  // as PNG stores them: 16-bit samples big-endian
          for (int y = 0; y < image.rows; ++y) {
            const uchar* row = image.ptr(y);
            for (size_t i = 0; i < image.cols * image.elemSize(); i += image.elemSize1()) {
              if (depth == CV_16U) {
                const std::uint16_t v = *reinterpret_cast<const std::uint16_t*>(row + i);
                bytes.push_back(static_cast<png_byte>(v >> 8));
                bytes.push_back(static_cast<png_byte>(v & 0xff));
              } else {
                bytes.push_back(row[i]);
              }
            }
          }
          const int colour[] = {PNG_COLOR_TYPE_GRAY, PNG_COLOR_TYPE_GRAY_ALPHA, PNG_COLOR_TYPE_RGB, PNG_COLOR_TYPE_RGBA};
          write_png_raw(file, image.cols, image.rows, depth == CV_16U ? 16 : 8, colour[channels - 1], false, false, bytes,
                        filter);
          const png::Info header = png::check(file, fs::file_size(file), true);
          ASSERT_FALSE(header.image_data.empty());
          const std::optional<cv::Mat> ours = png::decode_image_data(header);
          ASSERT_TRUE(ours.has_value());
          EXPECT_TRUE(same(*ours, image));
          EXPECT_TRUE(same(read_image_native(file), image));
        }
      }
    }
  }
}

// Image data that our decoder refuses although every chunk is intact (CRCs valid): a zlib
// stream cut short, a wrong Adler-32 checksum, a row filter byte past 4, data for one row too
// few. decode_image_data gives up (nullopt) and the file goes to libpng, whose verdict is one
// line of ours with nothing printed; a stream with a row too many is inflated by libpng, which
// ignores the excess, as before.
TEST(PngFile, DataOurDecoderRefusesGoesToLibpng) {
  testsupport::TempDir tmp("raindrop-png-");
  const int w = 20, h = 6;
  auto zlib_of = [](const std::string& raw) {
    std::vector<Bytef> out(compressBound(raw.size()));
    uLongf size = out.size();
    EXPECT_EQ(compress(out.data(), &size, reinterpret_cast<const Bytef*>(raw.data()), raw.size()), Z_OK);
    return std::string(reinterpret_cast<const char*>(out.data()), size);
  };
  std::string rows;  // RGB, filter type 0
  for (int y = 0; y < h; ++y) {
    rows += '\0';
    for (int x = 0; x < 3 * w; ++x) rows += static_cast<char>(x * 7 + y);
  }
  write_image_atomic(cv::Mat(h, w, CV_8UC3, cv::Scalar(1, 2, 3)), tmp / "good.png", kPngFast);
  const std::vector<Chunk> good = chunks_of(testsupport::read_file(tmp / "good.png"));
  ASSERT_EQ(good.front().type, "IHDR");
  auto with_data = [&](const std::string& idat) {
    return file_of({good.front(), {"IDAT", idat}, {"IEND", ""}});
  };
  std::string bad_filter = rows;
  bad_filter[(3 * w + 1) * 2] = 7;
  std::string bad_adler = zlib_of(rows);
  bad_adler.back() = static_cast<char>(bad_adler.back() ^ 1);
  const std::pair<const char*, std::string> refused[] = {
      {"cut stream", zlib_of(rows).substr(0, zlib_of(rows).size() / 2)},
      {"wrong Adler-32", bad_adler},
      {"filter byte 7", zlib_of(bad_filter)},
      {"a row too few", zlib_of(rows.substr(0, (3 * w + 1) * (h - 1)))},
  };
  for (const auto& [why, idat] : refused) {
    SCOPED_TRACE(why);
    std::ofstream(tmp / "bad.png", std::ios::binary | std::ios::trunc) << with_data(idat);
    const png::Info header = png::check(tmp / "bad.png", fs::file_size(tmp / "bad.png"), true);
    EXPECT_FALSE(png::decode_image_data(header).has_value());
    testing::internal::CaptureStderr();
    const std::string error = read_error(tmp / "bad.png");  // "decoded" names no file: fails below
    EXPECT_EQ(error.find('\n'), std::string::npos) << error;
    EXPECT_NE(error.find("bad.png"), std::string::npos) << error;
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  }
  // One row too many: ours refuses it (the stream does not fit the declared rows), libpng
  // decodes the declared rows.
  std::string extra = rows;
  extra += rows.substr(0, 3 * w + 1);
  std::ofstream(tmp / "long.png", std::ios::binary | std::ios::trunc) << with_data(zlib_of(extra));
  const png::Info header = png::check(tmp / "long.png", fs::file_size(tmp / "long.png"), true);
  EXPECT_FALSE(png::decode_image_data(header).has_value());
  const cv::Mat read = read_image_native(tmp / "long.png");
  ASSERT_EQ(read.size(), cv::Size(w, h));
  EXPECT_EQ(read.at<cv::Vec3b>(5, 3), cv::Vec3b(9 * 7 + 5, 10 * 7 + 5, 11 * 7 + 5));  // byte i of row y: 7 i + y
}

namespace {

// PNG's row filter `type` of one row (bpp bytes per pixel) against the row above, as an encoder
// applies it.
std::vector<png_byte> filter_row(const png_byte* row, const png_byte* above, size_t bytes, size_t bpp, int type) {
  std::vector<png_byte> out(bytes);
  for (size_t i = 0; i < bytes; ++i) {
    const int a = i >= bpp ? row[i - bpp] : 0, b = above[i], c = i >= bpp ? above[i - bpp] : 0;
    int predictor = 0;
    if (type == 1) predictor = a;
    if (type == 2) predictor = b;
    if (type == 3) predictor = (a + b) / 2;
    if (type == 4) {
      const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
      predictor = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
    }
    out[i] = static_cast<png_byte>(row[i] - predictor);
  }
  return out;
}

}  // namespace

// Runs of Paeth rows of 8-bit RGB and RGBA are undone four rows at a time where the processor has
// AVX2 and eight where it has AVX-512 (png_unfilter.cpp, unpaeth_band4_avx2, unpaeth_band8_avx512):
// on images whose rows take random filter types (mostly Paeth: runs of every length, broken by
// the others) at widths below and from the bands' least (4 and 8 pixels) up, and on all-Paeth
// images whose heights leave every remainder of four and eight, the pixels are those written, at
// every level this processor has and row by row.
TEST(PngFile, PaethBandsGiveTheRowByRowPixels) {
  const int widest = png::limit_paeth_bands(2);
  testsupport::TempDir tmp("raindrop-png-");
  std::mt19937 rng(77);
  int cases = 0;
  for (int channels : {3, 4}) {
    for (int width : {1, 3, 4, 5, 7, 8, 9, 16, 33, 100}) {
      for (int height : {1, 3, 4, 5, 8, 9, 15, 16, 23}) {
        for (bool all_paeth : {true, false}) {
          // Smooth with noise: the Paeth predictor picks each of a, b and c somewhere.
          cv::Mat image(height, width, CV_8UC(channels));
          for (int y = 0; y < height; ++y)
            for (int i = 0; i < width * channels; ++i)
              image.ptr<uchar>(y)[i] = static_cast<uchar>(3 * i + 7 * y + static_cast<int>(rng() % 40));
          const size_t bytes = static_cast<size_t>(width) * channels;
          std::string raw;
          std::vector<png_byte> zero(bytes, 0);
          for (int y = 0; y < height; ++y) {
            const int type = all_paeth || rng() % 3 != 0 ? 4 : static_cast<int>(rng() % 4);
            const auto filtered = filter_row(image.ptr<uchar>(y), y ? image.ptr<uchar>(y - 1) : zero.data(), bytes,
                                             static_cast<size_t>(channels), type);
            raw += static_cast<char>(type);
            raw.append(reinterpret_cast<const char*>(filtered.data()), filtered.size());
          }
          uLongf deflated_size = compressBound(static_cast<uLong>(raw.size()));
          std::string deflated(deflated_size, '\0');
          ASSERT_EQ(compress2(reinterpret_cast<Bytef*>(deflated.data()), &deflated_size,
                              reinterpret_cast<const Bytef*>(raw.data()), static_cast<uLong>(raw.size()), 6),
                    Z_OK);
          deflated.resize(deflated_size);
          const std::string ihdr = testsupport::be32(static_cast<std::uint32_t>(width)) +
                                   testsupport::be32(static_cast<std::uint32_t>(height)) +
                                   std::string{8, static_cast<char>(channels == 3 ? 2 : 6), 0, 0, 0};
          const auto file = tmp / "bands.png";
          {
            std::ofstream out(file, std::ios::binary);
            out << testsupport::png_from_chunks({{"IHDR", ihdr}, {"IDAT", deflated}, {"IEND", ""}});
          }
          SCOPED_TRACE(std::to_string(channels) + " channels, " + std::to_string(width) + "x" + std::to_string(height) +
                       (all_paeth ? ", all Paeth" : ", mixed filters"));
          const png::Info header = png::check(file, fs::file_size(file), true);
          for (int level = 0; level <= widest; ++level) {
            png::limit_paeth_bands(level);
            const std::optional<cv::Mat> ours = png::decode_image_data(header);
            ASSERT_TRUE(ours.has_value());
            EXPECT_TRUE(same(*ours, image)) << (level == 0 ? "row by row" : level == 1 ? "four-row bands" : "eight-row bands");
          }
          png::limit_paeth_bands(2);
          ++cases;
        }
      }
    }
  }
  EXPECT_EQ(cases, 2 * 10 * 9 * 2);
  // Not a skip: what this processor runs was checked. Said, so that a log shows which bands ran.
  if (widest < 2)
    std::cout << "note: this processor has no " << (widest == 0 ? "AVX2 or " : "") << "AVX-512: "
              << (widest == 0 ? "the row-by-row path was" : "four-row bands and rows were") << " checked\n";
}

// An iCCP chunk's profile is inflated only up to the limit it is asked for: one byte over it is
// no profile (and the rest of a zip bomb is never inflated), the limit itself is the profile.
TEST(PngFile, AnIccProfileIsInflatedOnlyUpToTheLimit) {
  namespace png = raindrop::png;
  const std::string profile(300000, 'p');  // compresses to a few hundred bytes
  std::string stream(compressBound(profile.size()), '\0');
  uLongf n = stream.size();
  ASSERT_EQ(compress2(reinterpret_cast<Bytef*>(stream.data()), &n, reinterpret_cast<const Bytef*>(profile.data()),
                      profile.size(), 9),
            Z_OK);
  stream.resize(n);
  png::Info info;
  info.iccp = std::string("icc") + '\0' + '\0' + stream;  // name, its zero, method 0 (zlib), the stream
  EXPECT_EQ(png::icc_profile(info, profile.size()), profile);
  EXPECT_EQ(png::icc_profile(info, profile.size() - 1), "");
  EXPECT_EQ(png::icc_profile(info, 1 << 20), profile);
}

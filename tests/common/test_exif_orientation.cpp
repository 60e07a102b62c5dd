// EXIF Orientation (src/common/exif_orientation.cpp): the tag read from its bytes in both byte
// orders, nothing found in anything malformed (the file is then read as stored), and JPEG files
// read upright, as OpenCV's imread (and so the Python tools) and image viewers show them.
#include <gtest/gtest.h>

#include <cstdint>
#include <csetjmp>
#include <cstdio>
#include <fstream>

#include <OpenImageIO/imageio.h>
#include <png.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "exif_orientation.h"
#include "raindrop/common/image_io.h"
#include "test_images.h"
#include "test_support.h"

using namespace raindrop;
namespace fs = std::filesystem;

namespace {

struct Entry {
  std::uint16_t tag, type;
  std::uint32_t count, value;
};

// An APP1 payload: "Exif\0\0", a TIFF header in the given byte order, one IFD holding `entries`.
std::vector<unsigned char> exif_payload(bool little, const std::vector<Entry>& entries) {
  std::vector<unsigned char> b = {'E', 'x', 'i', 'f', 0, 0};
  auto put16 = [&](std::uint32_t v) {
    const unsigned char lo = v & 255, hi = (v >> 8) & 255;
    b.push_back(little ? lo : hi);
    b.push_back(little ? hi : lo);
  };
  auto put32 = [&](std::uint32_t v) {
    put16(little ? v & 0xFFFF : v >> 16);
    put16(little ? v >> 16 : v & 0xFFFF);
  };
  b.push_back(little ? 'I' : 'M');
  b.push_back(little ? 'I' : 'M');
  put16(42);
  put32(8);  // the first IFD right after the header
  put16(static_cast<std::uint32_t>(entries.size()));
  for (const Entry& e : entries) {
    put16(e.tag);
    put16(e.type);
    put32(e.count);
    if (e.type == 3) {  // a SHORT sits in the first two bytes of the value field
      put16(e.value);
      put16(0);
    } else {
      put32(e.value);
    }
  }
  put32(0);  // no next IFD
  return b;
}

constexpr Entry kMake{0x010F, 2, 4, 0};  // another tag before the orientation

int read(const std::vector<unsigned char>& b) { return exif::orientation(b.data(), b.size()); }

// `jpeg` with an APP1 segment holding `payload` inserted after its start-of-image marker.
std::string with_app1(const std::string& jpeg, const std::vector<unsigned char>& payload) {
  const size_t length = payload.size() + 2;
  std::string segment = {'\xFF', '\xE1', static_cast<char>(length >> 8), static_cast<char>(length & 255)};
  segment.append(payload.begin(), payload.end());
  return jpeg.substr(0, 2) + segment + jpeg.substr(2);
}

}  // namespace

TEST(ExifOrientation, ReadsTheTagInBothByteOrders) {
  for (bool little : {true, false}) {
    for (std::uint32_t o = 1; o <= 8; ++o) {
      EXPECT_EQ(read(exif_payload(little, {kMake, {0x0112, 3, 1, o}})), static_cast<int>(o))
          << (little ? "II" : "MM") << " orientation " << o;
      // As OpenCV and PIL read it: a LONG too, and the count not checked.
      EXPECT_EQ(read(exif_payload(little, {{0x0112, 4, 1, o}})), static_cast<int>(o)) << "a LONG";
      EXPECT_EQ(read(exif_payload(little, {{0x0112, 3, 0, o}})), static_cast<int>(o)) << "count 0";
      EXPECT_EQ(read(exif_payload(little, {{0x0112, 3, 2, o}})), static_cast<int>(o)) << "count 2";
    }
  }
}

TEST(ExifOrientation, NothingIsFoundInAnythingMalformedOrMissing) {
  const auto good = exif_payload(true, {kMake, {0x0112, 3, 1, 6}});
  ASSERT_EQ(read(good), 6);
  EXPECT_EQ(read(exif_payload(true, {kMake})), 0) << "no orientation tag";
  EXPECT_EQ(read(exif_payload(false, {{0x0112, 3, 1, 0}})), 0) << "value 0";
  EXPECT_EQ(read(exif_payload(false, {{0x0112, 3, 1, 9}})), 0) << "value 9";
  EXPECT_EQ(read(exif_payload(true, {{0x0112, 2, 1, 6}})), 0) << "ASCII, neither SHORT nor LONG";
  auto bad_magic = good;
  bad_magic[8] = 43;
  EXPECT_EQ(read(bad_magic), 0);
  auto not_exif = good;
  not_exif[0] = 'X';
  EXPECT_EQ(read(not_exif), 0);
  auto far_ifd = good;
  far_ifd[10] = 0xFF, far_ifd[11] = 0xFF;  // the IFD offset points past the end
  EXPECT_EQ(read(far_ifd), 0);
  // Cut anywhere before the orientation entry ends: as stored, and nothing read past the cut
  // (each cut is its own allocation, so a read past it is a heap overflow for the sanitizers).
  const size_t entry_end = 6 + 8 + 2 + 2 * 12;
  for (size_t n = 0; n < entry_end; ++n) {
    const std::vector<unsigned char> cut(good.begin(), good.begin() + n);
    EXPECT_EQ(exif::orientation(cut.empty() ? nullptr : cut.data(), n), 0) << "cut at " << n;
  }
  EXPECT_EQ(read(std::vector<unsigned char>(good.begin(), good.begin() + entry_end)), 6);
}

// A JPEG whose EXIF says how to show it reads as it is shown: exactly our decoder's stored
// pixels turned and mirrored, and the same picture OpenCV's imread gives (the reference: it
// applies the tag); 5-8 swap the sides, in the header too.
TEST(ExifOrientation, JpegFilesReadUprightAsOpenCvReadsThem) {
  testsupport::TempDir tmp("raindrop-exif-");
  const cv::Mat rgb = testsupport::street_like(23, 37, 3);  // no symmetry: every turn shows
  ASSERT_EQ(write_image_atomic(rgb, tmp / "plain.jpg"), "");
  const cv::Mat stored = read_image_native(tmp / "plain.jpg");
  const std::string plain = testsupport::read_file(tmp / "plain.jpg");
  for (bool little : {true, false}) {
    for (std::uint32_t o = 1; o <= 8; ++o) {
      SCOPED_TRACE(std::string(little ? "II" : "MM") + " orientation " + std::to_string(o));
      const fs::path file = tmp / ("o" + std::to_string(o) + ".jpg");
      std::ofstream(file, std::ios::binary) << with_app1(plain, exif_payload(little, {kMake, {0x0112, 3, 1, o}}));
      const cv::Mat ours = read_image_native(file);
      cv::Mat expected = stored.clone();
      exif::make_upright(expected, static_cast<int>(o));
      ASSERT_EQ(ours.size(), expected.size());
      EXPECT_EQ(cv::norm(ours, expected, cv::NORM_INF), 0);
      cv::Mat theirs = cv::imread(file.string(), cv::IMREAD_COLOR);
      ASSERT_FALSE(theirs.empty());
      cv::cvtColor(theirs, theirs, cv::COLOR_BGR2RGB);
      ASSERT_EQ(ours.size(), theirs.size());
      // The same decoder library: equal but for rounding, where a wrong turn differs by tens of levels.
      EXPECT_LE(cv::norm(ours, theirs, cv::NORM_INF), 2);
      const ImageHeader h = read_header(file);
      EXPECT_EQ(h.width, ours.cols);
      EXPECT_EQ(h.height, ours.rows);
      EXPECT_EQ(h.width, exif::swaps_sides(static_cast<int>(o)) ? 23 : 37);
    }
  }
}

// Other formats, through OpenImageIO's plugin, follow the same tag (a TIFF's own Orientation
// here): read as shown, header included.
TEST(ExifOrientation, TiffFilesReadUprightToo) {
  testsupport::TempDir tmp("raindrop-exif-");
  const cv::Mat rgb = testsupport::street_like(23, 37, 3);
  auto out = OIIO::ImageOutput::create("side.tif");
  ASSERT_TRUE(out);
  OIIO::ImageSpec spec(rgb.cols, rgb.rows, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("Orientation", 6);
  const std::string file = (tmp / "side.tif").string();
  ASSERT_TRUE(out->open(file, spec) && out->write_image(OIIO::TypeDesc::UINT8, rgb.data) && out->close());
  const cv::Mat ours = read_image_native(file);
  cv::Mat expected;
  cv::rotate(rgb, expected, cv::ROTATE_90_CLOCKWISE);  // 6: turn a quarter clockwise to show
  ASSERT_EQ(ours.size(), expected.size());
  EXPECT_EQ(cv::norm(ours, expected, cv::NORM_INF), 0);
  const ImageHeader h = read_header(file);
  EXPECT_EQ(h.width, 23);
  EXPECT_EQ(h.height, 37);
}

// Other APP1 markers before the EXIF one (XMP), and an EXIF marker without the tag before one
// with it: the tag is found where it is.
TEST(ExifOrientation, TheTagIsFoundPastOtherApp1Markers) {
  testsupport::TempDir tmp("raindrop-exif-");
  const cv::Mat rgb = testsupport::street_like(23, 37, 3);
  ASSERT_EQ(write_image_atomic(rgb, tmp / "plain.jpg"), "");
  const std::string plain = testsupport::read_file(tmp / "plain.jpg");
  const std::string xmp = "http://ns.adobe.com/xap/1.0/";
  std::vector<unsigned char> xmp_payload(xmp.begin(), xmp.end());
  xmp_payload.push_back(0);
  const auto tagged = exif_payload(false, {kMake, {0x0112, 3, 1, 6}});
  for (const auto& first : {xmp_payload, exif_payload(true, {kMake})}) {
    // with_app1 inserts after the start-of-image marker: the second call's segment comes first.
    std::ofstream(tmp / "two.jpg", std::ios::binary) << with_app1(with_app1(plain, tagged), first);
    const cv::Mat ours = read_image_native(tmp / "two.jpg");
    EXPECT_EQ(ours.cols, 23);
    EXPECT_EQ(ours.rows, 37);
  }
}

// A palette PNG (read through OpenImageIO, which reads an eXIf chunk) with `exif` (the TIFF
// data, without "Exif\0\0") as its eXIf chunk, written with libpng.
void write_palette_png(const fs::path& path, const cv::Mat& indices, const std::vector<unsigned char>& exif) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_TRUE(f);
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    std::fclose(f);
    FAIL() << "libpng failed";
  }
  png_init_io(png, f);
  png_set_IHDR(png, info, indices.cols, indices.rows, 8, PNG_COLOR_TYPE_PALETTE, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_color colours[4] = {{0, 0, 0}, {200, 30, 30}, {30, 200, 30}, {30, 30, 200}};
  png_set_PLTE(png, info, colours, 4);
  std::vector<unsigned char> data(exif);
  png_set_eXIf_1(png, info, static_cast<png_uint_32>(data.size()), data.data());
  png_write_info(png, info);
  for (int y = 0; y < indices.rows; ++y) png_write_row(png, const_cast<png_bytep>(indices.ptr(y)));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  std::fclose(f);
}

// A PNG is read as stored whichever reader takes it: an eXIf chunk in a palette PNG does not
// turn it, as it would not turn the same picture in RGB (read by libpng).
TEST(ExifOrientation, PngFilesAreReadAsStored) {
  testsupport::TempDir tmp("raindrop-exif-");
  cv::Mat indices(23, 37, CV_8UC1);
  for (int y = 0; y < indices.rows; ++y)
    for (int x = 0; x < indices.cols; ++x) indices.at<unsigned char>(y, x) = static_cast<unsigned char>((x + 3 * y) % 4);
  const auto payload = exif_payload(true, {kMake, {0x0112, 3, 1, 6}});
  write_palette_png(tmp / "p.png", indices, std::vector<unsigned char>(payload.begin() + 6, payload.end()));
  const ImageHeader h = read_header(tmp / "p.png");
  EXPECT_EQ(h.format, "png");
  const cv::Mat ours = read_image_native(tmp / "p.png");
  EXPECT_EQ(ours.cols, 37);
  EXPECT_EQ(ours.rows, 23);
  EXPECT_EQ(h.width, 37);
}

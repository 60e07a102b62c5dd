// Image input conversions that the CLI tests do not reach: float (linear) files.
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <random>
#include <fstream>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <tuple>
#include <unistd.h>

#include "raindrop/common/error.h"
#include "raindrop/common/image_io.h"
#include "test_images.h"
#include "test_support.h"

using namespace raindrop;
using testsupport::street_like;

TEST(ImageIo, FloatInputsAreSrgbEncodedWhenConverted) {
  const auto path = std::filesystem::temp_directory_path() / ("raindrop_linear_" + std::to_string(::getpid()) + ".exr");
  const float pixels[4 * 3] = {0.0f, 0.5f, 1.0f, 0.0031308f, 2.0f, -1.0f, 0.2140f, 0.2140f, 0.2140f, 1e9f, 0.0f, 0.5f};
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out);
  OIIO::ImageSpec spec(2, 2, 3, OIIO::TypeDesc::FLOAT);
  ASSERT_TRUE(out->open(path.string(), spec) && out->write_image(OIIO::TypeDesc::FLOAT, pixels) && out->close());
  EXPECT_THROW(read_rgb8(path, false, 1), Error);  // strict mode refuses float input
  const cv::Mat rgb = read_rgb8(path, true, 1);
  auto encode = [](double v) {
    v = std::min(std::max(v, 0.0), 1.0);
    v = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
    return static_cast<int>(std::floor(v * 255 + 0.5));
  };
  for (int i = 0; i < 12; ++i) {
    EXPECT_NEAR(rgb.data[i], encode(pixels[i]), 1) << i;
  }
  EXPECT_EQ(rgb.at<cv::Vec3b>(0, 0)[1], 188);  // linear 0.5 is sRGB 0.7354
  EXPECT_EQ(rgb.at<cv::Vec3b>(1, 0)[0], 127);  // linear 0.214 is sRGB 0.4999 (127.47)
  std::filesystem::remove(path);
}

// Float formats (OpenEXR, Radiance HDR) hold linear light. The 8-bit sRGB-encoded values we
// write used to be stored as they were, so an EXR viewer showed them washed out and the
// renderer read them back brighter (0.5 stored was sRGB 0.735). Written decoded, every 8-bit
// value comes back as it was, and the file holds the linear value.
TEST(ImageIo, FloatFormatsAreWrittenInLinearLight) {
  const auto dir = std::filesystem::temp_directory_path() / ("raindrop_exr_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  cv::Mat ramp(16, 16, CV_8UC3);
  for (int i = 0; i < 256; ++i) ramp.at<cv::Vec3b>(i / 16, i % 16) = cv::Vec3b(i, 255 - i, (i * 7) % 256);
  for (const char* name : {"ramp.exr", "ramp.hdr"}) {
    SCOPED_TRACE(name);
    const auto path = dir / name;
    write_image_atomic(ramp, path);
    const cv::Mat back = read_rgb8(path, true, 1);
    ASSERT_EQ(back.size(), ramp.size());
    // Radiance HDR shares one exponent among three 8-bit mantissas: a dark channel beside a
    // bright one keeps only a few bits.
    const double tolerance = std::string(name) == "ramp.exr" ? 0 : 12;
    EXPECT_LE(cv::norm(back, ramp, cv::NORM_INF), tolerance);
    auto in = OIIO::ImageInput::open(path.string());
    ASSERT_TRUE(in);
    std::vector<float> stored(16 * 16 * 3);
    ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::FLOAT, stored.data()));
    const int i = 5 * 16 + 4;  // sRGB 84 = linear 0.0887
    EXPECT_NEAR(stored[3 * i], std::pow((84 / 255.0 + 0.055) / 1.055, 2.4), 2e-3);
    EXPECT_NEAR(stored[3 * 255 + 0], 1.0, 2e-3);
  }
  std::filesystem::remove_all(dir);
}

// WebP holds RGB and RGBA only: a grey image (a grey photograph's output) was refused after the
// removal had run. It is written as RGB (grey+alpha as RGBA), and the loss is said.
TEST(ImageIo, AFormatWithoutGreyTakesGreyAsRgb) {
  const auto dir = std::filesystem::temp_directory_path() / ("raindrop_webp_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  cv::Mat grey(24, 32, CV_8UC1);
  for (int y = 0; y < grey.rows; ++y)
    for (int x = 0; x < grey.cols; ++x) grey.at<uchar>(y, x) = static_cast<uchar>(40 + 4 * x + 2 * y);
  cv::Mat grey_alpha;
  cv::Mat alpha(grey.size(), CV_8UC1);
  for (int x = 0; x < grey.cols; ++x) alpha.col(x).setTo(128 + 3 * x);  // not opaque: WebP would drop it
  cv::merge(std::vector<cv::Mat>{grey, alpha}, grey_alpha);
  for (const auto& [image, channels, what] : {std::tuple{grey, 3, "RGB"}, std::tuple{grey_alpha, 4, "RGBA"}}) {
    SCOPED_TRACE(what);
    const auto path = dir / "g.webp";
    const std::string lost = write_image_atomic(image, path);
    EXPECT_NE(lost.find("holds no grey image: written as " + std::string(what)), std::string::npos) << lost;
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);  // the colour as stored, not times alpha
    auto in = OIIO::ImageInput::open(path.string(), &config);
    ASSERT_TRUE(in);
    EXPECT_EQ(in->spec().nchannels, channels);
    std::vector<std::uint8_t> back(grey.total() * channels);
    ASSERT_TRUE(in->read_image(0, 0, 0, channels, OIIO::TypeDesc::UINT8, back.data()));
    // Lossy, so near on average: each colour channel the grey level (RGB), the alpha kept (RGBA;
    // WebP is free to change the colour under partly transparent pixels).
    double colour = 0, alpha_off = 0;
    for (size_t i = 0; i < grey.total(); ++i) {
      for (int c = 0; c < 3; ++c) colour += std::abs(double(back[i * channels + c]) - grey.data[i]);
      if (channels == 4) alpha_off += std::abs(double(back[i * 4 + 3]) - alpha.data[i]);
    }
    if (channels == 3) EXPECT_LE(colour / (3.0 * grey.total()), 4.0);
    EXPECT_LE(alpha_off / grey.total(), 4.0);
  }
  std::filesystem::remove_all(dir);
}

// Debian's OpenImageIO JPEG 2000 writer reports success and writes nothing: the output was a
// 0-byte file and the run said it had succeeded. Either a file with bytes in it, or an error
// and no file.
TEST(ImageIo, AWriterThatWritesNothingIsAnError) {
  const auto dir = std::filesystem::temp_directory_path() / ("raindrop_jp2_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const cv::Mat rgb(24, 32, CV_8UC3, cv::Scalar(10, 120, 200));
  try {
    write_image_atomic(rgb, dir / "x.jp2");
    EXPECT_GT(std::filesystem::file_size(dir / "x.jp2"), 0u);
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("wrote no bytes"), std::string::npos) << e.what();
    EXPECT_FALSE(std::filesystem::exists(dir / "x.jp2"));
  }
  std::filesystem::remove_all(dir);
}

// A name near the file system's 255-byte limit: its hidden temporary (16-27 bytes longer)
// used to fail with "File name too long" after the work was done. The temporary now cuts the
// name; a final name past the limit is refused by the destination check.
TEST(ImageIo, LongFileNamesFitTheirTemporaries) {
  const auto dir = std::filesystem::temp_directory_path() / ("raindrop_long_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const cv::Mat img(4, 4, CV_8UC3, cv::Scalar(1, 2, 3));
  for (const char* ext : {".png", ".tif"}) {
    const auto longest = dir / (std::string(kMaxFileNameBytes - 4, 'a') + ext);
    EXPECT_NO_THROW(check_image_destination(longest));
    EXPECT_NO_THROW(write_image_atomic(img, longest));
    EXPECT_EQ(read_header(longest).width, 4);
    EXPECT_NO_THROW(write_text_atomic("x", dir / std::string(kMaxFileNameBytes, 't')));
    const auto too_long = dir / (std::string(kMaxFileNameBytes - 3, 'b') + ext);
    try {
      check_image_destination(too_long);
      ADD_FAILURE() << "a 256-byte name passed the destination check";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("256 bytes, longer than the 255"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(temporary_stem("short.png"), "short.png");
  EXPECT_LE(temporary_stem(std::string(300, 'c')).size() + 27, kMaxFileNameBytes);
  std::size_t hidden = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) hidden += e.path().filename().string()[0] == '.';
  EXPECT_EQ(hidden, 0u) << "temporaries left behind";
  std::filesystem::remove_all(dir);
}

// A failed rename must report its own error, not that of the clean-up after it (which
// succeeds, so the message read "(Success)").
TEST(ImageIo, FailedRenameReportsItsOwnError) {
  const auto dir = std::filesystem::temp_directory_path() / ("raindrop_rename_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir / "taken.png" / "inside");  // a non-empty folder by the final name
  std::filesystem::create_directories(dir / "taken.txt" / "inside");
  const cv::Mat img(4, 4, CV_8UC3, cv::Scalar(1, 2, 3));
  for (int text = 0; text < 2; ++text) {
    try {
      if (text) {
        write_text_atomic("hello\n", dir / "taken.txt");
      } else {
        write_image_atomic(img, dir / "taken.png");
      }
      ADD_FAILURE() << "writing over a folder succeeded";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("cannot move the finished file into place"), std::string::npos) << what;
      EXPECT_EQ(what.find("Success"), std::string::npos) << what;
      EXPECT_NE(what.find(std::strerror(EISDIR)), std::string::npos) << what;
    }
  }
  size_t left = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) left += e.path().filename().string()[0] == '.';
  EXPECT_EQ(left, 0u) << "temporaries left behind";
  std::filesystem::remove_all(dir);
}

// A photograph's colour profile goes from input to output: written into PNG (our fast writer
// and libpng's) and JPEG, read back byte for byte, grey and colour; a file without one reads
// back none. The pixels are those written without it.
TEST(ImageIo, ColourProfilesAreWrittenAndReadBack) {
  const auto dir = std::filesystem::temp_directory_path() / ("raindrop_icc_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  cv::Mat rgb(24, 32, CV_8UC3), grey(24, 32, CV_8UC1);
  cv::randu(rgb, 0, 256);
  cv::randu(grey, 0, 256);
  for (const auto& [image, space] : {std::pair{rgb, "RGB "}, std::pair{grey, "GRAY"}}) {
    const std::string icc = testsupport::test_icc_profile(space, 1000);
    for (const auto& [name, level] : {std::pair{"fast.png", kPngFast}, std::pair{"rle.png", kPngRunLength},
                                      std::pair{"level6.png", 6}, std::pair{"photo.jpg", kPngFast}}) {
      SCOPED_TRACE(std::string(name) + " " + space);
      write_image_atomic(image, dir / name, level, icc);
      std::string read;
      const cv::Mat back = read_image_native(dir / name, 1, &read);
      EXPECT_EQ(read, icc);
      write_image_atomic(image, dir / name, level);  // the same file again, without a profile
      const cv::Mat plain = read_image_native(dir / name, 1, &read);
      EXPECT_EQ(read, "");
      EXPECT_EQ(cv::norm(back, plain, cv::NORM_INF), 0.0);
    }
  }
  std::filesystem::remove_all(dir);
}

// Only a profile that is one by its header, and at most 1 MiB, is carried, as stored (padding
// past its size field included): a file whose "profile" is 9 MB of noise gave outputs that
// OpenCV and Pillow refuse to read (a fuzzer's). Written into PNG and JPEG by the test; those
// refused read back as none, and the pixels are read all the same.
TEST(ImageIo, OnlyAPlausibleProfileOfAtMostAMegabyteIsCarried) {
  testsupport::TempDir tmp("raindrop-icc-");
  cv::Mat rgb(24, 32, CV_8UC3);
  cv::randu(rgb, 0, 256);
  const std::string good = testsupport::test_icc_profile("RGB ", 1000);
  const auto declaring = [&good](std::uint32_t size) {  // the profile with its size field set to `size`
    std::string p = good;
    for (int i = 0; i < 4; ++i) p[i] = static_cast<char>(size >> (24 - 8 * i));
    return p;
  };
  const auto n = static_cast<std::uint32_t>(good.size());
  const std::string overstated = declaring(n + 4);   // says 4 bytes more than there are
  const std::string understated = declaring(n - 52);  // padded: a monitor profile's habit
  std::string no_signature = good;
  no_signature[36] = 'x';
  const std::string largest = testsupport::test_icc_profile("RGB ", ((1 << 20) - 132) / 4);
  const std::string too_large = testsupport::test_icc_profile("RGB ", ((1 << 20) - 132) / 4 + 1);
  ASSERT_EQ(largest.size(), 1u << 20);
  for (const auto& [why, icc, kept] : {std::tuple{"a profile", good, true}, std::tuple{"1 MiB", largest, true},
                                       std::tuple{"its size field past its end", overstated, false},
                                       std::tuple{"52 bytes of padding past its size", understated, true},
                                       std::tuple{"no 'acsp'", no_signature, false},
                                       std::tuple{"1 MiB and 4 bytes", too_large, false}}) {
    for (const char* name : {"p.png", "p.jpg"}) {
      SCOPED_TRACE(std::string(why) + ", " + name);
      write_image_atomic(rgb, tmp / name, kPngFast, icc);
      std::string read = "stale";
      const cv::Mat back = read_image_native(tmp / name, 1, &read);
      EXPECT_EQ(read, kept ? icc : "");
      EXPECT_EQ(back.size(), rgb.size());
    }
  }
}

// Staged images appear together at commit, or not at all: nothing is at its name before the
// commit, and a failed stage or no commit leaves no file and no temporary behind.
TEST(StagedImages, AppearTogetherAtCommitOrNotAtAll) {
  testsupport::TempDir tmp("raindrop_staged_");
  const cv::Mat image(8, 12, CV_8UC3, cv::Scalar(10, 20, 30));
  auto entries = [&] {
    int n = 0;
    for (const auto& e : std::filesystem::directory_iterator(tmp.path())) n += e.exists() ? 1 : 0;
    return n;
  };
  {
    StagedImages staged;
    staged.stage(image, tmp / "a.png");
    staged.stage(image, tmp / "b.jpg");
    EXPECT_FALSE(std::filesystem::exists(tmp / "a.png"));
    EXPECT_FALSE(std::filesystem::exists(tmp / "b.jpg"));
    EXPECT_EQ(entries(), 2);  // the two temporaries
  }
  EXPECT_EQ(entries(), 0) << "an uncommitted stage leaves nothing";
  {
    StagedImages staged;
    staged.stage(image, tmp / "a.png");
    EXPECT_THROW(staged.stage(image, tmp / "missing-folder" / "b.png"), Error);
  }
  EXPECT_EQ(entries(), 0) << "a failed stage takes the others with it";
  StagedImages staged;
  staged.stage(image, tmp / "a.png");
  staged.stage(image, tmp / "b.jpg");
  staged.commit();
  EXPECT_TRUE(std::filesystem::is_regular_file(tmp / "a.png"));
  EXPECT_TRUE(std::filesystem::is_regular_file(tmp / "b.jpg"));
  EXPECT_EQ(entries(), 2);
}

// Damaged files: cut at about 100 lengths, and 300 copies with one byte changed each:
// each read either decodes the image whole or throws raindrop::Error with one line naming the
// file; nothing else escapes, nothing crashes (run under the sanitizers: scripts/test-sanitizers.sh),
// and libpng/libjpeg print nothing of their own.
TEST(ImageIo, DamagedPngAndJpegFailInOneLine) {
  testsupport::TempDir tmp("raindrop-damaged-");
  const cv::Mat m = street_like(23, 31, 3);
  for (const std::string name : {"a.png", "a.jpg"}) {
    write_image_atomic(m, tmp / name);
    const std::string bytes = testsupport::read_file(tmp / name);
    std::mt19937 rng(11);
    int refused = 0, decoded = 0;
    auto attempt = [&](const std::string& damaged) {
      std::ofstream(tmp / ("bad-" + name), std::ios::binary | std::ios::trunc) << damaged;
      try {
        const cv::Mat got = read_image_native(tmp / ("bad-" + name));
        EXPECT_EQ(got.size(), m.size());
        ++decoded;
      } catch (const Error& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
        EXPECT_NE(what.find("bad-" + name), std::string::npos) << what;
        ++refused;
      }
    };
    testing::internal::CaptureStderr();
    for (size_t cut = 0; cut < bytes.size(); cut += std::max<size_t>(1, bytes.size() / 97)) attempt(bytes.substr(0, cut));
    for (int i = 0; i < 300; ++i) {
      std::string damaged = bytes;
      damaged[rng() % damaged.size()] ^= static_cast<char>(1 + rng() % 255);  // never the same byte
      attempt(damaged);
    }
    const std::string printed = testing::internal::GetCapturedStderr();
    EXPECT_EQ(printed, "") << name << ": a library printed on its own";
    EXPECT_GT(refused, 90) << name;  // every cut file at least
    if (name == "a.png") {
      EXPECT_EQ(decoded, 0) << "every changed byte of a PNG breaks a CRC";
    } else {
      EXPECT_GT(decoded, 0) << "a changed byte inside a JPEG's entropy-coded data still decodes";
    }
  }
}

// End-to-end: the clean image of a frame that is its input PNG as it was (no crop or resize, 8-bit
// RGB, shown as sRGB) is that file's bytes, not a new encoding of them; every other input's clean
// image is encoded, and decodes to the frame that was rendered. Either way the rainy image equals
// the clean one outside the mask.
#include <zlib.h>

#include "../common/png_bytes.h"
#include "cli_test_util.h"

namespace clitest {
namespace {

using testsupport::png_chunks;
using testsupport::png_from_chunks;

// An 8-bit RGB PNG of `pixels` with only its critical chunks, then `extra` ancillary chunks
// inserted before the image data (as PNG requires of the colour chunks).
std::string png_with(const cv::Mat& pixels, const std::vector<std::pair<std::string, std::string>>& extra,
                     const fs::path& scratch) {
  write_image(scratch, pixels);
  std::vector<std::pair<std::string, std::string>> chunks;
  for (auto& [type, data] : png_chunks(read_file(scratch))) {
    if (type == "IDAT" && !extra.empty() && chunks.back().first != "IDAT") chunks.insert(chunks.end(), extra.begin(), extra.end());
    if (type == "IHDR" || type == "IDAT" || type == "IEND") chunks.push_back({type, data});
  }
  return png_from_chunks(chunks);
}

std::string be32s(std::uint32_t v) { return testsupport::be32(v); }

// An 8-bit RGB PNG of `pixels` made here: rows with filter type None deflated by zlib, `trailing`
// bytes more in the stream after the last row (which libpng reads past with a warning and our
// own decoder refuses), `before` chunks ahead of the image data and `after` chunks behind it.
std::string png_made_here(const cv::Mat& pixels, const std::vector<std::pair<std::string, std::string>>& before,
                          const std::vector<std::pair<std::string, std::string>>& after = {}, int trailing = 0) {
  std::string raw;
  for (int y = 0; y < pixels.rows; ++y) {
    raw += '\0';
    raw.append(reinterpret_cast<const char*>(pixels.ptr(y)), 3 * static_cast<size_t>(pixels.cols));
  }
  raw.append(static_cast<size_t>(trailing), '\x55');
  uLongf size = compressBound(static_cast<uLong>(raw.size()));
  std::string deflated(size, '\0');
  EXPECT_EQ(compress2(reinterpret_cast<Bytef*>(deflated.data()), &size, reinterpret_cast<const Bytef*>(raw.data()),
                      static_cast<uLong>(raw.size()), 6),
            Z_OK);
  deflated.resize(size);
  std::vector<std::pair<std::string, std::string>> chunks{
      {"IHDR", be32s(static_cast<std::uint32_t>(pixels.cols)) + be32s(static_cast<std::uint32_t>(pixels.rows)) +
                   std::string{8, 2, 0, 0, 0}}};
  chunks.insert(chunks.end(), before.begin(), before.end());
  chunks.push_back({"IDAT", deflated});
  chunks.insert(chunks.end(), after.begin(), after.end());
  chunks.push_back({"IEND", ""});
  return png_from_chunks(chunks);
}

void expect_rainy_equals_clean_outside_mask(const fs::path& out, const std::string& id) {
  const auto rainy = read_image(out / "rainy" / (id + ".png"));
  const auto clean = read_image(out / "clean" / (id + ".png"));
  const auto mask = read_image(out / "mask" / (id + ".png"));
  ASSERT_TRUE(rainy && clean && mask) << id;
  ASSERT_EQ(rainy->pixels.size(), clean->pixels.size());
  cv::Mat differs;
  cv::compare(rainy->pixels.reshape(1, rainy->height * rainy->width), clean->pixels.reshape(1, clean->height * clean->width),
              differs, cv::CMP_NE);
  cv::Mat any_channel;
  cv::reduce(differs, any_channel, 1, cv::REDUCE_MAX);
  const cv::Mat outside = mask->pixels.reshape(1, mask->height * mask->width) == 0;
  EXPECT_EQ(cv::countNonZero(any_channel & outside), 0) << id << ": rainy differs from clean outside the mask";
  EXPECT_GT(cv::countNonZero(mask->pixels), 0) << id << ": no drop drawn";
}

TEST(RenderCleanBytes, AnInputShownAsSrgbIsItsOwnCleanImageToTheByte) {
  TempDir tmp;
  const cv::Mat pixels = make_background(160, 96, 2);
  // sRGB chunk (rendering intent 0), with the gAMA and cHRM that usually come with it (as in
  // Cityscapes' frames); a tEXt; nothing at all.
  const std::string srgb = png_with(pixels,
                                    {{"sRGB", std::string(1, '\0')},
                                     {"gAMA", be32s(45455)},
                                     {"cHRM", be32s(31270) + be32s(32900) + be32s(64000) + be32s(33000) + be32s(30000) +
                                                  be32s(60000) + be32s(15000) + be32s(6000)},
                                     {"tEXt", std::string("Comment") + '\0' + "a street"}},
                                    tmp / "scratch.png");
  const std::string bare = png_with(pixels, {}, tmp / "scratch.png");
  write_file(tmp / "in" / "srgb.png", srgb);
  write_file(tmp / "in" / "bare.png", bare);
  const auto r = run_render({"-i", "in", "--out", "out", "--variants", "2", "--seed", "3", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  for (const std::string name : {"srgb", "bare"}) {
    for (const std::string v : {"_v00", "_v01"}) {
      const std::string id = name + v;
      SCOPED_TRACE(id);
      EXPECT_EQ(read_file(tmp / "out" / "clean" / (id + ".png")), name == "srgb" ? srgb : bare)
          << "the clean image is not the input file's bytes";
      expect_rainy_equals_clean_outside_mask(tmp / "out", id);
    }
  }
}

// Where the file's bytes would not stand for the frame, the clean image is encoded from the frame:
// a gamma other than sRGB's or an ICC profile (a colour-managed viewer would show the copy
// otherwise than the rainy image), an orientation or an animation, pixels not decoded from the
// bytes read, a crop and resize (--size), and a 16-bit file (--convert).
TEST(RenderCleanBytes, OtherInputsAreEncodedFromTheFrame) {
  TempDir tmp;
  const cv::Mat pixels = make_background(160, 96, 4);
  const std::string icc = testsupport::test_icc_profile("RGB ", 3);
  std::string iccp = std::string("test") + '\0' + '\0';
  {
    // The profile deflated, as iCCP holds it: written by OpenImageIO's PNG writer and taken from there.
    auto out = OIIO::ImageOutput::create((tmp / "icc.png").string());
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(pixels.cols, pixels.rows, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("ICCProfile", OIIO::TypeDesc(OIIO::TypeDesc::UINT8, static_cast<int>(icc.size())), icc.data());
    ASSERT_TRUE(out->open((tmp / "icc.png").string(), spec));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, pixels.data));
    ASSERT_TRUE(out->close());
    for (auto& [type, data] : png_chunks(read_file(tmp / "icc.png")))
      if (type == "iCCP") iccp = data;
  }
  write_file(tmp / "in" / "linear.png", png_with(pixels, {{"gAMA", be32s(100000)}}, tmp / "scratch.png"));
  write_file(tmp / "in" / "profiled.png", png_with(pixels, {{"iCCP", iccp}}, tmp / "scratch.png"));
  cv::Mat wide16;
  pixels.convertTo(wide16, CV_16U, 257.0);
  write_image(tmp / "in16" / "deep.png", wide16);

  auto check_encoded = [&](const fs::path& out, const std::string& id, const std::string& input, const cv::Mat& frame) {
    SCOPED_TRACE(id);
    EXPECT_NE(read_file(out / "clean" / (id + ".png")), input) << "copied where it should have been encoded";
    const auto clean = read_image(out / "clean" / (id + ".png"));
    ASSERT_TRUE(clean);
    ASSERT_EQ(clean->pixels.size(), frame.size());
    EXPECT_EQ(cv::norm(clean->pixels, frame, cv::NORM_INF), 0) << "the clean image is not the rendered frame";
    expect_rainy_equals_clean_outside_mask(out, id);
  };

  // A plain file made here is copied (the control); the same with an EXIF orientation (a reader
  // may turn the copy, not the rainy image), an APNG animation control, an sRGB chunk after the
  // data (ignored by readers, so the gAMA before it rules), or data that libpng takes and our
  // own decoder refuses (libpng then reads the file again, which may have changed) is encoded.
  const std::string exif = std::string("MM\0*\0\0\0\x08\0\x01\x01\x12\0\x03\0\0\0\x01\0\x06\0\0\0\0\0\0", 26);
  write_file(tmp / "in" / "plain.png", png_made_here(pixels, {}));
  write_file(tmp / "in" / "turned.png", png_made_here(pixels, {{"eXIf", exif}}));
  write_file(tmp / "in" / "animated.png",
             png_made_here(pixels, {{"acTL", be32s(1) + be32s(0)}}));
  write_file(tmp / "in" / "late.png",
             png_made_here(pixels, {{"gAMA", be32s(100000)}}, {{"sRGB", std::string(1, '\0')}}));
  write_file(tmp / "in" / "overlong.png", png_made_here(pixels, {}, {}, 10));

  auto r = run_render({"-i", "in", "--out", "out", "--seed", "3", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  check_encoded(tmp / "out", "linear_v00", read_file(tmp / "in" / "linear.png"), pixels);
  check_encoded(tmp / "out", "profiled_v00", read_file(tmp / "in" / "profiled.png"), pixels);
  EXPECT_EQ(read_file(tmp / "out" / "clean" / "plain_v00.png"), read_file(tmp / "in" / "plain.png"))
      << "the control, a plain PNG made here, was not copied";
  for (const char* name : {"turned", "animated", "late", "overlong"})
    check_encoded(tmp / "out", std::string(name) + "_v00", read_file(tmp / "in" / (std::string(name) + ".png")), pixels);

  // An input that would have been copied, resized: the frame is the resized input.
  write_file(tmp / "in2" / "bare.png", png_with(pixels, {}, tmp / "scratch.png"));
  r = run_render({"-i", "in2", "--out", "out2", "--size", "80x48", "--seed", "3", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  cv::Mat resized;
  cv::resize(pixels, resized, cv::Size(80, 48), 0, 0, cv::INTER_AREA);
  check_encoded(tmp / "out2", "bare_v00", read_file(tmp / "in2" / "bare.png"), resized);

  r = run_render({"-i", "in16", "--out", "out3", "--convert", "--seed", "3", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  check_encoded(tmp / "out3", "deep_v00", read_file(tmp / "in16" / "deep.png"), pixels);
}

}  // namespace
}  // namespace clitest

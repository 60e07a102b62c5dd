// The pieces of the removal pipeline on their own: edge map, threshold and dilation, tiling
// layout and weights, pixel conversions, model discovery.
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"
#include "raindrop/remove/edge_map.h"
#include "raindrop/remove/mask.h"
#include "raindrop/remove/model_paths.h"
#include "raindrop/remove/pixels.h"
#include "raindrop/remove/tiling.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

cv::Mat random_rgb_float(int w, int h, int seed) {
  cv::Mat m(h, w, CV_32FC3);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::UNIFORM, 0.0, 1.0);
  return m;
}

TEST(EdgeMap, MatchesTheContractFormulaBitForBit) {
  for (const cv::Size s : {cv::Size(1, 1), cv::Size(2, 3), cv::Size(7, 5), cv::Size(33, 17)}) {
    const cv::Mat img = random_rgb_float(s.width, s.height, s.area());
    const cv::Mat e = edge_map(img);
    ASSERT_EQ(e.type(), CV_32FC1);
    ASSERT_EQ(e.size(), img.size());
    auto at = [&](int y, int x, int c) {
      y = std::clamp(y, 0, s.height - 1);
      x = std::clamp(x, 0, s.width - 1);
      return img.at<cv::Vec3f>(y, x)[c];
    };
    for (int y = 0; y < s.height; ++y) {
      for (int x = 0; x < s.width; ++x) {
        float d[3];
        for (int c = 0; c < 3; ++c) {
          const float v = at(y, x, c);
          d[c] = ((std::fabs(v - at(y, x + 1, c)) + std::fabs(v - at(y, x - 1, c))) + std::fabs(v - at(y + 1, x, c))) +
                 std::fabs(v - at(y - 1, x, c));
        }
        const float want = ((d[0] + d[1]) + d[2]) * 0.25f;
        ASSERT_EQ(e.at<float>(y, x), want) << "at " << x << "," << y << " of " << s;
      }
    }
  }
}

TEST(EdgeMap, KnownValues) {
  // A single white pixel on black: 4 neighbours differ by 1 in 3 channels -> 3; each
  // neighbour differs from it in one direction -> 3/4.
  cv::Mat img(5, 5, CV_32FC3, cv::Scalar::all(0));
  img.at<cv::Vec3f>(2, 2) = cv::Vec3f(1, 1, 1);
  const cv::Mat e = edge_map(img);
  EXPECT_FLOAT_EQ(e.at<float>(2, 2), 3.0f);
  EXPECT_FLOAT_EQ(e.at<float>(1, 2), 0.75f);
  EXPECT_FLOAT_EQ(e.at<float>(2, 3), 0.75f);
  EXPECT_FLOAT_EQ(e.at<float>(1, 1), 0.0f);
  // Uniform image: no edges anywhere, the border included (replicate rule).
  const cv::Mat flat = edge_map(cv::Mat(4, 6, CV_32FC3, cv::Scalar(0.2, 0.5, 0.9)));
  EXPECT_EQ(cv::countNonZero(flat), 0);
}

TEST(Mask, ThresholdIsStrictAndComparedInFloat) {
  const float t = 0.3f;  // the float nearest to 0.3 is slightly above it
  cv::Mat p = (cv::Mat_<float>(1, 5) << 0.0f, std::nextafter(t, 0.0f), t, std::nextafter(t, 1.0f),
               std::numeric_limits<float>::quiet_NaN());
  cv::Mat m(1, 5, CV_8U, cv::Scalar(7));
  threshold_mask(p, 0.3, m);
  EXPECT_EQ(m.at<unsigned char>(0, 0), 0);
  EXPECT_EQ(m.at<unsigned char>(0, 1), 0);
  EXPECT_EQ(m.at<unsigned char>(0, 2), 0) << "P == threshold must not count (strictly greater)";
  EXPECT_EQ(m.at<unsigned char>(0, 3), 1);
  EXPECT_EQ(m.at<unsigned char>(0, 4), 0) << "NaN must not count";
}

TEST(Mask, DilationIsTheOpenCvEllipseWithOutsidePixelsNotCounting) {
  cv::Mat m0(9, 11, CV_8U, cv::Scalar(0));
  m0.at<unsigned char>(4, 5) = 1;
  m0.at<unsigned char>(0, 0) = 1;  // at the border: must not wrap or smear
  EXPECT_EQ(cv::countNonZero(dilate_mask(m0, 1) != m0), 0);
  const cv::Mat m3 = dilate_mask(m0, 3);
  // 3x3 ellipse = a plus: 5 pixels around (4,5), 3 inside the image around (0,0).
  EXPECT_EQ(cv::countNonZero(m3), 5 + 3);
  EXPECT_EQ(m3.at<unsigned char>(3, 5), 1);
  EXPECT_EQ(m3.at<unsigned char>(3, 4), 0);
  // k = 5 around a single pixel: exactly the structuring element.
  cv::Mat one(5, 5, CV_8U, cv::Scalar(0));
  one.at<unsigned char>(2, 2) = 1;
  const cv::Mat k5 = cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5});
  EXPECT_EQ(cv::countNonZero(dilate_mask(one, 5) != k5), 0);
  // A full mask stays full (the border value must not erode it).
  const cv::Mat full(6, 6, CV_8U, cv::Scalar(1));
  EXPECT_EQ(cv::countNonZero(dilate_mask(full, 7)), 36);
  EXPECT_THROW(dilate_mask(one, 0), raindrop::Error);
}

// Every property the pipeline relies on, for many lengths, tiles and alignments.
TEST(Tiling, LayoutCoversAlignsOverlapsAndStaysWithinTheTile) {
  for (const int align : {1, 2, 8, 16}) {
    for (const int tile : {64, 100, 256, 1024}) {
      for (const int overlap : {0, 8, 16, 31}) {
        if (2 * overlap >= tile) continue;
        for (int length = 1; length < 2200; length += (length < 300 ? 7 : 97)) {
          const int len = (length + align - 1) / align * align;  // canvases are padded to the multiple
          const AxisLayout l = layout_axis(len, tile, overlap, align);
          const std::string ctx = "len " + std::to_string(len) + " tile " + std::to_string(tile) + " overlap " +
                                  std::to_string(overlap) + " align " + std::to_string(align);
          ASSERT_GE(l.count(), 1) << ctx;
          EXPECT_EQ(l.begin.front(), 0) << ctx;
          EXPECT_EQ(l.end.back(), len) << ctx;
          if (len <= tile) {
            EXPECT_EQ(l.count(), 1) << ctx;
          }
          for (int i = 0; i < l.count(); ++i) {
            EXPECT_EQ(l.begin[i] % align, 0) << ctx;
            EXPECT_LT(l.begin[i], l.end[i]) << ctx;
            // Within the tile whenever the tile leaves room for the overlap and alignment.
            const bool roomy = tile / align * align - align >= overlap + 3 * align - 1;
            EXPECT_LE(l.end[i] - l.begin[i], roomy ? tile : tile + overlap + 4 * align) << ctx;
            if (i + 1 < l.count()) {
              EXPECT_EQ((l.end[i] - l.begin[i]) % align, 0) << ctx;
            }
            if (i + 1 < l.count()) {
              EXPECT_GE(l.end[i] - l.begin[i + 1], overlap) << ctx << " window " << i;
              EXPECT_LT(l.begin[i], l.begin[i + 1]) << ctx;
              EXPECT_GE(l.cut[i], l.begin[i + 1]) << ctx;
              EXPECT_LE(l.cut[i], l.end[i]) << ctx;
            }
          }
          // Weights: a partition of unity, zero outside the window and within overlap/4 of an
          // inner window edge; owned ranges partition the axis.
          int owned_total = 0;
          for (int i = 0; i < l.count(); ++i) owned_total += l.owned_end(i) - l.owned_begin(i);
          EXPECT_EQ(owned_total, len) << ctx;
          for (int x = 0; x < len; ++x) {
            double sum = 0;
            for (int i = 0; i < l.count(); ++i) {
              const float w = l.weight(i, x);
              ASSERT_GE(w, 0.0f) << ctx;
              ASSERT_LE(w, 1.0f) << ctx;
              if (x < l.begin[i] || x >= l.end[i]) {
                ASSERT_EQ(w, 0.0f) << ctx << " x " << x << " window " << i;
              }
              if ((i > 0 && x < l.begin[i] + overlap / 4) || (i + 1 < l.count() && x >= l.end[i] - overlap / 4)) {
                ASSERT_EQ(w, 0.0f) << ctx << " x " << x << " window " << i;
              }
              sum += w;
            }
            ASSERT_NEAR(sum, 1.0, 1e-6) << ctx << " x " << x;
          }
          // The seams are cross-faded, not cut: with an overlap of 4 or more every seam has
          // pixels where both windows contribute (weights strictly between 0 and 1).
          if (overlap >= 4) {
            for (int j = 0; j + 1 < l.count(); ++j) {
              int blended = 0;
              for (int x = l.begin[j + 1]; x < l.end[j]; ++x) {
                const float w = l.weight(j, x);
                blended += w > 0.0f && w < 1.0f;
              }
              EXPECT_GT(blended, 0) << ctx << " seam " << j << ": a hard cut";
            }
          }
        }
      }
    }
  }
}

// The seam ramp itself (tiling.h): a raised cosine of half-width overlap/4 centred on the
// cut, where overlap is the windows' actual overlap. Checked against the formula written out
// here, on layouts whose windows are roomy enough that no ramp is narrowed by a neighbour.
TEST(Tiling, SeamsAreRaisedCosineRampsOfAQuarterOfTheOverlap) {
  struct Case {
    int length, tile, overlap, align;
  };
  for (const Case c : {Case{2048, 1024, 128, 2}, Case{1000, 256, 16, 8}, Case{300, 96, 16, 2}, Case{777, 200, 40, 1}}) {
    const AxisLayout l = layout_axis(c.length, c.tile, c.overlap, c.align);
    const std::string ctx = "len " + std::to_string(c.length) + " tile " + std::to_string(c.tile) + " overlap " +
                            std::to_string(c.overlap) + " align " + std::to_string(c.align);
    ASSERT_GE(l.count(), 2) << ctx;
    for (int j = 0; j + 1 < l.count(); ++j) {
      const int overlap = l.end[j] - l.begin[j + 1];
      const int cut = (l.begin[j + 1] + l.end[j]) / 2, r = overlap / 4;
      ASSERT_GE(r, c.overlap / 4) << ctx;
      EXPECT_EQ(l.cut[j], cut) << ctx;
      int blended = 0;
      for (int x = l.begin[j + 1]; x < l.end[j]; ++x) {
        const double t = (x + 0.5 - (cut - r)) / (2.0 * r);
        const double want = x < cut - r ? 1.0 : x >= cut + r ? 0.0 : 0.5 + 0.5 * std::cos(M_PI * t);
        const float left = l.weight(j, x), right = l.weight(j + 1, x);
        ASSERT_NEAR(left, want, 1e-6) << ctx << " seam " << j << " x " << x;
        ASSERT_NEAR(right, 1.0 - want, 1e-6) << ctx << " seam " << j << " x " << x;
        blended += left > 0.0f && left < 1.0f;
      }
      EXPECT_EQ(blended, 2 * r) << ctx << " seam " << j;
    }
  }
}

TEST(Tiling, WorkIsCloseToTheMinimum) {
  // A 2048-wide canvas with 1024 tiles and 128 overlap: 3 windows of ~770, not 3 x 1024.
  const AxisLayout l = layout_axis(2048, 1024, 128, 2);
  ASSERT_EQ(l.count(), 3);
  int work = 0;
  for (int i = 0; i < l.count(); ++i) work += l.end[i] - l.begin[i];
  EXPECT_LE(work, 2048 + 2 * (128 + 2) + 3 * 2);
  EXPECT_EQ(layout_axis(1024, 1024, 128, 2).count(), 1);
  EXPECT_EQ(layout_axis(5000, 0, 128, 2).count(), 1) << "tile 0 = never tile";
}

TEST(Tiling, OptionChecks) {
  EXPECT_NO_THROW(check_tile_options(0, 0));
  EXPECT_NO_THROW(check_tile_options(kDefaultTile, kDefaultOverlap));
  EXPECT_THROW(check_tile_options(-1, 0), raindrop::Error);
  EXPECT_THROW(check_tile_options(32, 0), raindrop::Error);
  EXPECT_THROW(check_tile_options(256, 128), raindrop::Error);
  EXPECT_THROW(check_tile_options(256, -1), raindrop::Error);
  // 2 * overlap must not wrap around: these are refused, not taken as a small overlap.
  EXPECT_THROW(check_tile_options(64, 1 << 30), raindrop::Error);
  EXPECT_THROW(check_tile_options(64, std::numeric_limits<int>::max()), raindrop::Error);
  EXPECT_THROW(check_tile_options(std::numeric_limits<int>::max(), std::numeric_limits<int>::max()), raindrop::Error);
}

TEST(Pixels, RoundingAndConversions) {
  // floor(clamp(x) * 255 + 0.5): round half up, clamped, NaN -> 0.
  EXPECT_EQ(to_u8(0.0f), 0);
  EXPECT_EQ(to_u8(1.0f), 255);
  EXPECT_EQ(to_u8(-3.0f), 0);
  EXPECT_EQ(to_u8(7.0f), 255);
  EXPECT_EQ(to_u8(std::numeric_limits<float>::quiet_NaN()), 0);
  EXPECT_EQ(to_u8(0.5f / 255.0f), 1);
  EXPECT_EQ(to_u8(0.49f / 255.0f), 0);
  EXPECT_EQ(to_u8(100.5f / 255.0f), 101) << "half rounds up";
  EXPECT_EQ(to_u8(100.49f / 255.0f), 100);
  EXPECT_EQ(to_u16(1.0f), 65535);
  EXPECT_EQ(to_u16(0.5f), 32768);
  // Every 8-bit value survives the round trip v / 255 -> to_u8.
  for (int v = 0; v < 256; ++v) {
    cv::Mat px(1, 1, CV_8UC3, cv::Scalar(v, v, v));
    const cv::Mat f = to_rgb_float(px, cv::Rect(0, 0, 1, 1));
    ASSERT_EQ(f.at<cv::Vec3f>(0, 0)[0], static_cast<float>(v) / 255.0f);
    ASSERT_EQ(to_u8(f.at<cv::Vec3f>(0, 0)[0]), v);
  }
  // Grey is replicated; RGBA's alpha is not part of the colour.
  cv::Mat grey(1, 1, CV_16UC1, cv::Scalar(65535));
  EXPECT_EQ(to_rgb_float(grey, {0, 0, 1, 1}).at<cv::Vec3f>(0, 0), cv::Vec3f(1, 1, 1));
  cv::Mat rgba(1, 1, CV_8UC4, cv::Scalar(0, 51, 255, 7));
  EXPECT_EQ(to_rgb_float(rgba, {0, 0, 1, 1}).at<cv::Vec3f>(0, 0), cv::Vec3f(0, 0.2f, 1));
  // Grey output is the luma of the RGB result.
  cv::Mat rgb(1, 1, CV_32FC3, cv::Scalar(1.0, 0.0, 0.0));
  cv::Mat out(1, 1, CV_8UC1);
  store_rgb_float(rgb, out, 0);
  EXPECT_EQ(out.at<unsigned char>(0, 0), to_u8(0.299f));
  EXPECT_THROW(check_input_format(cv::Mat()), raindrop::Error);
  EXPECT_THROW(check_input_format(cv::Mat(2, 2, CV_64FC3)), raindrop::Error);
}

// -------------------------------------------------------------------------------------------
// Model discovery.

class ModelSearchTest : public ::testing::Test {
 protected:
  void make_models(const fs::path& dir) {
    for (const char* f : {"rdn.onnx", "rrn.onnx", "rfn.onnx"}) write_file(dir / f, "x");
  }
  TempDir tmp;
};

TEST_F(ModelSearchTest, ExplicitFolderWinsOverEverything) {
  ModelSearch s;
  s.explicit_dir = tmp / "mine";
  s.env_dir = tmp / "env";
  make_models(tmp / "env");
  EXPECT_EQ(find_models(s), tmp / "mine");
}

TEST_F(ModelSearchTest, EnvironmentFolderOrRootOfConfigurations) {
  ModelSearch s;
  s.env_dir = tmp / "env";
  make_models(tmp / "env");
  EXPECT_EQ(find_models(s), tmp / "env");
  s.env_dir = tmp / "root";
  make_models(tmp / "root" / "compact");
  make_models(tmp / "root" / "paper");
  EXPECT_EQ(find_models(s), tmp / "root" / "compact") << "no DEFAULT: compact";
  write_file(tmp / "root" / "DEFAULT", "paper\n");
  EXPECT_EQ(find_models(s), tmp / "root" / "paper");
  s.config = "compact";
  EXPECT_EQ(find_models(s), tmp / "root" / "compact");
  s.config = "missing";
  EXPECT_THROW(find_models(s), raindrop::Error) << "$RAINDROP_MODELS is authoritative";
  s.config = "../escape";
  EXPECT_THROW(find_models(s), raindrop::Error);
}

TEST_F(ModelSearchTest, InstalledLocationBeforeSourceTree) {
  ModelSearch s;
  s.executable = tmp / "prefix" / "bin" / "raindrop-remove";
  s.source_models = tmp / "src" / "models";
  make_models(tmp / "src" / "models" / "compact");
  EXPECT_EQ(find_models(s), tmp / "src" / "models" / "compact");
  make_models(tmp / "prefix" / "share" / "raindrop" / "models" / "compact");
  EXPECT_EQ(find_models(s), tmp / "prefix" / "share" / "raindrop" / "models" / "compact");
  s.config = "paper";
  try {
    find_models(s);
    FAIL() << "expected an error";
  } catch (const raindrop::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("share/raindrop/models/paper"), std::string::npos) << msg;
    EXPECT_NE(msg.find("src/models/paper"), std::string::npos) << msg;
    EXPECT_NE(msg.find("--models"), std::string::npos) << msg;
  }
}

TEST(ModelDefault, SourceTreeNamesCompact) {
  EXPECT_EQ(read_default_config(source_dir() / "models").value_or("<none>"), "compact");
}

}  // namespace
}  // namespace removetest

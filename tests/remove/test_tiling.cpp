// tiling.h: the tile layout, the seam ramps and the option checks.
#include <cmath>

#include "raindrop/common/error.h"
#include "raindrop/remove/tiling.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

using namespace raindrop::removal;

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

}  // namespace
}  // namespace removetest

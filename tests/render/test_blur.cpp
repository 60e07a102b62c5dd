// Defocus blur: the fast row-run implementation equals direct summation, kernels have the
// closed-form area and variance, only drop pixels change, and constants stay constant.
#include <algorithm>
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "raindrop/common/rng.h"
#include "raindrop/render/blur.h"
#include "raindrop/render/disk_kernel.h"

using namespace raindrop;

namespace {

struct Fixture {
  cv::Mat clean, label, color;
};

Fixture random_fixture(int w, int h, std::uint64_t seed) {
  Fixture f;
  f.clean = cv::Mat(h, w, CV_8UC3);
  cv::randu(f.clean, 0, 256);
  f.label = cv::Mat(h, w, CV_32S, cv::Scalar(-1));
  f.color = cv::Mat(h, w, CV_32FC3, cv::Scalar(-7, -7, -7));  // sentinel outside drops
  Rng rng(seed);
  for (int i = 0; i < 6; ++i) {
    const int cx = rng.uniform_int(0, w - 1), cy = rng.uniform_int(0, h - 1), r = rng.uniform_int(2, 12);
    for (int y = std::max(0, cy - r); y <= std::min(h - 1, cy + r); ++y) {
      for (int x = std::max(0, cx - r); x <= std::min(w - 1, cx + r); ++x) {
        if ((x - cx) * (x - cx) + (y - cy) * (y - cy) > r * r) continue;
        f.label.at<int>(y, x) = i;
        f.color.at<cv::Vec3f>(y, x) = cv::Vec3f(static_cast<float>(rng.uniform()), static_cast<float>(rng.uniform()),
                                                static_cast<float>(rng.uniform()));
      }
    }
  }
  return f;
}

double max_diff_in_mask(const Fixture& a, const cv::Mat& ca, const cv::Mat& cb) {
  double worst = 0;
  for (int y = 0; y < a.label.rows; ++y)
    for (int x = 0; x < a.label.cols; ++x)
      if (a.label.at<int>(y, x) >= 0)
        for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs<double>(ca.at<cv::Vec3f>(y, x)[k] - cb.at<cv::Vec3f>(y, x)[k]));
  return worst;
}

}  // namespace

TEST(Blur, RowRunsEqualDirectSummation) {
  for (double d : {1.0, 2.5, 7.0, 13.3, 20.0}) {
    Fixture f = random_fixture(97, 61, static_cast<std::uint64_t>(d * 10));
    cv::Mat fast = f.color.clone(), direct = f.color.clone();
    blur_drops(f.clean, f.label, fast, d, BlurMethod::DiskSpan);
    blur_drops(f.clean, f.label, direct, d, BlurMethod::DiskDirect);
    EXPECT_LT(max_diff_in_mask(f, fast, direct), 2e-5) << "d = " << d;
    // A binary disk narrower than 2 px is the centre tap alone (see the test below).
    if (d >= 2) {
      EXPECT_GT(max_diff_in_mask(f, fast, f.color), 1e-3) << "the blur changed nothing, d = " << d;
    }
  }
}

TEST(Blur, OnlyDropPixelsChange) {
  for (BlurMethod m : {BlurMethod::DiskSpan, BlurMethod::DiskDirect, BlurMethod::DiskAntialiased, BlurMethod::Gaussian}) {
    Fixture f = random_fixture(80, 50, 5);
    cv::Mat out = f.color.clone();
    blur_drops(f.clean, f.label, out, 9, m);
    for (int y = 0; y < f.label.rows; ++y) {
      for (int x = 0; x < f.label.cols; ++x) {
        if (f.label.at<int>(y, x) < 0) {
          ASSERT_EQ(out.at<cv::Vec3f>(y, x), cv::Vec3f(-7, -7, -7)) << to_string(m);
        }
      }
    }
  }
}

TEST(Blur, ConstantImagesStayConstantUpToTheFrameBorder) {
  const cv::Mat clean(40, 60, CV_8UC3, cv::Scalar(51, 102, 204));
  const cv::Mat label(40, 60, CV_32S, cv::Scalar(0));  // every pixel is a drop pixel
  for (BlurMethod m : {BlurMethod::DiskSpan, BlurMethod::DiskDirect, BlurMethod::DiskAntialiased, BlurMethod::Gaussian}) {
    for (double d : {0.7, 3.0, 17.0, 150.0}) {  // up to kernels much larger than the frame
      cv::Mat color(40, 60, CV_32FC3, cv::Scalar(0.2f, 0.4f, 0.8f));
      blur_drops(clean, label, color, d, m);
      double lo, hi;
      cv::minMaxLoc(color.reshape(1), &lo, &hi);
      // float sums over up to ~18000 taps (d = 150, direct) drift by ~2e-5.
      EXPECT_NEAR(lo, 0.2, 1e-4) << to_string(m) << " d " << d;
      EXPECT_NEAR(hi, 0.8, 1e-4) << to_string(m) << " d " << d;
    }
  }
}

TEST(Blur, KernelsHaveTheDiskAreaAndVariance) {
  // Diameters of 5 px and more: below that the pixel grid dominates the moments.
  for (double d : {5.0, 7.5, 20.0, 41.0}) {
    const double r = d / 2;
    // Antialiased: the summed pixel areas equal the disk's area (before normalisation).
    cv::Mat aa = blur_kernel(d, BlurMethod::DiskAntialiased);
    const int R = aa.rows / 2;
    double max_w = 0, var = 0;
    for (int y = 0; y < aa.rows; ++y)
      for (int x = 0; x < aa.cols; ++x) {
        max_w = std::max(max_w, aa.at<double>(y, x));
        var += aa.at<double>(y, x) * (x - R) * (x - R);
      }
    EXPECT_NEAR(1.0 / max_w, M_PI * r * r, 0.01 * M_PI * r * r) << d;  // interior weight 1 / area
    // A uniform disk has variance r^2 / 4 per axis; weighting pixel centres by pixel areas
    // adds at most the pixels' own variance, 1/12.
    EXPECT_GE(var, r * r / 4 - 0.02 * r * r / 4) << d;
    EXPECT_LE(var, r * r / 4 + 1.0 / 12 + 0.02 * r * r / 4) << d;
    // The Gaussian method is matched to that variance.
    cv::Mat g = blur_kernel(d, BlurMethod::Gaussian);
    const int G = g.rows / 2;
    double gvar = 0;
    for (int y = 0; y < g.rows; ++y)
      for (int x = 0; x < g.cols; ++x) gvar += g.at<double>(y, x) * (x - G) * (x - G);
    EXPECT_NEAR(gvar, r * r / 4, 0.05 * r * r / 4 + 0.02) << d;
    // Kernels are normalised and symmetric.
    EXPECT_NEAR(cv::sum(aa)[0], 1.0, 1e-12);
    cv::Mat flipped;
    cv::flip(aa, flipped, -1);
    EXPECT_LT(cv::norm(aa, flipped, cv::NORM_INF), 1e-15);
  }
}

// The antialiased disk weighs each rim pixel by the fraction of its 16 x 16 sub-points inside
// the circle; disk_kernel.cpp counts them per sub-row from the chord, corrected with the same
// test. Point by point here, over diameters that put the rim anywhere in its pixels.
TEST(Blur, AntialiasedWeightsAreThePointByPointCount) {
  int rim = 0;
  for (double d = 1.1; d < 140; d += 0.37) {
    const double r = 0.5 * d;
    for (const KernelRow& row : disk_rows(d, true, false)) {
      for (const auto& [dx, w] : row.taps) {
        int inside = 0;
        for (int j = 0; j < 16; ++j) {
          const double yy = row.dy - 0.5 + (j + 0.5) / 16;
          for (int i = 0; i < 16; ++i) {
            const double xx = dx - 0.5 + (i + 0.5) / 16;
            inside += xx * xx + yy * yy <= r * r;
          }
        }
        ASSERT_EQ(w, static_cast<float>(inside / 256.0)) << "diameter " << d << " at " << dx << ", " << row.dy;
        rim += inside < 256;
      }
    }
  }
  EXPECT_GT(rim, 10000);
}

TEST(Blur, DisksSmallerThanAPixelAreTheIdentity) {
  for (BlurMethod m : {BlurMethod::DiskSpan, BlurMethod::DiskAntialiased}) {
    for (double d : {1e-9, 1e-3, 0.5, 1.0}) {
      const cv::Mat k = blur_kernel(d, m);
      EXPECT_DOUBLE_EQ(k.at<double>(k.rows / 2, k.cols / 2), 1.0) << to_string(m) << " " << d;
    }
  }
}

TEST(Blur, AntialiasedDiskIsExactAtSmallDiametersWhereTheBinaryDiskIsNot) {
  // At 512 px wide the paper's 7-20 px diameters become 1.75-5 px. A binary disk of
  // diameter 1.75 keeps only the centre tap (no blur at all); the antialiased one does not.
  const cv::Mat binary = blur_kernel(1.75, BlurMethod::DiskSpan);
  const cv::Mat aa = blur_kernel(1.75, BlurMethod::DiskAntialiased);
  const int R = binary.rows / 2;
  EXPECT_DOUBLE_EQ(binary.at<double>(R, R), 1.0);
  EXPECT_LT(aa.at<double>(R, R), 0.5);
}

TEST(Blur, ReadingOnlyNearTracedSpansGivesTheSameResult) {
  // The renderer passes the tracer's spans so the blur builds its source only near drops;
  // the result must equal the whole-row source up to float rounding of the prefix sums.
  Fixture f = random_fixture(120, 70, 17);
  std::vector<std::vector<std::pair<int, int>>> spans(f.label.rows);
  for (int y = 0; y < f.label.rows; ++y) {
    int lo = -1, hi = -1;
    for (int x = 0; x < f.label.cols; ++x) {
      if (f.label.at<int>(y, x) < 0) continue;
      if (lo < 0) lo = x;
      hi = x;
    }
    if (lo >= 0) spans[y].push_back({lo, hi});
  }
  const cv::Rect box = cv::boundingRect(cv::Mat(f.label >= 0));
  for (BlurMethod m : {BlurMethod::DiskSpan, BlurMethod::DiskDirect, BlurMethod::DiskAntialiased, BlurMethod::Gaussian}) {
    for (double d : {3.0, 9.5, 21.0}) {
      cv::Mat full = f.color.clone(), near = f.color.clone();
      blur_drops(f.clean, f.label, full, d, m);
      blur_drops(f.clean, f.label, near, d, m, &box, &spans);
      EXPECT_LT(max_diff_in_mask(f, full, near), 1e-5) << to_string(m) << " d " << d;
    }
  }
}

// What the blur reads near the traced spans is, row for row, the union of the window's spans
// widened and clipped (here computed directly, sorted and merged), for random spans, reaches
// (0 to 12: windows of 1 to 25 rows) and boxes at and inside the frame's border.
TEST(Blur, ReadIntervalsAreEachWindowsWidenedSpans) {
  Rng rng(23);
  int rows_checked = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const int width = rng.uniform_int(20, 200), height = rng.uniform_int(5, 90);
    std::vector<std::vector<std::pair<int, int>>> spans(height);
    for (auto& row : spans) {
      const int count = rng.uniform_int(0, 4);
      for (int i = 0; i < count; ++i) {
        const int a = rng.uniform_int(0, width - 1);
        row.push_back({a, std::min(width - 1, a + rng.uniform_int(0, 30))});
      }
      merge_spans(row);
    }
    const int reach = rng.uniform_int(0, 12);
    const int x = rng.uniform_int(0, width / 3), y = rng.uniform_int(0, height / 3);
    const cv::Rect box(x, y, rng.uniform_int(1, width - x), rng.uniform_int(1, height - y));
    const auto got = blur_read_intervals(&spans, reach, box);
    ASSERT_EQ(static_cast<int>(got.size()), box.height);
    for (int j = 0; j < box.height; ++j) {
      std::vector<std::pair<int, int>> want;
      for (int yy = std::max(0, box.y + j - reach); yy <= std::min(height - 1, box.y + j + reach); ++yy) {
        for (const auto& [a, b] : spans[yy]) {
          const int ia = std::max(box.x, a - reach), ib = std::min(box.x + box.width - 1, b + reach);
          if (ia <= ib) want.push_back({ia, ib});
        }
      }
      merge_spans(want);
      EXPECT_EQ(got[j], want) << "trial " << trial << " row " << j;
      ++rows_checked;
    }
  }
  EXPECT_GT(rows_checked, 1000);
}

// The blur of a single bright drop pixel is the kernel itself, so its footprint shows the
// disk's diameter (blur.h): for "disk" and "disk-direct" exactly the pixels whose centre is
// within d / 2 of the point; for "disk-aa" each column holds the area of the disk of
// diameter d between the column's edges (closed form below), over the disk's area.
TEST(Blur, APointSpreadsToADiskOfTheGivenDiameter) {
  constexpr int kSize = 41, kC = kSize / 2;
  auto blurred_point = [](double d, BlurMethod m) {
    const cv::Mat clean(kSize, kSize, CV_8UC3, cv::Scalar(0, 0, 0));
    const cv::Mat label(kSize, kSize, CV_32S, cv::Scalar(0));  // every pixel is a drop pixel
    cv::Mat color(kSize, kSize, CV_32FC3, cv::Scalar(0, 0, 0));
    color.at<cv::Vec3f>(kC, kC) = cv::Vec3f(1, 1, 1);
    blur_drops(clean, label, color, d, m);
    cv::Mat out;
    cv::extractChannel(color, out, 1);
    return out;
  };
  // r^2 is kept away from sums of two squares, so no pixel centre lies on the rim.
  for (double d : {6.2, 9.4, 13.1, 17.6}) {
    const double r = d / 2;
    for (BlurMethod m : {BlurMethod::DiskSpan, BlurMethod::DiskDirect}) {
      const cv::Mat out = blurred_point(d, m);
      int inside = 0;
      for (int y = 0; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
          const int dx = x - kC, dy = y - kC;
          const bool in_disk = dx * dx + dy * dy <= r * r;
          inside += in_disk;
          ASSERT_EQ(out.at<float>(y, x) > 0, in_disk) << to_string(m) << " d " << d << " at " << dx << "," << dy;
        }
      }
      EXPECT_NEAR(cv::sum(out)[0], 1.0, 1e-5) << to_string(m) << " d " << d;
      EXPECT_NEAR(out.at<float>(kC, kC), 1.0 / inside, 1e-6) << to_string(m) << " d " << d;
    }
    // Area of the disk left of X: integral of the chord 2 sqrt(r^2 - t^2) from -r to X.
    auto left_of = [r](double X) {
      X = std::clamp(X, -r, r);
      return X * std::sqrt(r * r - X * X) + r * r * std::asin(X / r) + r * r * M_PI / 2;
    };
    const cv::Mat aa = blurred_point(d, BlurMethod::DiskAntialiased);
    for (int x = 0; x < kSize; ++x) {
      const int dx = x - kC;
      const double want = (left_of(dx + 0.5) - left_of(dx - 0.5)) / (M_PI * r * r);
      // 16x16 midpoint rule per rim pixel (blur.cpp) and the normalisation by the summed areas:
      // a few hundredths of a pixel per column.
      EXPECT_NEAR(cv::sum(aa.col(x))[0], want, 0.06 / (M_PI * r * r)) << "disk-aa d " << d << " column " << dx;
    }
  }
}

// Every drop pixel is the kernel's weighted mean of the source (the traced colour inside
// drops, the clean pixel outside), summed here directly in double from blur_kernel, with the
// taps outside the frame dropped and the rest renormalised. Drops cover long runs of pixels
// (the blur sums several neighbours at a time) of every length, and touch every border.
TEST(Blur, EveryDropPixelIsTheKernelsMeanOfItsSource) {
  const int w = 97, h = 61;
  for (double d : {1.5, 4.0, 7.3, 12.0}) {
    for (BlurMethod m : {BlurMethod::DiskAntialiased, BlurMethod::DiskSpan, BlurMethod::DiskDirect}) {
      Fixture f = random_fixture(w, h, 17);
      Rng rng(static_cast<std::uint64_t>(d * 10) + 5);
      for (int y = 0; y < h; y += 3) {  // rows of drop pixels from 1 to w pixels long
        const int len = 1 + (y * 7) % w, x0 = y % 2 ? 0 : w - len;
        for (int x = x0; x < x0 + len; ++x) {
          f.label.at<int>(y, x) = 9;
          f.color.at<cv::Vec3f>(y, x) = cv::Vec3f(static_cast<float>(rng.uniform()), static_cast<float>(rng.uniform()),
                                                  static_cast<float>(rng.uniform()));
        }
      }
      cv::Mat source(h, w, CV_64FC3);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          for (int c = 0; c < 3; ++c)
            source.at<cv::Vec3d>(y, x)[c] = f.label.at<int>(y, x) >= 0 ? f.color.at<cv::Vec3f>(y, x)[c]
                                                                        : f.clean.at<cv::Vec3b>(y, x)[c] / 255.0;
      const cv::Mat k = blur_kernel(d, m);
      const int R = k.rows / 2;
      cv::Mat out = f.color.clone();
      blur_drops(f.clean, f.label, out, d, m);
      double worst = 0;
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          if (f.label.at<int>(y, x) < 0) continue;
          cv::Vec3d sum(0, 0, 0);
          double weight = 0;
          for (int dy = -R; dy <= R; ++dy) {
            for (int dx = -R; dx <= R; ++dx) {
              const int yy = y + dy, xx = x + dx;
              const double kw = k.at<double>(dy + R, dx + R);
              if (yy < 0 || xx < 0 || yy >= h || xx >= w || kw == 0) continue;
              sum += kw * source.at<cv::Vec3d>(yy, xx);
              weight += kw;
            }
          }
          for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(out.at<cv::Vec3f>(y, x)[c] - sum[c] / weight));
        }
      }
      EXPECT_LT(worst, 2e-5) << to_string(m) << " d " << d;
    }
  }
}

// The wide-register paths (AVX: two pixels per register, AVX-512: four) give the SSE2 path's
// bits, for both disk methods, diameters up to the paper's 20 px and drops wide enough for
// whole blocks of 8 pixels and their remainders.
TEST(Blur, EveryRegisterWidthGivesTheSameBits) {
  const int widest = blur_simd_level();
  if (widest == 0) GTEST_SKIP() << "this processor has neither AVX nor AVX-512: only the SSE2 path runs here";
  for (BlurMethod method : {BlurMethod::DiskAntialiased, BlurMethod::DiskSpan}) {
    for (double d : {2.5, 7.0, 13.3, 20.0}) {
      Fixture f = random_fixture(211, 97, static_cast<std::uint64_t>(d * 100));
      // Also as the renderer calls it: the drops' box and each row's traced spans (the source
      // then holds only what lies near drops, and its prefix sums restart per interval).
      std::vector<std::vector<std::pair<int, int>>> spans(f.label.rows);
      for (int y = 0; y < f.label.rows; ++y)
        for (int x = 0; x < f.label.cols; ++x)
          if (f.label.at<int>(y, x) >= 0) {
            if (spans[y].empty() || spans[y].back().second != x - 1) spans[y].push_back({x, x});
            spans[y].back().second = x;
          }
      const cv::Rect box = cv::boundingRect(cv::Mat(f.label >= 0));
      for (bool near : {false, true}) {
        force_blur_simd_level(0);
        cv::Mat narrow = f.color.clone();
        blur_drops(f.clean, f.label, narrow, d, method, near ? &box : nullptr, near ? &spans : nullptr);
        for (int level = 1; level <= widest; ++level) {
          force_blur_simd_level(level);
          cv::Mat wide = f.color.clone();
          blur_drops(f.clean, f.label, wide, d, method, near ? &box : nullptr, near ? &spans : nullptr);
          EXPECT_EQ(0, std::memcmp(narrow.data, wide.data, narrow.total() * narrow.elemSize()))
              << "level " << level << ", d = " << d << (near ? ", spans" : "") << ", max difference "
              << max_diff_in_mask(f, narrow, wide);
        }
      }
      force_blur_simd_level(0);
      cv::Mat narrow = f.color.clone();
      blur_drops(f.clean, f.label, narrow, d, method);
      force_blur_simd_level(-1);
      EXPECT_GT(max_diff_in_mask(f, narrow, f.color), 1e-3) << "the blur changed nothing, d = " << d;
    }
  }
}

// Runs of every length from 1 to 48 drop pixels, alone in their row and in pairs of runs, at
// every register width: a run's last pixels that do not fill a whole group are summed by a group
// that overlaps the pixels before it (blur.cpp, sum_at), which must give each pixel the SSE2
// path's bits, and never write outside the run (the pixels between the runs keep the sentinel).
TEST(Blur, RunsOfEveryLengthGiveTheSameBitsAtEveryRegisterWidth) {
  const int widest = blur_simd_level();
  if (widest == 0) GTEST_SKIP() << "this processor has neither AVX nor AVX-512: only the SSE2 path runs here";
  const int w = 160, h = 2 * 48 + 40;
  Fixture f = random_fixture(w, h, 23);
  f.label.setTo(-1);
  f.color.setTo(cv::Scalar(-7, -7, -7));
  Rng rng(29);
  auto drop_run = [&](int y, int x0, int len) {
    for (int x = x0; x < x0 + len; ++x) {
      f.label.at<int>(y, x) = 1;
      f.color.at<cv::Vec3f>(y, x) = cv::Vec3f(static_cast<float>(rng.uniform()), static_cast<float>(rng.uniform()),
                                              static_cast<float>(rng.uniform()));
    }
  };
  for (int len = 1; len <= 48; ++len) {
    drop_run(20 + len - 1, 30, len);              // alone, away from the border
    drop_run(20 + 48 + len - 1, 25, len);         // two runs in one row, a few pixels apart
    drop_run(20 + 48 + len - 1, 25 + len + 1 + len % 3, 48 - len + 1);
  }
  for (BlurMethod method : {BlurMethod::DiskAntialiased, BlurMethod::DiskSpan}) {
    for (double d : {2.5, 13.3, 20.0}) {
      force_blur_simd_level(0);
      cv::Mat narrow = f.color.clone();
      blur_drops(f.clean, f.label, narrow, d, method);
      for (int level = 1; level <= widest; ++level) {
        force_blur_simd_level(level);
        cv::Mat wide = f.color.clone();
        blur_drops(f.clean, f.label, wide, d, method);
        EXPECT_EQ(0, std::memcmp(narrow.data, wide.data, narrow.total() * narrow.elemSize()))
            << "level " << level << ", d = " << d << ", max difference in drops " << max_diff_in_mask(f, narrow, wide);
      }
      force_blur_simd_level(-1);
      EXPECT_GT(max_diff_in_mask(f, narrow, f.color), 1e-3) << "the blur changed nothing, d = " << d;
    }
  }
}

// The lens disk's points (lens_disk.h): the fast sine and cosine against the library's, and
// the points against the concentric map computed with them.
#include <cmath>
#include <cstring>
#include <vector>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "raindrop/common/rng.h"
#include "raindrop/render/lens_disk.h"
#include "raindrop/render/pinhole_lanes.h"

using namespace raindrop;

// Within an ulp of std::sin and std::cos over the quarter turn, its ends included.
TEST(LensDisk, QuarterSincosIsTheLibrarysToAnUlp) {
  Rng rng(3);
  double worst_sin = 0, worst_cos = 0;
  for (int i = 0; i < 1000000; ++i) {
    const double x = i < 2 ? (i == 0 ? M_PI / 4 : -M_PI / 4) : rng.uniform(-M_PI / 4, M_PI / 4);
    double s, c;
    quarter_sincos(x, &s, &c);
    const double ref_s = std::sin(x), ref_c = std::cos(x);
    if (ref_s != 0) worst_sin = std::max(worst_sin, std::abs(s - ref_s) / std::abs(ref_s));
    worst_cos = std::max(worst_cos, std::abs(c - ref_c) / ref_c);
  }
  EXPECT_LE(worst_sin, 0x1.0p-52);
  EXPECT_LE(worst_cos, 0x1.0p-52);
  double s, c;
  quarter_sincos(0.0, &s, &c);
  EXPECT_EQ(s, 0.0);
  EXPECT_EQ(c, 1.0);
}

// Each point is the concentric map of its jittered stratum (computed with the library's
// trigonometry) to 1e-15 of the radius, lies in the disk at the distance the map gives its
// square's ring, and over many pixels the points cover the disk uniformly.
TEST(LensDisk, PointsAreTheConcentricMapOfTheirStrata) {
  const double radius = 0.37;
  const int k = 4;
  double sum_x = 0, sum_y = 0, sum_r2 = 0;
  int n = 0;
  for (int y = 0; y < 40; ++y) {
    for (int x = 0; x < 40; ++x) {
      for (int j = 0; j < k; ++j) {
        for (int i = 0; i < k; ++i) {
          const glm::dvec2 p = lens_disk_point(x, y, i, j, k, radius);
          const glm::dvec2 jitter = unit_pair(pixel_hash(x, y, static_cast<std::uint64_t>(j * k + i)));
          const double a = 2.0 * (i + jitter.x) / k - 1.0, b = 2.0 * (j + jitter.y) / k - 1.0;
          const double r = std::abs(a) > std::abs(b) ? a : b;
          const double phi = std::abs(a) > std::abs(b) ? M_PI / 4 * (b / a) : M_PI / 2 - M_PI / 4 * (a / b);
          EXPECT_NEAR(p.x, radius * r * std::cos(phi), 1e-15 * radius);
          EXPECT_NEAR(p.y, radius * r * std::sin(phi), 1e-15 * radius);
          EXPECT_LE(glm::length(p), radius * (1 + 1e-15));
          // Its ring in the map: max(|a|, |b|) of the square, which the map keeps as r / radius.
          EXPECT_NEAR(glm::length(p) / radius, std::max(std::abs(a), std::abs(b)), 1e-14);
          sum_x += p.x, sum_y += p.y, sum_r2 += glm::dot(p, p);
          ++n;
        }
      }
    }
  }
  // A uniform disk: mean at the centre, mean squared distance radius^2 / 2.
  EXPECT_NEAR(sum_x / n, 0.0, 0.01 * radius);
  EXPECT_NEAR(sum_y / n, 0.0, 0.01 * radius);
  EXPECT_NEAR(sum_r2 / n, 0.5 * radius * radius, 0.01 * radius * radius);
}

// A pixel's points at once (lens_disk_points, in SIMD lanes) are lens_disk_point's one at a
// time to the bit, on every register width the processor has: grids whose strata fill the
// widths exactly (4 x 4), leave partial registers (3 x 3, 5 x 5) and span several of its
// chunks of 64 (9 x 9, 16 x 16), one stratum (1 x 1), far pixels, and radii from tiny to large.
// Fails if one operation is reordered (the radius multiplied in last, tried).
TEST(LensDisk, PointsAtOnceAreEachPointToTheBit) {
  struct ForcedLevel {
    explicit ForcedLevel(int level) { PinholeLanes::force_level(level); }
    ~ForcedLevel() { PinholeLanes::force_level(-1); }
  };
  Rng rng(11);
  int compared = 0;
  for (int level = 0; level <= PinholeLanes::level(); ++level) {
    const ForcedLevel forced(level);
    for (const int k : {1, 3, 4, 5, 9, 16}) {
      std::vector<glm::dvec2> points(static_cast<size_t>(k * k));
      for (int trial = 0; trial < 200; ++trial) {
        const int x = trial < 2 ? 65535 * trial : static_cast<int>(rng.uniform(0, 8192));
        const int y = trial < 2 ? 65535 * trial : static_cast<int>(rng.uniform(0, 8192));
        const double radius = std::exp(rng.uniform(std::log(1e-4), std::log(10.0)));
        lens_disk_points(x, y, k, radius, points.data());
        for (int j = 0; j < k; ++j) {
          for (int i = 0; i < k; ++i) {
            const glm::dvec2 one = lens_disk_point(x, y, i, j, k, radius);
            const glm::dvec2& all = points[static_cast<size_t>(j * k + i)];
            ASSERT_EQ(std::memcmp(&one, &all, sizeof one), 0)
                << "width level " << level << ", k " << k << ", pixel " << x << "," << y << ", stratum " << i << ","
                << j << ": " << one.x << "," << one.y << " one at a time, " << all.x << "," << all.y << " at once";
            ++compared;
          }
        }
      }
    }
  }
  EXPECT_GT(compared, 60000);
}

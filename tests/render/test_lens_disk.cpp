// The lens disk's points (lens_disk.h): the fast sine and cosine against the library's, and
// the points against the concentric map computed with them.
#include <cmath>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "raindrop/common/rng.h"
#include "raindrop/render/lens_disk.h"

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

// Rays leaving drops through their caps, two at a time in SIMD arithmetic (cap_exit.h): every
// answer is Drop::intersect's to the bit, on random drops (tilted glass, gravity's stretch,
// contact angles up to 90 degrees), rays in every direction from the base, short and long
// segments, and every packet size. And Drop::intersect's shortcut for rays going out through
// a base: the base is where they enter the water (the point just before it is dry, just after
// it wet, by the drop's implicit surface, not by intersect).
#include <cstring>
#include <limits>
#include <vector>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "raindrop/common/rng.h"
#include "raindrop/render/cap_exit.h"
#include "raindrop/render/drop.h"
#include "raindrop/render/glass.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// A random drop on a random glass, stretched by gravity one time in three.
Drop random_drop(Rng& rng) {
  const GlassPlane glass{rng.uniform(1.0, 100.0), rng.uniform(0.3, M_PI / 2)};
  DropShape shape = cap(rng.uniform(-20.0, 20.0), rng.uniform(-20.0, 20.0), rng.uniform(0.01, 1.5),
                        rng.uniform(5.0, 90.0));
  if (rng.uniform() < 1.0 / 3) {
    shape.elongation = rng.uniform(1.0, 2.0);
    shape.flattening = rng.uniform(0.5, 1.0);
  }
  return Drop(shape, glass);
}

// A point of the drop's base: its footprint centre moved across and downhill, inside the rim.
glm::dvec3 base_point(const Drop& drop, const GlassPlane& glass, Rng& rng) {
  const glm::dvec2 ab = drop.shape().footprint_semi_axes();
  double x, y;
  do {
    x = rng.uniform(-1.0, 1.0), y = rng.uniform(-1.0, 1.0);
  } while (x * x + y * y > 1.0);
  return glass.point(drop.shape().center + glm::dvec2(x * ab.x, y * ab.y));
}

}  // namespace

TEST(CapExit, GivesDropIntersectsAnswerToTheBit) {
  Rng rng(17);
  std::int64_t hits = 0, misses = 0, lanes = 0;
  for (int packet = 0; packet < 20000; ++packet) {
    const int n = 1 + packet % 8;
    std::vector<Drop> drops;
    drops.reserve(8);  // lane_drop points into it
    const Drop* lane_drop[8];
    glm::dvec3 origins[8], dirs[8];
    double t_max[8];
    for (int i = 0; i < n; ++i) {
      // Two packets in three share one drop (a camera packet mostly does).
      if (i == 0 || rng.uniform() < 1.0 / 3) drops.push_back(random_drop(rng));
    }
    for (int i = 0; i < n; ++i) {
      const Drop& drop = drops[rng.uniform_int(0, static_cast<int>(drops.size()) - 1)];
      lane_drop[i] = &drop;
      const Drop::Frame f = drop.frame();
      // A base point: the footprint centre plus a point of the ellipse in the glass frame.
      const glm::dvec2 ab = drop.shape().footprint_semi_axes();
      double x, y;
      do {
        x = rng.uniform(-1.0, 1.0), y = rng.uniform(-1.0, 1.0);
      } while (x * x + y * y > 1.0);
      origins[i] = f.c + x * ab.x * f.u + y * ab.y * f.v;
      // Mostly into the water (as a refracted camera ray goes), sometimes any direction
      // (back into the glass: no exit), any length.
      glm::dvec3 d(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
      if (rng.uniform() < 0.8 && glm::dot(d, f.n) < 0) d -= 2.0 * glm::dot(d, f.n) * f.n;
      dirs[i] = rng.uniform() < 0.5 ? glm::normalize(d) : d * rng.uniform(0.1, 10.0);
      const double r = rng.uniform();
      t_max[i] = r < 0.5 ? std::numeric_limits<double>::infinity() : rng.uniform(0.0, 2.0 * drop.shape().height());
    }
    CapExit out[8];
    exit_through_caps(lane_drop, origins, dirs, t_max, n, out);
    for (int i = 0; i < n; ++i) {
      ++lanes;
      const auto want = lane_drop[i]->intersect(origins[i], dirs[i], 0.0, t_max[i], DropSurface::Base);
      ASSERT_EQ(out[i].hit, want.has_value()) << "packet " << packet << " lane " << i;
      if (!want) {
        ++misses;
        continue;
      }
      ++hits;
      ASSERT_EQ(want->surface, DropSurface::Cap);
      ASSERT_TRUE(same_bits(out[i].t, want->t)) << out[i].t << " against " << want->t;
      for (int c = 0; c < 3; ++c)
        ASSERT_TRUE(same_bits(out[i].normal[c], want->normal[c])) << out[i].normal[c] << " against " << want->normal[c];
    }
  }
  // Both kinds of answer were asked for, many times.
  EXPECT_GT(hits, lanes / 2);
  EXPECT_GT(misses, lanes / 20);
}

TEST(CapExit, ARayGoingOutThroughTheBaseEntersTheWaterThere) {
  Rng rng(23);
  int checked = 0;
  for (int r = 0; r < 20000; ++r) {
    const GlassPlane glass{rng.uniform(1.0, 100.0), rng.uniform(0.3, M_PI / 2)};
    DropShape shape = cap(rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0), rng.uniform(0.05, 1.5), rng.uniform(5.0, 90.0));
    const Drop drop(shape, glass);
    // From the camera side of the glass (a lens point) to a point of the base.
    const glm::dvec3 origin(rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), 0.0);
    if (!(glass.height(origin) < 0)) continue;  // a steep glass 1 cm away can pass beside the lens
    const glm::dvec3 target = base_point(drop, glass, rng);
    const glm::dvec3 dir = target - origin;
    const auto hit = drop.intersect(origin, dir, 0.0, std::numeric_limits<double>::infinity());
    ASSERT_TRUE(hit.has_value());
    ASSERT_EQ(hit->surface, DropSurface::Base);
    ASSERT_EQ(hit->normal, drop.base_normal());
    // Dry just before, wet just after (a micrometre along the ray either way).
    const double step = 1e-4 / glm::length(dir);
    const glm::dvec3 p = origin + hit->t * dir;
    if (shape.height() < 1e-3) continue;  // thinner than 10 um: too thin to tell at this step
    // Stay away from the rim, where a micrometre can leave the footprint.
    const glm::dvec2 uv = glass.coords(p) - shape.center;
    if (glm::length(uv) > shape.footprint_radius - 1e-3) continue;
    EXPECT_FALSE(drop.contains(p - step * dir));
    EXPECT_TRUE(drop.contains(p + step * dir));
    ++checked;
  }
  EXPECT_GT(checked, 10000);
}

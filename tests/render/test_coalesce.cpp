// Drops that touch coalesce (raindrop/render/coalesce.h): water conserved, centre of mass,
// volume-weighted shape, repeated until no footprints overlap; and the scene option.
#include <cmath>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "raindrop/render/coalesce.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/scene_config.h"
#include "raindrop/render/trails.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

DropShape drop(double u, double v, double a, double tau_deg = 40, double elongation = 1, double flattening = 1) {
  DropShape d;
  d.center = {u, v};
  d.footprint_radius = a;
  d.contact_angle = tau_deg * M_PI / 180;
  d.elongation = elongation;
  d.flattening = flattening;
  return d;
}

double total_volume(const std::vector<DropShape>& drops) {
  double v = 0;
  for (const DropShape& d : drops) v += drop_volume(d);
  return v;
}

bool any_overlap(const std::vector<DropShape>& drops) {
  for (size_t i = 0; i < drops.size(); ++i)
    for (size_t j = i + 1; j < drops.size(); ++j)
      if (glm::length(drops[i].center - drops[j].center) <
          drops[i].footprint_radius * drops[i].elongation + drops[j].footprint_radius * drops[j].elongation)
        return true;
  return false;
}

}  // namespace

// Two equal round drops: one drop midway, the same angle, twice the water, so a footprint
// 2^(1/3) times as wide (a cap's volume goes with a^3 at a fixed angle).
TEST(Coalesce, TwoEqualDropsMakeOneWithTwiceTheWater) {
  const DropShape a = drop(0, 0, 0.2), b = drop(0.3, 0.1, 0.2);
  const DropShape m = merge_drops(a, b);
  EXPECT_NEAR(m.center.x, 0.15, 1e-15);
  EXPECT_NEAR(m.center.y, 0.05, 1e-15);
  EXPECT_NEAR(m.contact_angle, a.contact_angle, 1e-15);
  EXPECT_NEAR(m.footprint_radius, 0.2 * std::cbrt(2.0), 1e-12);
  EXPECT_NEAR(drop_volume(m), 2 * drop_volume(a), 1e-15);
}

// Unequal drops of different shapes: the volume is the sum, the centre and shape the
// volume-weighted means, and the footprint holds exactly that water.
TEST(Coalesce, TheLargerDropWeighsMore) {
  const DropShape a = drop(0, 0, 0.3, 50, 1.2, 0.9), b = drop(0.35, 0, 0.1, 30, 1.0, 1.0);
  const double va = drop_volume(a), vb = drop_volume(b);
  const DropShape m = merge_drops(a, b);
  EXPECT_NEAR(drop_volume(m), va + vb, 1e-14 * (va + vb));
  EXPECT_NEAR(m.center.x, 0.35 * vb / (va + vb), 1e-15);
  EXPECT_NEAR(m.contact_angle, (va * a.contact_angle + vb * b.contact_angle) / (va + vb), 1e-15);
  EXPECT_NEAR(m.elongation, (va * 1.2 + vb * 1.0) / (va + vb), 1e-15);
  EXPECT_NEAR(m.flattening, (va * 0.9 + vb * 1.0) / (va + vb), 1e-15);
  EXPECT_GT(m.footprint_radius, a.footprint_radius);
  EXPECT_EQ(merge_drops(b, a).footprint_radius, m.footprint_radius) << "the order of the two does not matter";
}

// A chain: A touches B, the merged drop reaches C, which did not touch either before; D stands
// apart and is left exactly as it was, in its place after the merged drop.
TEST(Coalesce, MergedDropsThatReachAnotherTakeItIn) {
  // C sits above the gap between A and B, 0.347 from each centre (0.32 would touch), 0.3 from
  // the merged drop's (0.2 2^(1/3) + 0.12 = 0.372 touches).
  std::vector<DropShape> drops = {drop(0, 0, 0.2), drop(0.35, 0, 0.2), drop(0.175, 0.3, 0.12), drop(3, 3, 0.5)};
  ASSERT_GE(glm::length(drops[2].center - drops[0].center), 0.2 + 0.12);
  ASSERT_GE(glm::length(drops[2].center - drops[1].center), 0.2 + 0.12);
  const double water = total_volume(drops);
  const DropShape d = drops[3];
  EXPECT_EQ(coalesce_drops(&drops), 2);
  ASSERT_EQ(drops.size(), 2u);
  EXPECT_NEAR(total_volume(drops), water, 1e-14 * water);
  EXPECT_EQ(drops[1].center, d.center);
  EXPECT_EQ(drops[1].footprint_radius, d.footprint_radius);
  EXPECT_FALSE(any_overlap(drops));
}

// Many random drops: afterwards no two overlap and all the water is still there; drops that
// touch nothing are untouched (no overlap: no merge, bit for bit).
TEST(Coalesce, NoOverlapIsLeftAndNoWaterIsLost) {
  Rng rng(5);
  for (int scene = 0; scene < 50; ++scene) {
    std::vector<DropShape> drops;
    const int n = 20 + scene * 4;
    for (int i = 0; i < n; ++i)
      drops.push_back(drop(rng.uniform(0, 10), rng.uniform(0, 5), rng.uniform(0.05, 0.5), rng.uniform(15, 90),
                           rng.uniform(1, 1.3), rng.uniform(0.8, 1)));
    const double water = total_volume(drops);
    const int merges = coalesce_drops(&drops);
    EXPECT_EQ(static_cast<int>(drops.size()), n - merges);
    EXPECT_FALSE(any_overlap(drops)) << "scene " << scene;
    EXPECT_NEAR(total_volume(drops), water, 1e-12 * water) << "scene " << scene;
    for (const DropShape& d : drops) {
      EXPECT_TRUE(std::isfinite(d.footprint_radius) && d.footprint_radius > 0);
      EXPECT_GT(d.contact_angle, 0);
      EXPECT_LE(d.contact_angle, M_PI / 2);
    }
  }
  // As many drops as a scene may ask for, piled on a small patch of glass: they end as a few
  // (the merge loop ends, and fast: each check of a drop is one pass over the others).
  std::vector<DropShape> pile;
  for (int i = 0; i < kMaxDropCount; ++i) pile.push_back(drop(rng.uniform(0, 3), rng.uniform(0, 3), 0.1));
  const double water = total_volume(pile);
  coalesce_drops(&pile);
  EXPECT_LT(pile.size(), 100u) << "1000 drops piled up should end as a few";
  EXPECT_FALSE(any_overlap(pile));
  EXPECT_NEAR(total_volume(pile), water, 1e-12 * water);
  std::vector<DropShape> apart = {drop(0, 0, 0.1), drop(1, 0, 0.1)};
  EXPECT_EQ(coalesce_drops(&apart), 0);
  EXPECT_EQ(apart[1].center, glm::dvec2(1, 0));
}

// In a scene: a lens-cover scene that overlaps drops, with coalesce, samples drops of which no
// two overlap, fewer and larger than without it, and holds the same water (the same placements
// before merging: coalescing draws nothing).
TEST(Coalesce, AScenesOverlappingDropsMerge) {
  SceneConfig c = scene_preset("lens-cover-merged");
  ASSERT_TRUE(c.allow_overlap);
  c.outline.enabled = false;  // drawn after the merge: would change the comparison of volumes
  c.trails.enabled = false;
  SceneConfig merged = c;
  merged.coalesce = true;
  const Camera cam = camera(512, 256, 283);
  int fewer = 0;
  for (std::uint64_t seed = 0; seed < 10; ++seed) {
    Rng r1(seed), r2(seed);
    const SceneSample a = sample_scene(c, cam, r1), b = sample_scene(merged, cam, r2);
    EXPECT_NEAR(total_volume(b.drops), total_volume(a.drops), 1e-12 * total_volume(a.drops)) << seed;
    EXPECT_FALSE(any_overlap(b.drops)) << seed;
    EXPECT_LE(b.drops.size(), a.drops.size());
    fewer += b.drops.size() < a.drops.size();
  }
  EXPECT_GT(fewer, 5) << "the preset's drops should overlap in most samples";
  const SceneConfig round_trip = parse_scene_json(scene_to_json(merged), "round trip");
  EXPECT_TRUE(round_trip.coalesce);
}

// The drop acceleration structure's shortcut for rays leaving a drop: it says "nothing more
// to meet" only when no other drop is met (checked against every drop, brute force), it does
// say so for most rays that leave a drop in a real scene, and tracing with it gives the same
// images, bit for bit, as querying every exit.
#include <cstring>
#include <limits>
#include <optional>
#include <vector>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "raindrop/common/rng.h"
#include "raindrop/render/drop_accel.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/tracer.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

TEST(ExitSkip, SaysNothingMoreOnlyWhenNoOtherDropIsMet) {
  const Camera cam = camera(640, 320, 700);
  std::int64_t skipped = 0, met = 0, rays = 0;
  for (std::uint64_t seed : {1, 2, 3}) {
    const SceneSample scene = crowded_scene(seed, cam);
    const std::vector<Drop> drops = drops_of(scene);
    const DropAccel accel(drops, GeometryOptions{});
    Rng rng(seed + 100);
    for (int r = 0; r < 20000; ++r) {
      // A point on a drop's cap and a direction out of the water there (rays leave a cap
      // outwards), going some way through the drops' layer.
      const int i = rng.uniform_int(0, static_cast<int>(drops.size()) - 1);
      const Drop& drop = drops[i];
      const glm::dvec3 o = drop.cap_point(rng.uniform() * drop.shape().contact_angle, 2 * M_PI * rng.uniform());
      const glm::dvec3 n = drop.cap_normal(o);
      glm::dvec3 d;
      do {
        d = glm::dvec3(rng.uniform() * 2 - 1, rng.uniform() * 2 - 1, rng.uniform() * 2 - 1);
      } while (glm::length(d) > 1 || glm::length(d) < 1e-3 || glm::dot(d, n) <= 0);
      d = glm::normalize(d);
      const double t_max = rng.uniform() < 0.5 ? rng.uniform() * accel.max_height() * 3 : rng.uniform() * 2.0;
      bool hit = false;
      for (size_t j = 0; j < drops.size() && !hit; ++j)
        hit = static_cast<int>(j) != i && drops[j].intersect(o, d, 0.0, t_max).has_value();
      const bool may = accel.may_meet_after_exit(i, o, d, t_max);
      ++rays;
      met += hit;
      skipped += !may;
      ASSERT_TRUE(may || !hit) << "seed " << seed << " ray " << r << ": skipped a ray that meets another drop";
    }
  }
  // Not vacuous: some leaving rays do meet a neighbour here, and most are still skipped.
  EXPECT_GT(met, 100);
  EXPECT_GT(skipped, rays / 2);
}

TEST(ExitSkip, OnlyForExactCapsOfCircularOutlineAndCanBeTurnedOff) {
  const GlassPlane glass = upright_glass(10);
  const std::vector<Drop> drops = {Drop(cap(0, 0, 0.2, 60), glass), Drop(cap(3, 0, 0.2, 60), glass)};
  const glm::dvec3 o = drops[0].cap_point(0, 0);  // the apex, leaving along the glass's normal
  const glm::dvec3 away = glass.normal();
  const glm::dvec3 towards = glm::normalize(drops[1].cap_point(0, 0) - o);
  DropAccel exact(drops, GeometryOptions{});
  EXPECT_FALSE(exact.may_meet_after_exit(0, o, away, 0.5));
  EXPECT_TRUE(exact.may_meet_after_exit(0, o, towards, 10.0));  // reaches the other drop
  EXPECT_FALSE(exact.may_meet_after_exit(0, o, towards, 1.0));  // stops short of it
  exact.set_exit_skip(false);
  EXPECT_TRUE(exact.may_meet_after_exit(0, o, away, 0.5));
  const DropAccel mesh(drops, GeometryOptions::parse("mesh-32-smooth"));
  EXPECT_TRUE(mesh.may_meet_after_exit(0, o, away, 0.5));
}

// Whatever the effects, the images traced with the shortcut are those traced with a query
// for every ray that leaves a drop.
TEST(ExitSkip, TracedImagesAreTheSameBitForBit) {
  const Camera cam = camera(320, 160, 353);
  const cv::Mat clean = random_frame(cam);
  int scenes = 0;
  for (const char* preset : {"paper", "full-physics", "lens-cover", "lens-cover-merged", "windshield-day"}) {
    for (std::uint64_t seed : {1, 2, 3}) {
      SceneConfig c = scene_preset(preset);
      SceneSample scene;
      if (std::string(preset) == "paper" && seed == 3) {
        scene = crowded_scene(seed, cam);
      } else {
        Rng rng(seed);
        scene = sample_scene(c, cam, rng);
      }
      const std::vector<Drop> drops = drops_of(scene);
      DropAccel with(drops, c.geometry), without(drops, c.geometry);
      with.set_disjoint(c.drops_disjoint());
      without.set_disjoint(c.drops_disjoint());
      without.set_exit_skip(false);
      const TraceResult a = trace_drops(clean, cam, c, scene, with);
      const TraceResult b = trace_drops(clean, cam, c, scene, without);
      ASSERT_GT(a.stats.drop_pixels, 0) << preset << " seed " << seed;
      EXPECT_TRUE(equal_bits(a.label, b.label)) << preset << " seed " << seed;
      // Colours only where a drop was met (elsewhere the buffer is not written).
      cv::Mat ca = a.color.clone(), cb = b.color.clone();
      ca.setTo(cv::Scalar::all(0), a.label < 0);
      cb.setTo(cv::Scalar::all(0), b.label < 0);
      EXPECT_TRUE(equal_bits(ca, cb)) << preset << " seed " << seed;
      ++scenes;
    }
  }
  EXPECT_EQ(scenes, 15);
}

// A packet query answers each ray as a single-ray query does: same drop, surface, distance
// and normal, bit for bit, for rays from the camera through every pixel of a frame (packets
// of 1 to 8 rays; on every other row each ray from its own point of the lens), on scenes with overlapping, merged and irregular drops; and for exact caps
// that answer is the nearest of every drop's own (where merged caps cross, two drops are met
// within a float's rounding, and the order Embree visits them in must not decide).
TEST(PacketQuery, AnswersEachRayAsASingleQueryDoes) {
  const Camera cam = camera(160, 80, 176);
  int hits = 0;
  for (const char* preset : {"paper", "lens-cover-merged", "full-physics"}) {
    for (std::uint64_t seed : {1, 2}) {
      const SceneConfig c = scene_preset(preset);
      Rng rng(seed);
      const SceneSample scene = sample_scene(c, cam, rng);
      const std::vector<Drop> drops = drops_of(scene);
      const DropAccel accel(drops, c.geometry);
      for (int y = 0; y < cam.height; ++y) {
        for (int x0 = 0; x0 < cam.width;) {
          const int n = std::min(1 + (x0 + y) % 8, cam.width - x0);
          glm::dvec3 origins[8], dirs[8];
          double t_min[8], t_max[8];
          // Odd rows: every ray from its own point of a 1 cm aperture (trace_aperture's packets).
          const bool own_origins = y % 2 == 1;
          for (int i = 0; i < n; ++i) {
            origins[i] = own_origins ? glm::dvec3(0.4 * std::cos(2.1 * i), 0.4 * std::sin(2.1 * i), 0.0) : glm::dvec3(0.0);
            dirs[i] = glm::normalize(cam.ray_direction(x0 + i, y));
            t_min[i] = 0.5 * (i % 3);
            t_max[i] = i % 4 == 3 ? 1e3 : std::numeric_limits<double>::infinity();
          }
          std::optional<DropHit> packet[8];
          accel.intersect_packet(origins, dirs, t_min, t_max, n, packet);
          for (int i = 0; i < n; ++i) {
            const auto one = accel.intersect(origins[i], dirs[i], nullptr, t_min[i], t_max[i]);
            ASSERT_EQ(one.has_value(), packet[i].has_value()) << preset << " " << x0 + i << "," << y;
            if (c.geometry.kind == GeometryOptions::Kind::Exact) {
              // The nearest of every drop's own answer (a tie: the lower index).
              std::optional<SurfaceHit> nearest;
              int nearest_drop = -1;
              for (size_t j = 0; j < drops.size(); ++j) {
                const auto h = drops[j].intersect(origins[i], dirs[i], t_min[i], t_max[i]);
                if (h && (!nearest || h->t < nearest->t)) nearest = h, nearest_drop = static_cast<int>(j);
              }
              ASSERT_EQ(one.has_value(), nearest.has_value()) << preset << " " << x0 + i << "," << y;
              if (one) {
                ASSERT_EQ(one->drop, nearest_drop) << preset << " " << x0 + i << "," << y;
                ASSERT_EQ(one->t, nearest->t);
              }
            }
            if (!one) continue;
            ++hits;
            ASSERT_EQ(one->drop, packet[i]->drop) << preset << " " << x0 + i << "," << y;
            ASSERT_EQ(one->t, packet[i]->t);
            ASSERT_EQ(one->surface, packet[i]->surface);
            ASSERT_EQ(one->normal, packet[i]->normal);
          }
          x0 += n;
        }
      }
    }
  }
  EXPECT_GT(hits, 1000);
}

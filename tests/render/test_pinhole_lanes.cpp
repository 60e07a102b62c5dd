// The pinhole pass in SIMD lanes (pinhole_lanes.h) against the same rays traced one at a time.
#include <algorithm>
#include <cstring>
#include <iostream>
#include <string>

#include <gtest/gtest.h>

#include "raindrop/common/rng.h"
#include "raindrop/render/aperture_reach.h"
#include "raindrop/render/pinhole_lanes.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene_config.h"
#include "raindrop/render/tracer.h"
#include "support.h"

namespace raindrop {
namespace {

using namespace test;

// Forces the lanes' register width for the guard's lifetime (the widest again after it, even
// when an assertion ends the test early).
struct ForcedLevel {
  explicit ForcedLevel(int level) { PinholeLanes::force_level(level); }
  ~ForcedLevel() { PinholeLanes::force_level(-1); }
};

#define SKIP_WITHOUT_LANES() \
  if (!PinholeLanes::available()) GTEST_SKIP() << "this build has no SIMD lanes (GCC on x86-64 only)"

// Scenes the lanes take: every preset whose drops are disjoint circular caps, crowded glass
// (neighbours in reach of leaving rays, caps met from outside), traced internal reflection,
// and random glass tilts and contact angles up to 90 degrees.
std::vector<NamedScene> lane_cases(const Camera& cam) {
  std::vector<NamedScene> cases = preset_scenes(cam);
  for (std::uint64_t seed : {1, 2, 3}) {
    SceneConfig c = scene_preset("paper");
    cases.push_back({"crowded seed " + std::to_string(seed), c, crowded_scene(seed, cam)});
    c.tir = TirMode::Trace;
    cases.push_back({"crowded, internal reflection traced, seed " + std::to_string(seed), c, crowded_scene(seed, cam)});
  }
  Rng pick(99);
  for (int i = 0; i < 24; ++i) {
    SceneConfig c = scene_preset("paper");
    const double tilt = pick.uniform(0.0, 85.0), angle = pick.uniform(5.0, 90.0);
    c.tilt_deg = {tilt, tilt};
    c.contact_angle_deg = {angle, std::min(90.0, angle + 10)};
    c.glass_distance_cm = {pick.uniform(2.0, 60.0), 80.0};
    c.drop_count = {20, 200};
    if (i % 3 == 1) c.tir = TirMode::Trace;
    Rng rng(1000 + static_cast<std::uint64_t>(i));
    cases.push_back({"random " + std::to_string(i), c, sample_scene(c, cam, rng)});
  }
  return cases;
}

// What the lanes gave ray i of `row` against what trace_path gave it, `w`, to the bit: a Miss
// meets no drop (counted in *misses), a Path ends where w ends (counted in *paths; Alone is not
// compared). Returns false where a Path's direction differs (the caller stops: the rest would
// differ too). `where()` names the ray in a failure's message.
template <class Where>
bool same_outcome(const PinholeLanes::Row& row, int i, const DropPath& w, const Camera& cam, double background_z,
                  const Where& where, std::int64_t* paths, std::int64_t* misses) {
  if (row.outcome[i] == PinholeLanes::Outcome::Alone) return true;
  if (row.outcome[i] == PinholeLanes::Outcome::Miss) {
    ++*misses;
    EXPECT_FALSE(w.hit) << where();
    return true;
  }
  ++*paths;
  const DropPath got = row.path(i);
  EXPECT_TRUE(w.hit) << where();
  if (!w.hit) return false;
  EXPECT_EQ(got.first_drop, w.first_drop) << where();
  EXPECT_EQ(got.dark, w.dark) << where();
  EXPECT_EQ(got.escaped_in, w.escaped_in) << where();
  EXPECT_EQ(got.events, w.events) << where();
  EXPECT_EQ(std::memcmp(&got.transmittance, &w.transmittance, sizeof got.transmittance), 0) << where();
  EXPECT_EQ(std::memcmp(&got.origin, &w.origin, sizeof got.origin), 0) << where();
  EXPECT_EQ(std::memcmp(&got.dir, &w.dir, sizeof got.dir), 0) << where();
  if (std::memcmp(&got.dir, &w.dir, sizeof got.dir) != 0) return false;
  if (w.dark || w.escaped_in) return true;
  const glm::dvec2 seen = background_pixel(w, cam, background_z);
  EXPECT_EQ(std::memcmp(&row.seen_x[i], &seen.x, sizeof seen.x), 0) << where();
  EXPECT_EQ(std::memcmp(&row.seen_y[i], &seen.y, sizeof seen.y), 0) << where();
  return true;
}

// same_outcome's counts per register width: on every width both a Path and a Miss were
// compared often enough for the comparison to hold something.
void expect_many_of_each(const std::vector<std::int64_t>& paths, const std::vector<std::int64_t>& misses) {
  for (size_t level = 0; level < paths.size(); ++level) {
    EXPECT_GT(paths[level], 20000) << "level " << level;
    EXPECT_GT(misses[level], 2000) << "level " << level;
  }
}

// For every register width the processor has, the lanes' images are the one-ray-at-a-time
// images to the bit, and they do trace most rays that meet a drop where the dark band is
// black (else this test would hold nothing).
TEST(PinholeLanes, EveryRegisterWidthTracesWhatOneRayAtATimeTraces) {
  SKIP_WITHOUT_LANES();
  const Camera cam = camera(240, 120, 265);
  const cv::Mat clean = random_frame(cam);
  const std::vector<NamedScene> cases = lane_cases(cam);
  int applied = 0;
  const int widest = PinholeLanes::level();
  for (int level = 0; level <= widest; ++level) {
    const ForcedLevel forced(level);
    std::cerr << "register width " << level << " (0 SSE2, 1 AVX2, 2 AVX-512)\n";
    applied = 0;
    std::int64_t drop_pixels = 0, lane_pixels = 0;
    for (const NamedScene& k : cases) {
      const std::vector<Drop> drops = drops_of(k.scene);
      DropAccel accel(drops, k.config.geometry);
      accel.set_disjoint(k.config.drops_disjoint());
      // The lanes take the kernels without dispersion.
      if (!PinholeLanes::applies(accel) || k.config.dispersion.enabled) continue;
      ++applied;
      const TraceResult a = trace_drops(clean, cam, k.config, k.scene, accel, nullptr, TraceStrategy{true, true});
      const TraceResult b = trace_drops(clean, cam, k.config, k.scene, accel, nullptr, TraceStrategy{false, false});
      const std::string name = k.name + ", level " + std::to_string(level);
      EXPECT_TRUE(equal_bits(a.label, b.label)) << name;
      cv::Mat ca = a.color.clone(), cb = b.color.clone();
      ca.setTo(cv::Scalar::all(0), a.label < 0);
      cb.setTo(cv::Scalar::all(0), b.label < 0);
      EXPECT_TRUE(equal_bits(ca, cb)) << name;
      EXPECT_EQ(a.stats.drop_pixels, b.stats.drop_pixels) << name;
      EXPECT_EQ(a.stats.dark_band_pixels, b.stats.dark_band_pixels) << name;
      EXPECT_EQ(a.stats.off_frame_pixels, b.stats.off_frame_pixels) << name;
      EXPECT_EQ(b.stats.lockstep_pixels, 0) << name;
      EXPECT_EQ(b.stats.lane_pixels, 0) << name;
      // On the presets' glass, with the dark band painted black, nearly every ray takes the
      // common path (crowded glass, steep random scenes and a heavy lens cover's large drops,
      // whose leaving rays often have a neighbour in reach, send many elsewhere).
      if (k.config.tir == TirMode::Black && k.name.find("crowded") == std::string::npos &&
          k.name.find("random") == std::string::npos && k.name.find("heavy") == std::string::npos) {
        drop_pixels += a.stats.drop_pixels;
        lane_pixels += a.stats.lane_pixels;
      }
    }
    EXPECT_GT(lane_pixels, drop_pixels * 95 / 100) << "level " << level;
  }
  EXPECT_GE(applied, 30);
}

// Each ray the lanes trace ends where trace_path ends it, to the bit (origin, direction,
// events, transmittance, dark band, escape into the car, the background point seen), and each
// ray they call a miss meets no drop; rows are given the tracer's own spans per drop.
TEST(PinholeLanes, EachPathIsTracePathsToTheBit) {
  SKIP_WITHOUT_LANES();
  // An odd width: spans end in partly filled registers on every width.
  const Camera cam = camera(163, 80, 180);
  const std::vector<NamedScene> cases = lane_cases(cam);
  const int widest = PinholeLanes::level();
  std::vector<std::int64_t> paths(widest + 1, 0), misses(widest + 1, 0);
  std::int64_t outside = 0;
  for (const NamedScene& k : cases) {
    const std::vector<Drop> drops = drops_of(k.scene);
    DropAccel accel(drops, k.config.geometry);
    accel.set_disjoint(k.config.drops_disjoint());
    if (!PinholeLanes::applies(accel)) continue;
    const double n = k.config.channel_indices().y;
    std::vector<DropPath> want(static_cast<size_t>(cam.width * cam.height));
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x)
        want[y * cam.width + x] = trace_through_drops(glm::dvec3(0.0), cam.ray_direction(x, y), n, k.config.tir,
                                                      k.config.fresnel.enabled, accel, k.scene.glass);
    // The tracer's own spans, per drop: a pixel outside all of them must meet no drop (the
    // lanes never look there), and a pixel in some drops' spans only is traced against those.
    const std::vector<std::vector<DropSpan>> spans = drop_candidate_spans(cam, accel);
    for (int y = 0; y < cam.height; ++y) {
      std::vector<char> covered(cam.width, 0);
      for (const DropSpan& s : spans[y]) std::fill(covered.begin() + s.first, covered.begin() + s.last + 1, 1);
      for (int x = 0; x < cam.width; ++x) {
        if (covered[x]) continue;
        ++outside;
        EXPECT_FALSE(want[y * cam.width + x].hit) << k.name << ": pixel " << x << "," << y << " outside every span";
      }
    }
    for (int level = 0; level <= widest; ++level) {
      const ForcedLevel forced(level);
      const PinholeLanes lanes(cam, accel, k.scene.glass, k.scene.background_distance_cm, n, k.config.tir,
                               k.config.fresnel.enabled);
      PinholeLanes::Row row;
      for (int y = 0; y < cam.height; ++y) {
        if (spans[y].empty()) continue;
        lanes.trace_row(y, spans[y], &row);
        for (const DropSpan& s : spans[y]) {
          for (int x = s.first; x <= s.last; ++x) {
            const auto where = [&] {
              return k.name + ", level " + std::to_string(level) + ", pixel " + std::to_string(x) + "," + std::to_string(y);
            };
            ASSERT_TRUE(same_outcome(row, x, want[y * cam.width + x], cam, k.scene.background_distance_cm, where,
                                     &paths[level], &misses[level]));
          }
        }
      }
    }
  }
  EXPECT_GT(outside, 100000);
  expect_many_of_each(paths, misses);
}

// The lanes and the side-by-side path without them agree too (the lanes replace both the
// Embree packet query and trace_through_one_drop).
TEST(PinholeLanes, TraceWhatTheSideBySidePathTraces) {
  SKIP_WITHOUT_LANES();
  const Camera cam = camera(320, 160, 353);
  const cv::Mat clean = random_frame(cam);
  for (std::uint64_t seed : {4, 5}) {
    const SceneConfig c = scene_preset("paper");
    const SceneSample scene = crowded_scene(seed, cam);
    const std::vector<Drop> drops = drops_of(scene);
    DropAccel accel(drops, c.geometry);
    accel.set_disjoint(true);
    const TraceResult a = trace_drops(clean, cam, c, scene, accel, nullptr, TraceStrategy{true, true});
    const TraceResult b = trace_drops(clean, cam, c, scene, accel, nullptr, TraceStrategy{true, false});
    ASSERT_GT(a.stats.drop_pixels, 1000);
    EXPECT_TRUE(equal_bits(a.label, b.label)) << seed;
    cv::Mat ca = a.color.clone(), cb = b.color.clone();
    ca.setTo(cv::Scalar::all(0), a.label < 0);
    cb.setTo(cv::Scalar::all(0), b.label < 0);
    EXPECT_TRUE(equal_bits(ca, cb)) << seed;
  }
}

// Rays origins[i] + t raw[i], i < n, traced in the lanes against `near` (directions normalised as
// trace_packet normalises them), each outcome compared with trace_path's (same_outcome;
// `where(i)` names ray i). Returns false where a comparison stopped.
template <class Where>
bool lane_rays_are_trace_paths(const PinholeLanes& lanes, const NamedScene& k, const DropAccel& accel, const Camera& cam,
                               double background_z, const glm::dvec3* origins, const glm::dvec3* raw, int n,
                               const std::vector<int>& near, const Where& where, std::int64_t* paths,
                               std::int64_t* misses) {
  // Padded to whole registers with the last ray, as the tracer pads them (the lanes read them).
  const int padded = (n + 7) / 8 * 8;
  std::vector<double> arrays[6];
  for (auto& v : arrays) v.resize(static_cast<size_t>(padded));
  for (int j = 0; j < padded; ++j) {
    const int i = std::min(j, n - 1);
    const glm::dvec3 d = glm::normalize(raw[i]);
    arrays[0][j] = origins[i].x, arrays[1][j] = origins[i].y, arrays[2][j] = origins[i].z;
    arrays[3][j] = d.x, arrays[4][j] = d.y, arrays[5][j] = d.z;
  }
  const lanes_detail::RayArrays rays{arrays[0].data(), arrays[1].data(), arrays[2].data(),
                                     arrays[3].data(), arrays[4].data(), arrays[5].data()};
  PinholeLanes::Row row;
  lanes.trace_rays(rays, n, near, &row);
  const double n_water = k.config.channel_indices().y;
  for (int i = 0; i < n; ++i) {
    if (row.outcome[i] == PinholeLanes::Outcome::Alone) continue;
    const DropPath w =
        trace_through_drops(origins[i], raw[i], n_water, k.config.tir, k.config.fresnel.enabled, accel, k.scene.glass);
    if (!same_outcome(row, i, w, cam, background_z, [&] { return where(i); }, paths, misses)) return false;
  }
  return true;
}

// The lane cases' scenes the lanes take, each at every register width the processor has:
// fn(k, drops, accel, lanes, reach, level), with the lanes' background and the reach's focus on
// the background plane and the reach for a lens disk of `radius`. Stops at a fatal failure.
template <class Fn>
void at_every_width_of_each_lane_case(const Camera& cam, double radius, const Fn& fn) {
  for (const NamedScene& k : lane_cases(cam)) {
    const std::vector<Drop> drops = drops_of(k.scene);
    DropAccel accel(drops, k.config.geometry);
    accel.set_disjoint(k.config.drops_disjoint());
    if (!PinholeLanes::applies(accel)) continue;
    const double F = k.scene.background_distance_cm;
    const ApertureReach reach(drops, radius, F);
    for (int level = 0; level <= PinholeLanes::level(); ++level) {
      const ForcedLevel forced(level);
      const PinholeLanes lanes(cam, accel, k.scene.glass, F, k.config.channel_indices().y, k.config.tir,
                               k.config.fresnel.enabled);
      fn(k, drops, accel, lanes, reach, level);
      if (::testing::Test::HasFatalFailure()) return;
    }
  }
}

// An aperture pixel's rays (trace_rays: any origins, the drops the pixel's cone meets): each
// ray the lanes trace ends where trace_path ends it, to the bit, and each they call a miss
// meets no drop; every register width, the lane cases' scenes seen through a 0.6 cm aperture
// focused on the background, 16 rays a pixel from random points of the disk (its rim among them).
TEST(PinholeLanes, EachApertureRayPathIsTracePathsToTheBit) {
  SKIP_WITHOUT_LANES();
  const Camera cam = camera(163, 80, 180);
  const int widest = PinholeLanes::level();
  std::vector<std::int64_t> paths(widest + 1, 0), misses(widest + 1, 0);
  constexpr int kRays = 16;
  constexpr double kRadius = 0.3;
  at_every_width_of_each_lane_case(cam, kRadius, [&](const NamedScene& k, const std::vector<Drop>& drops,
                                                     const DropAccel& accel, const PinholeLanes& lanes,
                                                     const ApertureReach& reach, int level) {
    const double F = k.scene.background_distance_cm;
    Rng rng(17);
    for (int y = 0; y < cam.height; y += 3) {
      for (int x = 0; x < cam.width; x += 3) {
        const glm::dvec3 focus = F * cam.ray_direction(x, y);
        std::vector<int> near;
        for (int d = 0; d < static_cast<int>(drops.size()); ++d)
          if (reach.cone_meets(d, focus)) near.push_back(d);
        if (near.empty()) continue;
        glm::dvec3 origins[kRays], raw[kRays];
        for (int i = 0; i < kRays; ++i) {
          const double angle = rng.uniform(0.0, 2 * M_PI), rho = i % 4 == 0 ? kRadius : kRadius * std::sqrt(rng.uniform());
          origins[i] = glm::dvec3(rho * std::cos(angle), rho * std::sin(angle), 0.0);
          raw[i] = focus - origins[i];
        }
        const auto where = [&](int i) {
          return k.name + ", level " + std::to_string(level) + ", pixel " + std::to_string(x) + "," +
                 std::to_string(y) + ", ray " + std::to_string(i);
        };
        ASSERT_TRUE(lane_rays_are_trace_paths(lanes, k, accel, cam, F, origins, raw, kRays, near, where, &paths[level],
                                              &misses[level]));
      }
    }
  });
  expect_many_of_each(paths, misses);
}

// Rays aimed at a drop's rim, just inside it, on it and just outside it (a billionth and a few
// units in the last place of the footprint's radius either way), where the lanes' first-hit
// test skips the registers whose lines clearly miss the drop's sphere: each ray the lanes trace
// ends where trace_path ends it and each they call a miss meets no drop, on every register
// width; the lane cases' scenes (contact angles up to 90 degrees, where the rim is the sphere's
// widest circle).
TEST(PinholeLanes, RaysAtADropsRimMeetWhatTracePathMeets) {
  SKIP_WITHOUT_LANES();
  const Camera cam = camera(163, 80, 180);
  const int widest = PinholeLanes::level();
  std::vector<std::int64_t> paths(widest + 1, 0), misses(widest + 1, 0);
  constexpr int kRays = 16;
  const double scales[] = {1 - 1e-9, 1 - 4e-16, 1, 1 + 4e-16, 1 + 1e-9};
  at_every_width_of_each_lane_case(cam, 0.3, [&](const NamedScene& k, const std::vector<Drop>& drops,
                                                 const DropAccel& accel, const PinholeLanes& lanes,
                                                 const ApertureReach& reach, int level) {
    Rng rng(23);
    for (size_t d = 0; d < drops.size(); ++d) {
      glm::dvec3 origins[kRays], raw[kRays];
      std::vector<int> near;
      for (int i = 0; i < kRays; ++i) {
        const double angle = rng.uniform(0.0, 2 * M_PI), rho = 0.3 * std::sqrt(rng.uniform());
        origins[i] = glm::dvec3(rho * std::cos(angle), rho * std::sin(angle), 0.0);
        const glm::dvec3 c = drops[d].centre();
        const glm::dvec3 rim = drops[d].cap_point(drops[d].shape().contact_angle, rng.uniform(0.0, 2 * M_PI));
        raw[i] = c + scales[i % 5] * (rim - c) - origins[i];
        for (int e = 0; e < static_cast<int>(drops.size()); ++e)
          if (reach.ray_meets(e, origins[i], raw[i]) && std::find(near.begin(), near.end(), e) == near.end())
            near.push_back(e);
      }
      const auto where = [&](int i) {
        return k.name + ", level " + std::to_string(level) + ", drop " + std::to_string(d) + ", ray " + std::to_string(i);
      };
      ASSERT_TRUE(lane_rays_are_trace_paths(lanes, k, accel, cam, k.scene.background_distance_cm, origins, raw, kRays,
                                            near, where, &paths[level], &misses[level]));
    }
  });
  expect_many_of_each(paths, misses);
}

// A drop of 1 degree contact angle: its base disk (radius a, set apart from the sphere's radius
// and centre height) reaches about 1.6e-13 a past the sphere in doubles, so a line may cross the
// base just inside the rim and miss the sphere. The first-hit test's skip must leave such a line
// to the full test, however near its origin: this ray, 0.002 cm before the rim (found by a
// review), was a miss in the lanes and a base hit for Embree, Drop::intersect and trace_path.
TEST(PinholeLanes, ALineThroughAFlatDropsBaseBesideItsSphereIsNotSkipped) {
  SKIP_WITHOUT_LANES();
  NamedScene k;
  k.name = "1-degree drop";
  k.config = scene_preset("paper");
  k.scene.glass = upright_glass(1.0);
  k.scene.drops = {cap(0, 0, 1.0, 1.0)};
  const std::vector<Drop> drops = drops_of(k.scene);
  DropAccel accel(drops, k.config.geometry);
  accel.set_disjoint(true);
  ASSERT_TRUE(PinholeLanes::applies(accel));
  const Camera cam = camera(100, 100, 100);
  const glm::dvec3 origin(1.001999695390231, 2.137303368083617e-21, 0.9999650951871254);
  const glm::dvec3 dir(-0.99984769515639127, -1.0686516840418084e-18, 0.017452406437282086);
  const DropPath want = trace_through_drops(origin, dir, k.config.channel_indices().y, k.config.tir,
                                            k.config.fresnel.enabled, accel, k.scene.glass);
  ASSERT_TRUE(want.hit);
  std::int64_t paths = 0, misses = 0;
  for (int level = 0; level <= PinholeLanes::level(); ++level) {
    const ForcedLevel forced(level);
    const PinholeLanes lanes(cam, accel, k.scene.glass, 1000, k.config.channel_indices().y, k.config.tir,
                             k.config.fresnel.enabled);
    const auto where = [&](int) { return "level " + std::to_string(level); };
    EXPECT_TRUE(lane_rays_are_trace_paths(lanes, k, accel, cam, 1000, &origin, &dir, 1, {0}, where, &paths, &misses));
  }
  EXPECT_EQ(misses, 0);
}

// The aperture reference with its rays in the lanes renders what it renders with every ray
// traced alone, on every register width, and the lanes do take most of the rays that meet a
// drop on windshield glass with the dark band black.
TEST(PinholeLanes, EveryRegisterWidthRendersTheApertureReferenceAsOneRayAtATime) {
  SKIP_WITHOUT_LANES();
  const Camera cam = camera(160, 80, 176);
  const cv::Mat clean = random_frame(cam);
  const int widest = PinholeLanes::level();
  for (int level = 0; level <= widest; ++level) {
    const ForcedLevel forced(level);
    std::int64_t windshield_rays = 0, windshield_in_lanes = 0;
    int compared = 0;
    for (const char* preset : {"lens-cover", "lens-cover-heavy", "windshield-day", "windshield-night", "real-photo",
                               "glass-plate"}) {
      for (int variant = 0; variant < 3; ++variant) {
        SceneConfig c = scene_preset(preset);
        c.fresnel.enabled = variant != 0;
        if (variant == 2) c.tir = TirMode::Trace;
        Rng rng(23 + variant);
        const SceneSample scene = sample_scene(c, cam, rng);
        const std::vector<Drop> drops = drops_of(scene);
        DropAccel accel(drops, c.geometry);
        accel.set_disjoint(c.drops_disjoint());
        const ApertureResult a = trace_aperture(clean, cam, c, scene, accel, 16, nullptr, TraceStrategy{});
        const ApertureResult b = trace_aperture(clean, cam, c, scene, accel, 16, nullptr, TraceStrategy{false, false});
        const std::string name = std::string(preset) + " variant " + std::to_string(variant) + ", level " + std::to_string(level);
        ASSERT_GT(cv::countNonZero(b.coverage), 0) << name;
        EXPECT_EQ(b.lane_rays, 0) << name;
        EXPECT_TRUE(equal_bits(a.coverage, b.coverage)) << name;
        EXPECT_TRUE(equal_bits(a.linear, b.linear)) << name;
        if (std::string(preset) == "windshield-day" && c.tir == TirMode::Black) {
          // The rays that met a drop: coverage is their share of the pixel's 16.
          windshield_rays += std::llround(cv::sum(a.coverage)[0] * 16);
          windshield_in_lanes += a.lane_rays;
        }
        ++compared;
      }
    }
    EXPECT_EQ(compared, 18);
    EXPECT_GT(windshield_in_lanes, windshield_rays * 9 / 10) << "level " << level;
  }
}

// The layered path's drops in focus, traced through the aperture (LensTrace), give with their
// rays in the lanes what they give with every ray alone, on every register width, and the lanes
// take a good share of those rays: glass-droplets scenes (the lens focused on the glass), every drop
// sampled and every other one, 16 and 9 rays a pixel, with and without Fresnel.
TEST(PinholeLanes, EveryRegisterWidthTracesTheDropsInFocusAsOneRayAtATime) {
  SKIP_WITHOUT_LANES();
  const Camera cam = camera(160, 80, 176);
  const cv::Mat clean = random_frame(cam);
  const int widest = PinholeLanes::level();
  for (int level = 0; level <= widest; ++level) {
    const ForcedLevel forced(level);
    std::int64_t sampled = 0, in_lanes = 0;
    for (int variant = 0; variant < 4; ++variant) {
      SceneConfig c = scene_preset("glass-droplets");
      c.fresnel.enabled = variant % 2 == 0;
      Rng rng(31 + variant);
      const SceneSample scene = sample_scene(c, cam, rng);
      const std::vector<Drop> drops = drops_of(scene);
      DropAccel accel(drops, c.geometry);
      accel.set_disjoint(c.drops_disjoint());
      ASSERT_TRUE(PinholeLanes::applies(accel));
      LensTrace lens;
      lens.samples = variant < 2 ? 16 : 9;
      lens.sampled.assign(drops.size(), 1);
      if (variant == 3)
        for (size_t d = 0; d < drops.size(); d += 2) lens.sampled[d] = 0;
      const TraceResult a = trace_drops(clean, cam, c, scene, accel, nullptr, TraceStrategy{}, &lens);
      const TraceResult b = trace_drops(clean, cam, c, scene, accel, nullptr, TraceStrategy{false, false}, &lens);
      const std::string name = "variant " + std::to_string(variant) + ", level " + std::to_string(level);
      ASSERT_GT(a.stats.lens_sampled_pixels, 0) << name;
      EXPECT_EQ(b.stats.lens_lane_rays, 0) << name;
      EXPECT_TRUE(equal_bits(a.label, b.label)) << name;
      EXPECT_TRUE(equal_bits(a.coverage, b.coverage)) << name;
      cv::Mat ca = a.color.clone(), cb = b.color.clone();
      ca.setTo(cv::Scalar::all(0), a.label < 0);
      cb.setTo(cv::Scalar::all(0), b.label < 0);
      EXPECT_TRUE(equal_bits(ca, cb)) << name;
      sampled += a.stats.lens_sampled_pixels * lens.samples;
      in_lanes += a.stats.lens_lane_rays;
    }
    // 15% here: most of the other rays, from the pixels around a drop, meet none (on the 8
    // Cityscapes frames at 512x256, 47% of the rays are traced in the lanes, 0.03% alone).
    EXPECT_GT(in_lanes, sampled / 10) << "level " << level;
  }
}

// Only drops the lanes' closed forms describe: overlapping drops (one body of water), meshes
// and irregular outlines keep the general tracer.
TEST(PinholeLanes, ApplyOnlyToDisjointExactCircularCaps) {
  SKIP_WITHOUT_LANES();
  const GlassPlane glass{30, 40 * kDegToRad};
  const std::vector<Drop> drops{Drop(cap(-1, 0, 0.4, 40), glass), Drop(cap(1, 0, 0.4, 40), glass)};
  DropAccel exact(drops, GeometryOptions{});
  exact.set_disjoint(true);
  EXPECT_TRUE(PinholeLanes::applies(exact));
  exact.set_disjoint(false);
  EXPECT_FALSE(PinholeLanes::applies(exact));
  DropAccel mesh(drops, GeometryOptions::parse("mesh-32-smooth"));
  mesh.set_disjoint(true);
  EXPECT_FALSE(PinholeLanes::applies(mesh));
  DropShape irregular = cap(0, 2, 0.4, 40);
  Rng rng(3);
  irregular.outline = Outline::draw(0.2, 4, rng);
  const std::vector<Drop> with_irregular{drops[0], Drop(irregular, glass)};
  DropAccel odd(with_irregular, GeometryOptions{});
  odd.set_disjoint(true);
  EXPECT_FALSE(PinholeLanes::applies(odd));
}

}  // namespace
}  // namespace raindrop

// Hard cases stay finite: the hazards found in the authors' released renderer, extreme scene
// parameters, and random sweeps (10^6 rays, 10^4 scenes) with zero NaN or Inf anywhere.
#include <cmath>
#include <cstdio>
#include <limits>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include "raindrop/common/rng.h"
#include "raindrop/render/background.h"
#include "raindrop/render/blur.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/tracer.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

bool finite(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Everything a traced ray produces must be finite and in range.
void expect_sane(const DropPath& p, const Camera& cam, double background_z, const char* what) {
  EXPECT_TRUE(finite(p.origin)) << what;
  EXPECT_TRUE(std::isfinite(p.transmittance) && p.transmittance >= 0 && p.transmittance <= 1) << what;
  if (p.hit && !p.dark) {
    EXPECT_TRUE(finite(p.dir)) << what;
    EXPECT_NEAR(glm::length(p.dir), 1.0, 1e-9) << what;
    const glm::dvec2 bg = background_pixel(p, cam, background_z);
    EXPECT_TRUE(std::isfinite(bg.x) && std::isfinite(bg.y)) << what;
  }
}

// Checks the float colours of a traced and blurred frame: finite, in [0, 1], in drops only.
void expect_sane_frame(const cv::Mat& clean, const Camera& cam, const SceneConfig& config, const SceneSample& scene,
                       std::int64_t* bad) {
  std::vector<Drop> drops;
  for (const auto& s : scene.drops) drops.emplace_back(s, scene.glass);
  const DropAccel accel(drops, config.geometry);
  TraceResult t = trace_drops(clean, cam, config, scene, accel);
  if (config.blur.enabled) blur_drops(clean, t.label, t.color, scene.blur_diameter_px, config.blur.method);
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      if (t.label.at<int>(y, x) < 0) continue;
      const cv::Vec3f c = t.color.at<cv::Vec3f>(y, x);
      for (int k = 0; k < 3; ++k) {
        const bool ok = std::isfinite(c[k]) && c[k] >= 0 && c[k] <= 1;
        if (!ok && *bad < 5) std::fprintf(stderr, "bad value %.9g at %d,%d (%s)\n", c[k], x, y, config.blur.enabled ? to_string(config.blur.method) : "no blur");
        *bad += !ok;
      }
    }
  }
}

SceneSample single_drop_scene(const GlassPlane& glass, const DropShape& shape) {
  SceneSample s;
  s.glass = glass;
  s.background_distance_cm = 1000;
  s.blur_diameter_px = 3;
  s.drops = {shape};
  return s;
}

}  // namespace

TEST(Stability, PixelRaysParallelToTheGlassDoNotBreakAnything) {
  // The released code divides by tan(psi) - (y - v0) / fy, zero for the Cityscapes bottom
  // row at psi ~ 12.7 deg. Put the glass exactly parallel to some pixel rows.
  const Camera cam = camera(64, 48, 60);
  const double dy = (cam.height - 1 - cam.cy) / cam.fy;
  for (double tilt : {std::atan(dy), std::atan(dy) + 1e-12, 0.5 * std::atan(dy), 1e-3}) {
    const GlassPlane glass{20, tilt};
    EXPECT_FALSE(glass.intersect({0, 0, 0}, {0, std::sin(tilt), std::cos(tilt)}));  // along the glass
    SceneConfig config = scene_preset("full-physics");
    config.tilt_deg = {tilt * 180 / M_PI, tilt * 180 / M_PI};
    const cv::Mat clean(cam.height, cam.width, CV_8UC3, cv::Scalar(10, 200, 30));
    Rng rng(3);
    SceneSample scene = sample_scene(config, cam, rng);
    scene.glass.tilt = tilt;  // exact, without the degree round trip
    std::int64_t bad = 0;
    expect_sane_frame(clean, cam, config, scene, &bad);
    EXPECT_EQ(bad, 0) << "tilt " << tilt;
  }
}

TEST(Stability, RaysThroughTheFootprintRimAndTangentToTheCap) {
  const GlassPlane glass{30, 35 * kDegToRad};
  const Camera cam = camera(640, 480, 600);
  for (const auto& geometry : all_geometries()) {
    for (double tau : {1e-4, 0.3, 45.0, 89.999, 90.0}) {
      const DropShape shape = cap(0.5, -0.3, 0.9, tau);
      const std::vector<Drop> drops{Drop(shape, glass)};
      const DropAccel accel(drops, geometry);
      const Drop& drop = drops[0];
      for (int j = 0; j < 64; ++j) {
        const double phi = 2 * M_PI * j / 64;
        // Camera ray aimed exactly at a rim point: 0/0 territory in the released code.
        const glm::dvec3 rim = drop.cap_point(shape.contact_angle, phi);
        expect_sane(trace_through_drops({0, 0, 0}, rim, 1.333, TirMode::Trace, true, accel, glass), cam, 1000, "rim");
        // Rays tangent to the cap at points from apex to rim, from both sides.
        for (double f : {0.0, 0.3, 0.7, 1.0}) {
          const glm::dvec3 p = drop.cap_point(f * shape.contact_angle, phi);
          const glm::dvec3 n = drop.cap_normal(p);
          glm::dvec3 tangent = glm::cross(n, glm::dvec3(std::cos(phi + 1), std::sin(phi + 1), 0.3));
          if (glm::length(tangent) < 1e-9) tangent = glm::cross(n, glm::dvec3(0, 0, 1));
          tangent = glm::normalize(tangent);
          for (double s : {-1.0, 1.0}) {
            expect_sane(trace_through_drops(p - 5.0 * s * tangent, s * tangent, 1.333, TirMode::Black, false, accel, glass),
                        cam, 1000, "tangent");
            expect_sane(trace_through_drops(p - 5.0 * s * tangent, s * tangent, 1.333, TirMode::Trace, true, accel, glass),
                        cam, 1000, "tangent, traced");
          }
        }
      }
    }
  }
}

TEST(Stability, ViewRayAlongTheGlassNormalAndTheExactCriticalAngle) {
  const GlassPlane glass = upright_glass(25);
  const DropShape shape = cap(0, 0, 0.8, 70);
  const std::vector<Drop> drops{Drop(shape, glass)};
  const DropAccel accel(drops, GeometryOptions{});
  const Camera cam = camera(100, 100, 100);
  // Along the normal through the footprint centre: no division by a zero path length.
  expect_sane(trace_through_drops({0, 0, 0}, {0, 0, 1}, 1.333, TirMode::Black, true, accel, glass), cam, 1000, "normal");
  // Parallel ray meeting the cap exactly at the critical angle (height R / n).
  const double y = shape.sphere_radius() / 1.333;
  for (TirMode mode : {TirMode::Black, TirMode::Trace}) {
    expect_sane(trace_through_drops({y, 0, 1}, {0, 0, 1}, 1.333, mode, true, accel, glass), cam, 1000, "critical");
  }
}

TEST(Stability, ExtremeDropsAndGlassPoses) {
  const Camera cam = camera(96, 64, 90);
  const cv::Mat clean(cam.height, cam.width, CV_8UC3, cv::Scalar(255, 255, 255));
  std::int64_t bad = 0;
  for (double tilt : {1e-6, 1.0, 15.0, 45.0, 89.999, 90.0}) {
    for (double a : {1e-4, 0.01, 1.0, 40.0, 500.0}) {
      for (double tau : {1e-4, 1.0, 45.0, 90.0}) {
        for (const auto& geometry : all_geometries()) {
          SceneConfig config = scene_preset("full-physics");
          config.geometry = geometry;
          config.tir = TirMode::Trace;
          // On the axis, and partly off the frame's left edge.
          for (double u : {0.0, -12.0}) {
            const GlassPlane glass{20, tilt * kDegToRad};
            expect_sane_frame(clean, cam, config, single_drop_scene(glass, cap(u, 0, a, tau)), &bad);
          }
        }
      }
    }
  }
  EXPECT_EQ(bad, 0);
}

TEST(Stability, MillionRandomRaysStayFinite) {
  Rng rng(2024);
  const Camera cam = camera(2048, 1024, 2262);
  std::int64_t rays = 0, nonfinite = 0, hits = 0;
  for (int config = 0; config < 1000; ++config) {
    const GlassPlane glass{rng.uniform(1, 100), rng.uniform(0.01, M_PI / 2)};
    DropShape shape = cap(rng.uniform(-5, 5), rng.uniform(-5, 5), std::exp(rng.uniform(std::log(1e-3), std::log(20.0))),
                          rng.uniform(0.01, 90));
    if (config % 2) {
      shape.elongation = rng.uniform(1, 3);
      shape.flattening = rng.uniform(0.1, 1);
    }
    const std::vector<Drop> drops{Drop(shape, glass)};
    const GeometryOptions geometry = config % 5 == 0 ? GeometryOptions::parse("mesh-16-flat") : GeometryOptions{};
    const DropAccel accel(drops, geometry);
    const TirMode mode = config % 3 == 0 ? TirMode::Trace : TirMode::Black;
    glm::dvec3 lo, hi;
    drops[0].bounds(&lo, &hi);
    for (int i = 0; i < 1000; ++i, ++rays) {
      glm::dvec3 origin, dir;
      if (i % 2 == 0) {
        // Camera rays aimed at random points of the drop's box (many hit).
        origin = {0, 0, 0};
        dir = lo + glm::dvec3(rng.uniform(), rng.uniform(), rng.uniform()) * (hi - lo);
      } else {
        // Arbitrary rays through the box, from any side.
        const glm::dvec3 target = lo + glm::dvec3(rng.uniform(), rng.uniform(), rng.uniform()) * (hi - lo);
        dir = glm::dvec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
        if (glm::length(dir) < 1e-6) dir = {0, 0, 1};
        origin = target - 3.0 * glm::length(hi - lo) * glm::normalize(dir);
      }
      const DropPath p = trace_through_drops(origin, dir, rng.uniform(1.0, 2.0), mode, i % 4 == 1, accel, glass);
      hits += p.hit;
      bool ok = finite(p.origin) && std::isfinite(p.transmittance) && p.transmittance >= 0 && p.transmittance <= 1;
      if (p.hit && !p.dark) {
        const glm::dvec2 bg = background_pixel(p, cam, 1000);
        ok = ok && finite(p.dir) && std::isfinite(bg.x) && std::isfinite(bg.y);
      }
      nonfinite += !ok;
    }
  }
  EXPECT_EQ(rays, 1000000);
  EXPECT_EQ(nonfinite, 0);
  EXPECT_GT(hits, rays / 10);  // the sweep really exercises the drops
}

TEST(Stability, TenThousandRandomScenesStayFinite) {
  Rng rng(77);
  const Camera cam = camera(48, 32, 50);
  cv::Mat clean(cam.height, cam.width, CV_8UC3);
  cv::randu(clean, 0, 256);
  std::int64_t bad = 0, drop_pixels = 0;
  tbb::task_arena one(1);  // the sweep is many tiny frames: no point in threads
  one.execute([&] {
    for (int i = 0; i < 10000; ++i) {
      SceneConfig config = scene_preset(i % 2 ? "full-physics" : "paper");
      const double n = rng.uniform(1, 200);
      config.glass_distance_cm = {n, n};
      const double tilt = rng.uniform(15, 90);
      config.tilt_deg = {tilt, tilt};
      const double tau = rng.uniform(1, 90);
      config.contact_angle_deg = {tau, tau};
      const double size = std::exp(rng.uniform(std::log(1e-3), std::log(30.0)));
      config.drop_size_cm = {size, size};
      const int count = rng.uniform_int(0, 40);
      config.drop_count = {static_cast<double>(count), static_cast<double>(count)};
      config.allow_overlap = i % 3 == 0;
      config.tir = i % 4 == 0 ? TirMode::Trace : TirMode::Black;
      config.blur.method = static_cast<BlurMethod>(i % 4);
      config.blur.diameter_px_2048 = {0, 200};
      config.border = i % 2 ? BorderMode::Mirror : BorderMode::Clamp;
      config.geometry = i % 7 == 0 ? GeometryOptions::parse("mesh-8-flat") : GeometryOptions{};
      Rng scene_rng(i);
      const SceneSample scene = sample_scene(config, cam, scene_rng);
      expect_sane_frame(clean, cam, config, scene, &bad);
      const RenderedFrame f = render_frame(clean, cam, config, scene);
      drop_pixels += cv::countNonZero(f.mask);
    }
  });
  EXPECT_EQ(bad, 0);
  EXPECT_GT(drop_pixels, 10000);  // the sweep really puts drops on the frames
}

TEST(Stability, BackgroundSamplerFoldsAnyCoordinate) {
  cv::Mat img(5, 7, CV_8UC3);
  cv::randu(img, 0, 256);
  for (BorderMode mode : {BorderMode::Clamp, BorderMode::Mirror}) {
    const BackgroundSampler s(img, mode);
    const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
    for (double v : {-1e300, -1e9, -7.3, -0.5, 0.0, 3.25, 6.5, 13.9, 1e12, 1e300, inf, -inf, nan}) {
      const glm::dvec3 c = s.sample(v, -v);
      EXPECT_TRUE(finite(c) && c.x >= 0 && c.x <= 1) << v;
    }
    // Inside the frame both modes are plain bilinear interpolation.
    const glm::dvec3 mid = s.sample(2.5, 1.0);
    EXPECT_NEAR(mid.x, (img.at<cv::Vec3b>(1, 2)[0] + img.at<cv::Vec3b>(1, 3)[0]) / 510.0, 1e-12);
  }
  // Mirror reflects about the outer pixel edge: x = -1 reads pixel 0, x = -2 pixel 1.
  const BackgroundSampler m(img, BorderMode::Mirror);
  EXPECT_NEAR(m.sample(-2.0, 0).x, img.at<cv::Vec3b>(0, 1)[0] / 255.0, 1e-12);
  EXPECT_NEAR(m.sample(8.0, 0).x, img.at<cv::Vec3b>(0, 5)[0] / 255.0, 1e-12);
}

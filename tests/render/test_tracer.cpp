// A drop on the glass is a plano-convex lens. These tests trace rays through the real tracer
// (Embree queries, both exact caps and a fine mesh) and compare with closed-form optics.
#include <cmath>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "raindrop/render/renderer.h"
#include "raindrop/render/scene_config.h"
#include "raindrop/render/tracer.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

constexpr double kN = 1.333;  // the paper's index of water

// The cap's geometry from its definition, independently of DropShape: a footprint of radius
// a cut from a sphere at contact angle tau has sphere radius R = a / sin(tau) and height
// R (1 - cos(tau)).
struct Lens {
  GlassPlane glass;
  DropShape shape;
  std::vector<Drop> drops;
  double R, height;
  Lens(double n_cm, double footprint, double tau_deg)
      : glass(upright_glass(n_cm)),
        shape(cap(0, 0, footprint, tau_deg)),
        R(footprint / std::sin(tau_deg * kDegToRad)),
        height(R * (1 - std::cos(tau_deg * kDegToRad))) {
    drops.emplace_back(shape, glass);
  }
  double apex_z() const { return glass.distance + height; }
  double focal_length() const { return R / (kN - 1); }
};

}  // namespace

class LensTest : public ::testing::TestWithParam<GeometryOptions> {};

TEST_P(LensTest, RayThroughTheApexAtNormalIncidenceIsUndeviated) {
  const Lens lens(30, 0.8, 40);
  const DropAccel accel(lens.drops, GetParam());
  const DropPath p = trace_through_drops({0, 0, 0}, {0, 0, 1}, kN, TirMode::Black, false, accel, lens.glass);
  ASSERT_TRUE(p.hit);
  EXPECT_FALSE(p.dark);
  EXPECT_EQ(p.events, 2);  // in through the base, out through the apex
  EXPECT_NEAR(p.dir.x, 0, 1e-6);
  EXPECT_NEAR(p.dir.y, 0, 1e-6);
  EXPECT_NEAR(p.dir.z, 1, 1e-12);
  EXPECT_NEAR(p.origin.z, lens.apex_z(), GetParam().kind == GeometryOptions::Kind::Exact ? 1e-9 : 1e-4);
}

TEST_P(LensTest, CollimatedLightFocusesAtRadiusOverNMinusOne) {
  // Plano-convex lens, flat side towards the light: the back focal length measured from the
  // curved vertex equals f = R / (n - 1) (the back principal plane is at that vertex).
  const Lens lens(30, 0.8, 40);
  const DropAccel accel(lens.drops, GetParam());
  const double R = lens.R;
  const bool exact = GetParam().kind == GeometryOptions::Kind::Exact;
  double previous_focus = 1e300;
  for (double h : {1e-3 * R, 0.05 * R, 0.2 * R, 0.4 * R}) {
    const DropPath p = trace_through_drops({h, 0, 10}, {0, 0, 1}, kN, TirMode::Black, false, accel, lens.glass);
    ASSERT_TRUE(p.hit && !p.dark) << h;
    const double t = -p.origin.x / p.dir.x;  // where the exit ray crosses the axis
    const double focus = p.origin.z + t * p.dir.z - lens.apex_z();
    if (h < 1e-2 * R) {
      // Paraxial: relative error O((h/R)^2) for the exact cap; the mesh's interpolated
      // normals are exact at vertices only.
      EXPECT_NEAR(focus / lens.focal_length(), 1.0, exact ? 1e-5 : 2e-3) << "h = " << h;
    }
    // Spherical aberration: marginal rays focus closer to the lens.
    EXPECT_LT(focus, previous_focus + 1e-9);
    previous_focus = focus;
  }
}

TEST_P(LensTest, CameraSeesAnInvertedImageAtThePredictedMagnification) {
  // Camera at the origin, drop on the optical axis at N, background plane at T. Paraxial ray
  // transfer for a camera ray of slope theta: y = N theta at the base; inside the water the
  // slope is theta / n, so y2 = y + t theta / n at the curved surface (t: cap height); there
  // the slope becomes u = theta - y2 / f; at the background y_T = y2 + (T - N - t) u.
  // Without the drop y_T = T theta, so the background image is scaled by M = y_T / (T theta),
  // negative: the drop shows the scene upside down.
  const double N = 30, T = 1000;
  const Lens lens(N, 0.8, 40);
  const DropAccel accel(lens.drops, GetParam());
  const double t = lens.height, f = lens.focal_length();
  const double theta = 1e-5;
  const double y2 = N * theta + t * theta / kN;
  const double expected_m = (y2 + (T - N - t) * (theta - y2 / f)) / (T * theta);
  ASSERT_LT(expected_m, -1);  // inverted and magnified on the background: minified in the drop
  const Camera cam = camera(801, 601, 2000);
  for (const glm::dvec2 axis : {glm::dvec2(1, 0), glm::dvec2(0, 1), glm::dvec2(0.6, -0.8)}) {
    const glm::dvec3 dir(theta * axis.x, theta * axis.y, 1);
    const DropPath p = trace_through_drops({0, 0, 0}, dir, kN, TirMode::Black, false, accel, lens.glass);
    ASSERT_TRUE(p.hit && !p.dark);
    const glm::dvec2 bg = background_pixel(p, cam, T);
    const glm::dvec2 px = cam.project(dir);  // where this ray starts on the image
    const double tol = GetParam().kind == GeometryOptions::Kind::Exact ? 1e-4 : 5e-3;
    if (axis.y != 0) {
      EXPECT_NEAR((bg.y - cam.cy) / (px.y - cam.cy), expected_m, std::abs(expected_m) * tol);
    }
    if (axis.x != 0) {
      EXPECT_NEAR((bg.x - cam.cx) / (px.x - cam.cx), expected_m, std::abs(expected_m) * tol);
    }
  }
}

TEST_P(LensTest, DarkBandStartsWhereTheCapIsHitBeyondTheCriticalAngle) {
  // A ray parallel to the axis at height y crosses the flat base undeviated and meets the
  // sphere (centre on the axis) at incidence angle asin(y / R): total internal reflection
  // for y > R / n. tau = 70 deg so the footprint (R sin tau) reaches past R / n.
  const Lens lens(30, 0.8, 70);
  const DropAccel accel(lens.drops, GetParam());
  const double R = lens.R;
  const double y_critical = R / kN;
  ASSERT_LT(y_critical, lens.shape.footprint_radius);
  const bool exact = GetParam().kind == GeometryOptions::Kind::Exact;
  const double margin = exact ? 1e-7 : 5e-3;  // the mesh's normals differ slightly
  for (double phi : {0.0, 1.0, 2.5, 4.0}) {
    const glm::dvec2 dir(std::cos(phi), std::sin(phi));
    auto dark_at = [&](double y) {
      const DropPath p = trace_through_drops({y * dir.x, y * dir.y, 5}, {0, 0, 1}, kN, TirMode::Black, false, accel,
                                             lens.glass);
      EXPECT_TRUE(p.hit);
      return p.dark;
    };
    EXPECT_FALSE(dark_at(y_critical * (1 - margin))) << phi;
    EXPECT_TRUE(dark_at(y_critical * (1 + margin))) << phi;
    EXPECT_FALSE(dark_at(0.5 * y_critical));
    EXPECT_TRUE(dark_at(0.5 * (y_critical + lens.shape.footprint_radius)));
  }
}

INSTANTIATE_TEST_SUITE_P(Geometry, LensTest, ::testing::ValuesIn(all_geometries()), geometry_name);

// ---- The mask is the drop's projected silhouette -------------------------------------------

namespace {

// Shoelace area of the convex hull of the projected cap (rim and curved surface sampled
// densely): the projection of a convex solid is the hull of its projected points.
double projected_silhouette_area(const Drop& drop, const Camera& cam) {
  std::vector<cv::Point2f> pts;
  const double tau = drop.shape().contact_angle;
  for (int i = 0; i <= 200; ++i) {
    for (int j = 0; j < 720; ++j) {
      pts.emplace_back(cv::Point2f(static_cast<float>(cam.project(drop.cap_point(tau * i / 200, 2 * M_PI * j / 720)).x),
                                   static_cast<float>(cam.project(drop.cap_point(tau * i / 200, 2 * M_PI * j / 720)).y)));
    }
  }
  std::vector<cv::Point2f> hull;
  cv::convexHull(pts, hull);
  return cv::contourArea(hull);
}

cv::Mat render_mask(const Camera& cam, const GlassPlane& glass, const DropShape& shape, const GeometryOptions& geometry) {
  SceneConfig config = scene_preset("paper");
  config.blur.enabled = false;
  config.geometry = geometry;
  SceneSample scene;
  scene.glass = glass;
  scene.background_distance_cm = 1000;
  scene.drops = {shape};
  const cv::Mat clean(cam.height, cam.width, CV_8UC3, cv::Scalar(90, 120, 150));
  return render_frame(clean, cam, config, scene).mask;
}

double mask_area(const Camera& cam, const GlassPlane& glass, const DropShape& shape, const GeometryOptions& geometry) {
  return cv::countNonZero(render_mask(cam, glass, shape, geometry));
}

}  // namespace

class MaskAreaTest : public ::testing::TestWithParam<GeometryOptions> {};

TEST_P(MaskAreaTest, HeadOnTheMaskIsTheProjectedFootprintCircle) {
  // Glass parallel to the image plane: the circular footprint projects to a circle of radius
  // f a / N wherever it is in the frame (cap rim slopes are steeper than the view rays, so
  // the cap adds nothing to the silhouette).
  const Camera cam = camera(400, 300, 500);
  const double N = 30, a = 1.5;
  const double expected = M_PI * std::pow(cam.fx * a / N, 2);  // 25 px radius
  for (const glm::dvec2 c : {glm::dvec2(0, 0), glm::dvec2(8, 3), glm::dvec2(-9, -6)}) {
    const double area = mask_area(cam, upright_glass(N), cap(c.x, c.y, a, 40), GetParam());
    EXPECT_NEAR(area / expected, 1.0, 0.01) << "centre " << c.x << "," << c.y;
  }
}

TEST_P(MaskAreaTest, HeadOnTheMaskIsCentredWhereThePinholeProjectsTheDrop) {
  // The area tests above cannot see a mask in the wrong place. Glass parallel to the image
  // plane: the mask is the projected footprint, centred on the projection of the footprint
  // centre (u, v, N), which the pinhole model puts at (fx u / N + cx, fy v / N + cy) with
  // pixel centres at integer coordinates (camera.h). Sampled at pixel centres, a disc of
  // ~20 px radius has its centroid up to ~0.05 px off its true centre; that offset is
  // computed here from the same model (the pixels whose centre's ray, (x - cx) / fx and
  // (y - cy) / fy at depth N, meets the footprint disc), so the mask's centroid is checked
  // to 0.02 px. A camera ray off by half a pixel moves it by half a pixel.
  Camera cam = camera(360, 280, 430);
  cam.fy = 437.5;  // fx != fy and a principal point off the image centre, so neither is confused
  cam.cx = 171.37;
  cam.cy = 146.81;
  const double N = 30, a = 1.4;
  for (const glm::dvec2 c : {glm::dvec2(0.113, -0.271), glm::dvec2(7.31, 4.17), glm::dvec2(-8.93, -5.62)}) {
    SCOPED_TRACE("centre " + std::to_string(c.x) + "," + std::to_string(c.y));
    const cv::Mat mask = render_mask(cam, upright_glass(N), cap(c.x, c.y, a, 30), GetParam());
    const cv::Moments m = cv::moments(mask, /*binaryImage=*/true);
    ASSERT_GT(m.m00, 0);
    const double got_x = m.m10 / m.m00, got_y = m.m01 / m.m00;
    const double want_x = cam.fx * c.x / N + cam.cx, want_y = cam.fy * c.y / N + cam.cy;
    double n = 0, sx = 0, sy = 0;
    for (int y = 0; y < cam.height; ++y) {
      for (int x = 0; x < cam.width; ++x) {
        const double gx = (x - cam.cx) / cam.fx * N - c.x, gy = (y - cam.cy) / cam.fy * N - c.y;
        if (gx * gx + gy * gy > a * a) continue;
        n += 1;
        sx += x;
        sy += y;
      }
    }
    ASSERT_GT(n, 0);
    EXPECT_NEAR(sx / n, want_x, 0.06) << "the pixel-centre sampling offset is larger than expected";
    EXPECT_NEAR(sy / n, want_y, 0.06) << "the pixel-centre sampling offset is larger than expected";
    EXPECT_NEAR(got_x, sx / n, 0.02) << "projected centre x " << want_x;
    EXPECT_NEAR(got_y, sy / n, 0.02) << "projected centre y " << want_y;
    EXPECT_NEAR(got_x, want_x, 0.07);
    EXPECT_NEAR(got_y, want_y, 0.07);
  }
}

TEST_P(MaskAreaTest, TiltedTheMaskIsTheProjectedSilhouetteAndAtLeastTheFootprint) {
  const Camera cam = camera(512, 384, 560);
  for (double tilt : {30.0, 45.0}) {
    for (double tau : {30.0, 45.0}) {
      const GlassPlane glass{25, tilt * kDegToRad};
      const DropShape shape = cap(2, 3, 1.2, tau);
      const Drop drop(shape, glass);
      const double silhouette = projected_silhouette_area(drop, cam);
      // Projected footprint alone: the rim polygon.
      std::vector<cv::Point2f> rim;
      for (int j = 0; j < 720; ++j) {
        const glm::dvec2 q = cam.project(drop.cap_point(shape.contact_angle, 2 * M_PI * j / 720));
        rim.emplace_back(static_cast<float>(q.x), static_cast<float>(q.y));
      }
      const double footprint = cv::contourArea(rim);
      const double area = mask_area(cam, glass, shape, GetParam());
      EXPECT_NEAR(area / silhouette, 1.0, 0.015) << "tilt " << tilt << " tau " << tau;
      EXPECT_GE(area, footprint * 0.99) << "tilt " << tilt << " tau " << tau;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Geometry, MaskAreaTest, ::testing::ValuesIn(all_geometries()), geometry_name);

// Overlapping drops are one body of water: a ray bends where it enters the water and where it
// leaves it, never at a drop's surface that lies inside another drop's water. So a drop
// inside another is invisible, and a drop twice over renders as that drop once.
namespace {

// The traced colours (drop pixels) and labels of `shapes` on upright glass, overlap allowed.
TraceResult trace_merged(const std::vector<DropShape>& shapes, const cv::Mat& clean, const Camera& cam,
                         const GeometryOptions& geometry, TirMode tir) {
  SceneSample scene;
  scene.glass = upright_glass(20);
  scene.background_distance_cm = 1000;
  scene.drops = shapes;
  std::vector<Drop> drops;
  for (const auto& s : shapes) drops.emplace_back(s, scene.glass);
  DropAccel accel(drops, geometry);
  accel.set_disjoint(false);
  SceneConfig config = scene_preset("paper");
  config.geometry = geometry;
  config.tir = tir;
  return trace_drops(clean, cam, config, scene, accel);
}

double max_colour_difference(const TraceResult& a, const TraceResult& b) {
  double worst = 0;
  for (int y = 0; y < a.label.rows; ++y)
    for (int x = 0; x < a.label.cols; ++x) {
      if ((a.label.at<int>(y, x) >= 0) != (b.label.at<int>(y, x) >= 0)) return INFINITY;
      if (a.label.at<int>(y, x) < 0) continue;
      for (int c = 0; c < 3; ++c)
        worst = std::max(worst, std::abs<double>(a.color.at<cv::Vec3f>(y, x)[c] - b.color.at<cv::Vec3f>(y, x)[c]));
    }
  return worst;
}

}  // namespace

TEST_P(LensTest, ADropInsideAnotherDropsWaterIsInvisible) {
  const Camera cam = camera(160, 120, 300);
  const cv::Mat clean = random_frame(cam);
  cv::GaussianBlur(clean, clean, cv::Size(0, 0), 2);  // something smooth to look at through it
  for (TirMode tir : {TirMode::Black, TirMode::Trace}) {
    const DropShape big = cap(0.1, -0.05, 1.0, 70);
    // Footprints inside the big one's, caps under its cap: a low drop near its centre, and
    // one sharing its rim's side.
    const std::vector<DropShape> alone{big};
    const std::vector<DropShape> with_inner{big, cap(0.2, 0.1, 0.3, 40), cap(-0.5, -0.2, 0.35, 30)};
    const TraceResult a = trace_merged(alone, clean, cam, GetParam(), tir);
    const TraceResult b = trace_merged(with_inner, clean, cam, GetParam(), tir);
    // A mesh's inner caps are crossed in float precision.
    const double tolerance = GetParam().kind == GeometryOptions::Kind::Exact ? 1e-6 : 1e-5;
    EXPECT_LT(max_colour_difference(a, b), tolerance) << to_string(tir);
    // The same drop twice is the drop once (exact caps: a mesh's copies would be crossed at
    // float-rounded points of surfaces that are the same).
    if (GetParam().kind != GeometryOptions::Kind::Exact) continue;
    const TraceResult c = trace_merged({big, big}, clean, cam, GetParam(), tir);
    EXPECT_LT(max_colour_difference(a, c), 1e-6) << to_string(tir);
  }
}

TEST_P(LensTest, ARayThroughTwoMergedDropsBendsOnlyWhereItEntersAndLeavesTheWater) {
  const GlassPlane glass = upright_glass(20);
  // Two equal caps whose footprints overlap by half; the ray goes through the overlap, into the
  // water through the glass and out through the cap on top there (the left one's, nearer).
  const std::vector<Drop> drops{Drop(cap(-0.3, 0, 0.6, 60), glass), Drop(cap(0.3, 0, 0.6, 60), glass)};
  DropAccel accel(drops, GetParam());
  accel.set_disjoint(false);
  const glm::dvec3 dir = glm::normalize(glm::dvec3(-0.02, 0.01, 20));
  const DropPath p = trace_through_drops({0, 0, 0}, dir, kN, TirMode::Trace, false, accel, glass);
  ASSERT_TRUE(p.hit);
  EXPECT_EQ(p.events, 2);
  // The same ray through the left drop alone leaves the same way: the right drop's cap, inside
  // the left's water on this path, bent nothing.
  const std::vector<Drop> left{drops[0]};
  const DropAccel accel_left(left, GetParam());
  const DropPath q = trace_through_drops({0, 0, 0}, dir, kN, TirMode::Trace, false, accel_left, glass);
  EXPECT_EQ(q.events, 2);
  const double tolerance = GetParam().kind == GeometryOptions::Kind::Exact ? 1e-9 : 1e-5;
  EXPECT_LT(glm::length(p.dir - q.dir), tolerance);
  EXPECT_LT(glm::length(p.origin - q.origin), tolerance);
}

// Camera rays traced side by side (TraceStrategy::lockstep) give the images traced one ray at a
// time, bit for bit, for every preset, crowded glass, traced internal reflection and Fresnel;
// and the side-by-side path does take most rays where drops are disjoint (else this test
// would hold nothing), and none where they overlap (one body of water: trace_path's own).
TEST(Lockstep, TracesTheSameImagesAsOneRayAtATime) {
  const Camera cam = camera(320, 160, 353);
  const cv::Mat clean = random_frame(cam);
  std::vector<NamedScene> cases = preset_scenes(cam);
  for (std::uint64_t seed : {1, 2}) {
    SceneConfig c = scene_preset("paper");
    cases.push_back({"crowded seed " + std::to_string(seed), c, crowded_scene(seed, cam)});
    c.tir = TirMode::Trace;
    cases.push_back({"crowded, internal reflection traced, seed " + std::to_string(seed), c, crowded_scene(seed, cam)});
    c.fresnel.enabled = true;
    cases.push_back({"crowded, traced, Fresnel, seed " + std::to_string(seed), c, crowded_scene(seed, cam)});
  }
  std::int64_t disjoint_drop_pixels = 0, side_by_side = 0;
  for (const NamedScene& k : cases) {
    const std::vector<Drop> drops = drops_of(k.scene);
    DropAccel accel(drops, k.config.geometry);
    const bool disjoint = k.config.drops_disjoint();
    accel.set_disjoint(disjoint);
    // Side by side without the SIMD lanes (test_pinhole_lanes.cpp holds those).
    const TraceResult a = trace_drops(clean, cam, k.config, k.scene, accel, nullptr, TraceStrategy{true, false});
    const TraceResult b = trace_drops(clean, cam, k.config, k.scene, accel, nullptr, TraceStrategy{false});
    ASSERT_GT(a.stats.drop_pixels, 0) << k.name;
    EXPECT_EQ(b.stats.lockstep_pixels, 0) << k.name;
    EXPECT_TRUE(equal_bits(a.label, b.label)) << k.name;
    cv::Mat ca = a.color.clone(), cb = b.color.clone();
    ca.setTo(cv::Scalar::all(0), a.label < 0);
    cb.setTo(cv::Scalar::all(0), b.label < 0);
    EXPECT_TRUE(equal_bits(ca, cb)) << k.name;
    EXPECT_EQ(a.stats.dark_band_pixels, b.stats.dark_band_pixels) << k.name;
    EXPECT_EQ(a.stats.off_frame_pixels, b.stats.off_frame_pixels) << k.name;
    if (!disjoint) {
      EXPECT_EQ(a.stats.lockstep_pixels, 0) << k.name;
    }
    if (disjoint && !k.config.dispersion.enabled) {
      disjoint_drop_pixels += a.stats.drop_pixels;
      side_by_side += a.stats.lockstep_pixels;
    }
  }
  EXPECT_GT(side_by_side, disjoint_drop_pixels / 2);
}

// The aperture reference's rays, a pixel's 8 at a time side by side, give what each ray traced
// alone gives, bit for bit: thin-lens presets, 9 rays a pixel (a packet of 8 and one of 1), 16
// and 25 (a last packet of 1; 36 below: of 4), without Fresnel, with it and with internal
// reflection traced; and the side-by-side path is taken.
TEST(Lockstep, ApertureRaysTraceTheSameAsOneAtATime) {
  const Camera cam = camera(160, 80, 176);
  const cv::Mat clean = random_frame(cam);
  int compared = 0;
  for (const char* preset : {"lens-cover", "lens-cover-heavy", "windshield-day", "windshield-night", "real-photo"}) {
    for (int variant = 0; variant < 3; ++variant) {
      SceneConfig c = scene_preset(preset);
      c.fresnel.enabled = variant != 0;
      if (variant == 2) c.tir = TirMode::Trace;
      Rng rng(5 + variant);
      const SceneSample scene = sample_scene(c, cam, rng);
      if (!(scene.aperture_cm() > 0)) continue;
      const std::vector<Drop> drops = drops_of(scene);
      DropAccel accel(drops, c.geometry);
      accel.set_disjoint(c.drops_disjoint());
      for (int samples : {9, 16, variant == 0 ? 36 : 25}) {
        const ApertureResult a = trace_aperture(clean, cam, c, scene, accel, samples, nullptr, TraceStrategy{true});
        const ApertureResult b = trace_aperture(clean, cam, c, scene, accel, samples, nullptr, TraceStrategy{false});
        ASSERT_GT(cv::countNonZero(b.coverage), 0) << preset << " variant " << variant;
        EXPECT_GT(a.lockstep_rays, 0) << preset << " variant " << variant;
        EXPECT_EQ(b.lockstep_rays, 0) << preset << " variant " << variant;
        EXPECT_TRUE(equal_bits(a.coverage, b.coverage)) << preset << " variant " << variant << " samples " << samples;
        EXPECT_TRUE(equal_bits(a.linear, b.linear)) << preset << " variant " << variant << " samples " << samples;
        ++compared;
      }
    }
  }
  EXPECT_GE(compared, 30);
}

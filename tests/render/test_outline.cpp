// Irregular contact lines (outline.h): the outline's own closed forms, the stretched cap's
// conservation laws (footprint area and volume), its symmetry, its intersection against the
// closed-form sphere and against a fine march, its normals against neighbouring hits, and the
// mask it renders against the projected outline.
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "raindrop/common/rng.h"
#include "raindrop/render/drop.h"
#include "raindrop/render/outline.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

// A lobed outline: modes 2..6, peak deviation about 0.3.
Outline lobed() { return Outline({0.12, -0.05, 0.06, 0.0, 0.03}, {0.04, 0.09, -0.02, 0.05, 0.0}); }

DropShape irregular_cap(double footprint, double tau_deg, const Outline& outline) {
  DropShape s = cap(0, 0, footprint, tau_deg);
  s.outline = outline;
  return s;
}

// Water thickness along the glass normal through glass point (u, v) of an upright glass at
// distance N: the ray from just in front of the glass enters the base and leaves the cap.
double thickness(const Drop& drop, double N, double u, double v) {
  const glm::dvec3 origin{u, v, N - 1.0}, dir{0, 0, 1};
  const auto in = drop.intersect(origin, dir, 0.0, 1e9);
  if (!in || in->surface != DropSurface::Base) return 0.0;
  const glm::dvec3 p = origin + in->t * dir;
  const auto out = drop.intersect(p, dir, 0.0, 1e9, DropSurface::Base);
  return out ? out->t : 0.0;
}

double cap_volume(double a, double tau) {
  const double R = a / std::sin(tau), h = R * (1 - std::cos(tau));
  return M_PI * h * h * (3 * R - h) / 3;
}

}  // namespace

TEST(Outline, TheCircleIsExactlyOne) {
  const Outline circle;
  EXPECT_TRUE(circle.circular());
  EXPECT_EQ(circle.s(1.234), 1.0);
  EXPECT_EQ(circle.s_max(), 1.0);
  EXPECT_EQ(circle.mean_square(), 1.0);
  EXPECT_TRUE(Outline({0.0, 0.0}, {0.0, 0.0}).circular());  // zero modes are the circle
}

TEST(Outline, ValuesSlopeExtremesAndMeanSquareMatchTheFourierSeries) {
  const Outline o = lobed();
  const std::vector<double> c{0.12, -0.05, 0.06, 0.0, 0.03}, d{0.04, 0.09, -0.02, 0.05, 0.0};
  double hi = -1, lo = 9, sum_sq = 0;
  constexpr int kN = 20000;
  for (int i = 0; i < kN; ++i) {
    const double phi = 2 * M_PI * i / kN;
    double s = 1, ds = 0;
    for (size_t k = 0; k < c.size(); ++k) {
      const double m = static_cast<double>(k + 2);
      s += c[k] * std::cos(m * phi) + d[k] * std::sin(m * phi);
      ds += m * (d[k] * std::cos(m * phi) - c[k] * std::sin(m * phi));
    }
    double s2, ds2;
    o.s_and_slope(phi, &s2, &ds2);
    EXPECT_NEAR(o.s(phi), s, 1e-13);
    EXPECT_NEAR(s2, s, 1e-13);
    EXPECT_NEAR(o.s_at(std::cos(phi), std::sin(phi)), s, 1e-13);
    EXPECT_NEAR(ds2, ds, 1e-12);
    hi = std::max(hi, s), lo = std::min(lo, s), sum_sq += s * s / kN;
  }
  // The extremes bound the series from outside, and tightly.
  EXPECT_GE(o.s_max(), hi);
  EXPECT_LT(o.s_max() - hi, 1e-4);
  EXPECT_LE(o.s_min(), lo);
  EXPECT_LT(lo - o.s_min(), 1e-4);
  EXPECT_NEAR(o.mean_square(), sum_sq, 1e-12);  // Parseval
}

TEST(Outline, ADrawnOutlineHasTheAskedPeakAndIsReproducible) {
  for (double peak : {0.05, 0.2, 0.5}) {
    for (int modes : {2, 6, 16}) {
      Rng a(7), b(7);
      const Outline o = Outline::draw(peak, modes, a), p = Outline::draw(peak, modes, b);
      EXPECT_NEAR(o.peak_deviation(), peak, 2e-4 * (1 + modes)) << peak << " " << modes;
      EXPECT_EQ(o.cos_terms(), p.cos_terms());
      EXPECT_EQ(static_cast<int>(o.cos_terms().size()), modes - 1);
    }
  }
  Rng r(1);
  EXPECT_TRUE(Outline::draw(0.0, 6, r).circular());
}

TEST(Outline, RefusesOutlinesThroughTheCentreAndBadModes) {
  EXPECT_THROW(Outline({0.97}, {0.0}), Error);
  EXPECT_THROW(Outline({0.1, 0.1}, {0.1}), Error);
  EXPECT_THROW(Outline({NAN}, {0.0}), Error);
  Rng r(1);
  EXPECT_THROW(Outline::draw(0.95, 6, r), Error);
  EXPECT_THROW(Outline::draw(0.2, 1, r), Error);
  EXPECT_THROW(Outline::draw(0.2, kMaxOutlineModes + 1, r), Error);
}

TEST(IrregularDrop, ANearlyCircularOutlineIntersectsLikeTheClosedFormSphere) {
  // A mode of 1e-12 sends the drop down the searched path with the sphere's geometry.
  const GlassPlane glass{30, 0.7};
  const Drop sphere(cap(1, -2, 0.6, 55), glass);
  const Drop searched(irregular_cap(0.6, 55, Outline({1e-12}, {0.0})), glass);
  DropShape moved = searched.shape();
  moved.center = {1, -2};
  const Drop irregular(moved, glass);
  Rng rng(3);
  int hits = 0;
  for (int i = 0; i < 4000; ++i) {
    // Rays from the camera towards points around the drop, and rays from inside it.
    const glm::dvec3 target = sphere.centre() + glm::dvec3(rng.uniform(-0.8, 0.8), rng.uniform(-0.8, 0.8), rng.uniform(-0.3, 0.5));
    const bool inside = i % 2 == 1;
    glm::dvec3 origin{0, 0, 0}, dir = target;
    std::optional<DropSurface> start;
    if (inside) {
      const auto entry = sphere.intersect(origin, dir, 0, 1e9);
      if (!entry) continue;
      origin = origin + entry->t * dir;
      dir = glm::dvec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
      if (glm::dot(dir, entry->normal) > 0) dir = -dir;  // into the water
      start = entry->surface;
    }
    const auto a = sphere.intersect(origin, dir, 0, 1e9, start);
    const auto b = irregular.intersect(origin, dir, 0, 1e9, start);
    ASSERT_EQ(a.has_value(), b.has_value()) << "ray " << i;
    if (!a) continue;
    ++hits;
    EXPECT_EQ(a->surface, b->surface) << "ray " << i;
    EXPECT_NEAR(b->t, a->t, 1e-9 * std::max(1.0, a->t)) << "ray " << i;
    EXPECT_GT(glm::dot(a->normal, b->normal), 1 - 1e-9) << "ray " << i;
  }
  EXPECT_GT(hits, 1000);
}

TEST(IrregularDrop, KeepsFootprintAreaAndVolumeAsInClosedForm) {
  // Area pi a^2 <s^2> and volume V_cap <s^2>, integrated over a grid of rays along the normal;
  // gravity's stretch and flattening multiply them by elongation and elongation x flattening.
  const double N = 30, a = 0.5, tau = 50 * kDegToRad;
  for (const glm::dvec2 gravity : {glm::dvec2(1, 1), glm::dvec2(1.3, 0.7)}) {
    DropShape shape = irregular_cap(a, 50, lobed());
    shape.elongation = gravity.x;
    shape.flattening = gravity.y;
    const Drop drop(shape, upright_glass(N));
    const glm::dvec2 half = shape.footprint_semi_axes();
    constexpr int kGrid = 500;
    double area = 0, volume = 0;
    const double du = 2 * half.x / kGrid, dv = 2 * half.y / kGrid;
    for (int i = 0; i < kGrid; ++i) {
      for (int j = 0; j < kGrid; ++j) {
        const double t = thickness(drop, N, -half.x + (i + 0.5) * du, -half.y + (j + 0.5) * dv);
        if (t > 0) area += du * dv, volume += t * du * dv;
      }
    }
    const double ms = shape.outline.mean_square();
    EXPECT_NEAR(area / (M_PI * a * a * ms * gravity.x), 1.0, 3e-3);
    EXPECT_NEAR(volume / (cap_volume(a, tau) * ms * gravity.x * gravity.y), 1.0, 3e-3);
  }
}

TEST(IrregularDrop, AThreeLobedOutlineIsSymmetricUnderAThirdOfATurnAndItsMirror) {
  const double N = 30;
  const Drop drop(irregular_cap(0.5, 45, Outline({0.0, 0.25}, {0.0, 0.0})), upright_glass(N));
  Rng rng(11);
  int inside = 0;
  for (int i = 0; i < 300; ++i) {
    const double r = rng.uniform(0, 0.6), phi = rng.uniform(0, 2 * M_PI);
    const double t0 = thickness(drop, N, r * std::cos(phi), r * std::sin(phi));
    const double t1 = thickness(drop, N, r * std::cos(phi + 2 * M_PI / 3), r * std::sin(phi + 2 * M_PI / 3));
    const double t2 = thickness(drop, N, r * std::cos(phi), -r * std::sin(phi));  // cos terms only: mirror
    EXPECT_NEAR(t1, t0, 1e-9) << r << " " << phi;
    EXPECT_NEAR(t2, t0, 1e-9) << r << " " << phi;
    inside += t0 > 0;
  }
  EXPECT_GT(inside, 100);
}

TEST(IrregularDrop, FirstHitsAgreeWithAFineMarchThroughTheWater) {
  // A ray's first surface is where contains() first changes along it. The march takes 20000
  // steps and can step over a sliver of water the search finds; the search may miss water
  // only where the ray grazes a lobe between two of its samples.
  const GlassPlane glass{25, 0.8};
  Rng draw_rng(5);
  DropShape shape = irregular_cap(0.4, 60, Outline::draw(0.4, 8, draw_rng));
  shape.center = {0.5, 1.0};
  const Drop drop(shape, glass);
  glm::dvec3 lo, hi;
  drop.bounds(&lo, &hi);
  Rng rng(9);
  int rays = 0, hits = 0, missed = 0;
  for (int i = 0; i < 3000; ++i) {
    const glm::dvec3 target = lo + (hi - lo) * glm::dvec3(rng.uniform(-0.1, 1.1), rng.uniform(-0.1, 1.1), rng.uniform(-0.1, 1.1));
    glm::dvec3 origin{0, 0, 0};
    if (i % 3 == 0) origin = target + 2.0 * glm::dvec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
    const glm::dvec3 dir = target - origin;
    // March from just before the bounding box to just after it.
    const double t_end = 1.0 + 2.0 * glm::length(hi - lo) / glm::length(dir);
    constexpr int kSteps = 20000;
    const bool start_inside = drop.contains(origin);
    if (start_inside) continue;
    double march = -1;
    for (int k = 1; k <= kSteps; ++k) {
      const double t = t_end * k / kSteps;
      if (drop.contains(origin + t * dir)) {
        march = t;
        break;
      }
    }
    const auto hit = drop.intersect(origin, dir, 0, t_end);
    ++rays;
    hits += march > 0;
    if (hit) {
      // Every hit the search returns is a real crossing of the surface.
      const double d = 1e-9 * hit->t;
      EXPECT_NE(drop.contains(origin + (hit->t - d) * dir), drop.contains(origin + (hit->t + d) * dir)) << "ray " << i;
    }
    // Water the march found that the search missed, or passed (the march's first sample in
    // the water lies after the true crossing, so a right search meets it no later).
    if (march > 0 && (!hit || hit->t > march + 1e-12)) ++missed;
  }
  EXPECT_GT(hits, 500);
  EXPECT_LE(missed, rays / 1000) << missed << " of " << rays << " rays";

  // Rays from the base into the water, as the tracer sends them: the first dry point.
  int exits = 0, wrong = 0;
  for (int i = 0; i < 3000; ++i) {
    const glm::dvec3 target = lo + (hi - lo) * glm::dvec3(rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0, 1));
    const auto in = drop.intersect({0, 0, 0}, target, 0, 1e9);
    if (!in || in->surface != DropSurface::Base) continue;
    const glm::dvec3 origin = in->t * target;
    glm::dvec3 dir{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
    if (glm::dot(dir, in->normal) > 0) dir = -dir;
    const double t_end = 2.0 * glm::length(hi - lo) / glm::length(dir);
    constexpr int kSteps = 20000;
    double march = -1;
    for (int k = 1; k <= kSteps; ++k) {
      if (!drop.contains(origin + (t_end * k / kSteps) * dir)) {
        march = t_end * k / kSteps;
        break;
      }
    }
    const auto out = drop.intersect(origin, dir, 0, t_end, DropSurface::Base);
    ++exits;
    if (march < 0 || !out || out->t > march + 1e-12 || out->t < march - t_end / kSteps) ++wrong;
  }
  EXPECT_GT(exits, 500);
  EXPECT_LE(wrong, exits / 1000) << wrong << " of " << exits << " rays from the base";
}

TEST(IrregularDrop, NormalsAreOrthogonalToTheSurfaceThatNeighbouringHitsSpan) {
  // Rays through the water leave by the cap; three neighbouring exits span its tangent plane.
  const GlassPlane glass{30, 0.9};
  DropShape shape = irregular_cap(0.5, 50, lobed());
  shape.elongation = 1.2;
  shape.flattening = 0.8;
  const Drop drop(shape, glass);
  auto exit = [&](const glm::dvec3& dir) -> std::optional<std::pair<glm::dvec3, SurfaceHit>> {
    const auto in = drop.intersect({0, 0, 0}, dir, 0, 1e9);
    if (!in || in->surface != DropSurface::Base) return std::nullopt;
    const glm::dvec3 p = in->t * dir;
    const auto out = drop.intersect(p, dir, 0, 1e9, DropSurface::Base);
    if (!out || out->surface != DropSurface::Cap) return std::nullopt;
    return std::make_pair(p + out->t * dir, *out);
  };
  Rng rng(21);
  int checked = 0;
  for (int i = 0; i < 400; ++i) {
    const glm::dvec3 dir = glm::normalize(drop.centre() + glm::dvec3(rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), 0.0));
    const glm::dvec3 e1 = glm::normalize(glm::cross(dir, glm::dvec3(0, 1, 0))), e2 = glm::normalize(glm::cross(dir, e1));
    constexpr double kAngle = 1e-6;  // rad: exits about 3e-5 cm apart
    const auto h = exit(dir), h1 = exit(dir + kAngle * e1), h2 = exit(dir + kAngle * e2);
    if (!h || !h1 || !h2) continue;
    const glm::dvec3 tangent_normal = glm::normalize(glm::cross(h1->first - h->first, h2->first - h->first));
    EXPECT_GT(std::abs(glm::dot(tangent_normal, h->second.normal)), 1 - 1e-6) << "ray " << i;
    EXPECT_GT(glm::dot(h->second.normal, dir), 0) << "a ray leaving the water crosses the outward normal";
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(IrregularDrop, TheRimsContactAngleFallsWhereTheLineReachesFurther) {
  // Across the contact line the stretched cap's slope is tan(tau) / s(phi).
  const double N = 30, tau = 45 * kDegToRad;
  const Drop drop(irregular_cap(0.5, 45, lobed()), upright_glass(N));
  for (int i = 0; i < 36; ++i) {
    const double phi = 2 * M_PI * i / 36, s = drop.shape().outline.s(phi);
    const glm::dvec3 radial{std::cos(phi), std::sin(phi), 0};
    const glm::dvec3 rim = drop.cap_point(tau, phi);
    const glm::dvec3 n = drop.cap_normal(rim);
    EXPECT_NEAR(glm::dot(n, radial) / n.z, std::tan(tau) / s, 1e-9) << "phi " << phi;
  }
}

TEST(IrregularDrop, HeadOnTheMaskIsTheProjectedOutline) {
  // Glass parallel to the image plane: the mask is the outline scaled by f / N, for the exact
  // drop and for a fine mesh of it.
  const Camera cam = camera(400, 300, 500);
  const double N = 30, a = 1.5;
  DropShape shape = irregular_cap(a, 40, lobed());
  std::vector<cv::Point> polygon;
  constexpr int kFine = 8;  // the polygon is rasterised 8x finer, then averaged down
  for (int i = 0; i < 720; ++i) {
    const double phi = 2 * M_PI * i / 720, r = cam.fx * a * shape.outline.s(phi) / N;
    polygon.emplace_back(static_cast<int>(std::lround(kFine * (cam.cx + r * std::cos(phi) + 0.5) - 0.5)),
                         static_cast<int>(std::lround(kFine * (cam.cy + r * std::sin(phi) + 0.5) - 0.5)));
  }
  cv::Mat fine = cv::Mat::zeros(cam.height * kFine, cam.width * kFine, CV_8U);
  cv::fillPoly(fine, std::vector<std::vector<cv::Point>>{polygon}, cv::Scalar(255));
  cv::Mat expected;
  cv::resize(fine, expected, cv::Size(cam.width, cam.height), 0, 0, cv::INTER_AREA);
  cv::threshold(expected, expected, 127, 255, cv::THRESH_BINARY);
  for (const char* geometry : {"exact", "mesh-128-smooth"}) {
    SceneConfig config = scene_preset("paper");
    config.blur.enabled = false;
    config.geometry = GeometryOptions::parse(geometry);
    SceneSample scene;
    scene.glass = upright_glass(N);
    scene.background_distance_cm = 1000;
    scene.drops = {shape};
    const cv::Mat clean(cam.height, cam.width, CV_8UC3, cv::Scalar(90, 120, 150));
    const cv::Mat mask = render_frame(clean, cam, config, scene).mask;
    cv::Mat both, either;
    cv::bitwise_and(mask, expected, both);
    cv::bitwise_or(mask, expected, either);
    const double iou = static_cast<double>(cv::countNonZero(both)) / cv::countNonZero(either);
    EXPECT_GT(iou, 0.985) << geometry;
    EXPECT_NEAR(cv::countNonZero(mask) / (M_PI * std::pow(cam.fx * a / N, 2) * shape.outline.mean_square()), 1.0, 0.01)
        << geometry;
  }
}

TEST(IrregularDrop, SceneDrawsOutlinesKeepingAreaAndApartFootprints) {
  SceneConfig config = scene_preset("paper");
  config.outline.enabled = true;
  config.outline.peak_deviation = {0.1, 0.4};
  const Camera cam = camera(512, 256, 560);
  Rng rng(17);
  const SceneSample s = sample_scene(config, cam, rng);
  ASSERT_GT(s.drops.size(), 20u);
  SceneConfig plain = config;
  plain.outline.enabled = false;
  Rng rng2(17);
  const SceneSample p = sample_scene(plain, cam, rng2);
  for (size_t i = 0; i < s.drops.size(); ++i) {
    const DropShape& d = s.drops[i];
    EXPECT_FALSE(d.outline.circular());
    EXPECT_GE(d.outline.peak_deviation(), 0.1 - 1e-3);
    EXPECT_LE(d.outline.peak_deviation(), 0.4 + 1e-3);
    // The area-equivalent radius a sqrt(<s^2>) is a size from the scene's range.
    const double a = d.footprint_radius * std::sqrt(d.outline.mean_square());
    EXPECT_GE(a, config.drop_size_cm.lo * std::sin(config.contact_angle_deg.lo * kDegToRad) - 1e-12);
    EXPECT_LE(a, config.drop_size_cm.hi - 1e-12);
    for (size_t j = 0; j < i; ++j) {  // no overlap allowed: bounding circles apart
      const double gap = glm::length(d.center - s.drops[j].center) - d.footprint_semi_axes().x -
                         s.drops[j].footprint_semi_axes().x;
      EXPECT_GT(gap, 0) << i << " " << j;
    }
  }
  // The first drop is drawn and placed before any outline, as without them (later ones may land
  // elsewhere: placement keeps the larger enclosing circles apart).
  EXPECT_NEAR(s.drops[0].footprint_radius * std::sqrt(s.drops[0].outline.mean_square()), p.drops[0].footprint_radius, 1e-12);
  EXPECT_EQ(s.drops[0].contact_angle, p.drops[0].contact_angle);
  EXPECT_EQ(s.drops[0].center, p.drops[0].center);
}

TEST(IrregularDrop, WhereDropsMayOverlapOutlinesMoveNoDrop) {
  // Overlap allowed: placement counts overlaps with the drops' own circles, and outlines are
  // drawn last, so every drop keeps its centre, contact angle and footprint area.
  SceneConfig config = scene_preset("lens-cover-merged");
  const Camera cam = camera(512, 256, 560);
  SceneConfig with = config;
  with.outline.enabled = true;
  with.outline.peak_deviation = {0.1, 0.5};
  Rng a(6), b(6);
  const SceneSample s = sample_scene(config, cam, a), t = sample_scene(with, cam, b);
  ASSERT_EQ(s.drops.size(), t.drops.size());
  ASSERT_GT(s.drops.size(), 50u);
  for (size_t i = 0; i < s.drops.size(); ++i) {
    EXPECT_FALSE(t.drops[i].outline.circular());
    EXPECT_EQ(s.drops[i].center, t.drops[i].center);
    EXPECT_EQ(s.drops[i].contact_angle, t.drops[i].contact_angle);
    EXPECT_NEAR(t.drops[i].footprint_radius * std::sqrt(t.drops[i].outline.mean_square()), s.drops[i].footprint_radius, 1e-12);
  }
}

TEST(IrregularDrop, ZeroPeakIsTheOldSceneExactly) {
  SceneConfig config = scene_preset("lens-cover-merged");
  const Camera cam = camera(512, 256, 560);
  SceneConfig with = config;
  with.outline.enabled = true;
  with.outline.peak_deviation = {0, 0};
  Rng a(4), b(4);
  const SceneSample s = sample_scene(config, cam, a), t = sample_scene(with, cam, b);
  ASSERT_EQ(s.drops.size(), t.drops.size());
  for (size_t i = 0; i < s.drops.size(); ++i) {
    EXPECT_TRUE(t.drops[i].outline.circular());
    EXPECT_EQ(s.drops[i].center, t.drops[i].center);
    EXPECT_EQ(s.drops[i].footprint_radius, t.drops[i].footprint_radius);
  }
}

TEST(IrregularDrop, SceneFilesNameTheOutlineAndRefuseBadOnes) {
  const SceneConfig c = parse_scene_json(R"({"effects": {"outline": {"peak_deviation": [0.1, 0.3], "modes": 8}}})", "t.json");
  EXPECT_TRUE(c.outline.enabled);
  EXPECT_EQ(c.outline.modes, 8);
  EXPECT_EQ(c.outline.peak_deviation.hi, 0.3);
  const SceneConfig back = parse_scene_json(scene_to_json(c), "back.json");
  EXPECT_EQ(scene_to_json(back), scene_to_json(c));
  const auto names = c.effect_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "outline"), names.end());
  expect_scene_refused(R"({"effects": {"outline": {"peak_deviation": [0.1, 0.95]}}})", "peak_deviation");
  expect_scene_refused(R"({"effects": {"outline": {"modes": 1}}})", "modes");
  expect_scene_refused(R"({"effects": {"outline": {"modes": 4.5}}})", "modes");
  expect_scene_refused(R"({"effects": {"outline": "auto"}})", "outline");
  expect_scene_refused(R"({"effects": {"outline": {"peak": 0.2}}})", "peak");
}

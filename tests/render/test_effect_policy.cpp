// Effects chosen by the scene's physics ("auto", effect_policy.h): the criteria against
// closed-form cases and traced rays, and what skipping costs against the full simulation.
#include <algorithm>
#include <cmath>
#include <functional>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "raindrop/common/rng.h"
#include "raindrop/render/demo.h"
#include "raindrop/render/effect_policy.h"
#include "raindrop/render/optics.h"
#include "raindrop/render/renderer.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/tracer.h"
#include "support.h"

using namespace raindrop;
using namespace raindrop::test;

namespace {

// The tolerance auto is held to where it skipped something, in 8-bit levels.
constexpr double kToleranceRmse = 0.5, kToleranceMax = 4.0;

// The red and blue indices of the dispersion effect (620 and 460 nm) and green's.
glm::dvec3 rgb_indices() {
  SceneConfig c;
  c.dispersion.enabled = true;
  return c.channel_indices();
}

// The exit direction's angle, in the plane of incidence, of the camera ray through the base
// point at `v` cm downhill from the drop's centre, traced through the drop with index n; NaN
// in the dark band.
double exit_angle(const GlassPlane& glass, const DropAccel& accel, double v, double n) {
  const glm::dvec3 base = glass.point({0.0, v});
  const DropPath p = trace_through_drops({0, 0, 0}, base, n, TirMode::Black, false, accel, glass);
  if (!p.hit || p.dark) return NAN;
  return std::atan2(p.dir.y, p.dir.z);
}

// The largest shift, in cm on the glass, between the red and the blue image of a drop
// along the plane of incidence, from traced rays: at each base point, the red ray's exit
// angle is found again on the blue curve, and the dark band's edges are compared.
double traced_spread_cm(const GlassPlane& glass, const DropShape& shape, double n_red, double n_blue) {
  std::vector<Drop> drops{Drop(shape, glass)};
  const DropAccel accel(drops, GeometryOptions::parse("exact"));
  const double a = shape.footprint_radius;
  constexpr int kN = 4000;
  std::vector<double> v(kN + 1), red(kN + 1), blue(kN + 1);
  for (int i = 0; i <= kN; ++i) {
    v[i] = a * (0.999 * (2.0 * i / kN - 1.0));
    red[i] = exit_angle(glass, accel, v[i], n_red);
    blue[i] = exit_angle(glass, accel, v[i], n_blue);
  }
  double worst = 0;
  for (int i = 1; i < kN; ++i) {
    if (std::isnan(red[i]) != std::isnan(blue[i])) worst = std::max(worst, v[i + 1] - v[i]);  // an edge pixel's width
    if (std::isnan(red[i]) || std::isnan(blue[i]) || std::isnan(blue[i - 1]) || std::isnan(blue[i + 1])) continue;
    const double slope = (blue[i + 1] - blue[i - 1]) / (v[i + 1] - v[i - 1]);
    if (std::abs(slope) > 0) worst = std::max(worst, std::abs(red[i] - blue[i]) / std::abs(slope));
  }
  // The dark band's edges: where each index first and last goes dark.
  auto edges = [&](const std::vector<double>& angle) {
    std::vector<double> e;
    for (int i = 1; i <= kN; ++i)
      if (std::isnan(angle[i]) != std::isnan(angle[i - 1])) e.push_back(0.5 * (v[i] + v[i - 1]));
    return e;
  };
  const auto er = edges(red), eb = edges(blue);
  if (er.size() == eb.size())
    for (size_t i = 0; i < er.size(); ++i) worst = std::max(worst, std::abs(er[i] - eb[i]));
  return worst;
}

}  // namespace

TEST(EffectPolicy, ShiftLevelsFollowTheEdgeSlopeAndTheDropsArea) {
  // No blur: a pixel is the unit square, a shift of s px of a full-contrast edge changes it by 255 s.
  EXPECT_NEAR(shift_levels(0.01, 20, 0), 2.55, 1e-9);
  // A disk blur b px wide: the edge's slope is 4 / (pi b) of its contrast per pixel.
  EXPECT_NEAR(shift_levels(0.1, 20, 8), 255 * 0.1 * 8 / (M_PI * 16), 1e-9);
  // A drop smaller than the blur: only its diameter of edge lies inside the disk ...
  EXPECT_NEAR(shift_levels(0.1, 1, 8), 255 * 0.1 * 2 / (M_PI * 16), 1e-9);
  // ... and however far its content moves, no more than its area changes.
  EXPECT_NEAR(shift_levels(10, 0.2, 0), 255 * M_PI * 0.04, 1e-9);
  EXPECT_EQ(shift_levels(0, 5, 3), 0);
  // A shift wider than a pixel changes it by its full contrast, no more.
  EXPECT_EQ(shift_levels(3, 20, 0), 255);
}

TEST(EffectPolicy, DispersionSpreadMatchesTracedRays) {
  const glm::dvec3 n = rgb_indices();
  // Upright glass (the camera looks square on) and glass tilted to 45 and 30 degrees; caps
  // without and with a dark band (contact angles below and above the critical angle).
  for (double tilt_deg : {90.0, 45.0, 30.0}) {
    for (double tau_deg : {30.0, 45.0, 70.0, 85.0}) {
      SCOPED_TRACE("tilt " + std::to_string(tilt_deg) + ", contact angle " + std::to_string(tau_deg));
      const GlassPlane glass{30.0, tilt_deg * kDegToRad};
      const DropShape shape = cap(0, 0, 0.5, tau_deg);
      const double traced = traced_spread_cm(glass, shape, n.x, n.z);
      const double incidence = std::acos(std::abs(glm::dot(glm::normalize(glass.point({0, 0})), glass.normal())));
      // With 1 px per cm, the formula's pixels are the glass' centimetres.
      const double formula = dispersion_spread_px(shape.sphere_radius(), shape.contact_angle, incidence, n.y, n.z - n.x);
      EXPECT_GT(traced, 0);
      // Within the few per cent of the camera rays' divergence across the drop (the formula
      // takes the incidence at the centre) and of the sampling.
      EXPECT_NEAR(formula / traced, 1.0, 0.1) << "traced " << traced << " cm, formula " << formula;
    }
  }
}

TEST(EffectPolicy, GravityShiftVanishesForTheSphereAndGrowsWithTheDeformation) {
  EXPECT_EQ(gravity_shift_px(10, 1.0, 1.0), 0);
  EXPECT_NEAR(gravity_shift_px(10, 1.0, 0.6), 4.0, 1e-12);
  EXPECT_NEAR(gravity_shift_px(10, 1.3, 1.0), 10 * (1.3 - 1 / 1.3), 1e-12);
  EXPECT_GT(gravity_shift_px(10, 1.3, 0.6), gravity_shift_px(10, 1.3, 1.0));
}


#include "raindrop/render/effect_policy.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <glm/geometric.hpp>

#include "raindrop/render/defocus.h"

namespace raindrop {
namespace {

// The blur a drop is seen through, as the diameter of an equivalent disk: the lens' circle of
// confusion when the frame is defocused, else the paper's disk blur.
double drop_blur_px(const SceneConfig& config, const SceneSample& scene, const Camera& camera,
                    const DropShape& shape, bool defocused) {
  if (defocused) {
    const double coc = scene.drop_coc_px(shape, camera.fx);
    return std::isfinite(coc) && coc >= kMinVisibleCocPx ? coc : 0.0;
  }
  if (!config.blur.enabled) return 0.0;
  const double d = scene.blur_diameter_px;
  switch (config.blur.method) {
    case BlurMethod::DiskSpan:
    case BlurMethod::DiskDirect:
      return d < 2.0 ? 0.0 : d;  // a binary disk under 2 px holds only its centre tap
    case BlurMethod::Gaussian:
      return 0.8 * d;  // sigma d / 4: an edge's slope 1.6 / d, the disk's 4 / (pi d) at 0.8 d
    case BlurMethod::DiskAntialiased:
      return d;
  }
  return d;
}

std::string fixed(double v, int digits) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

// "k of n drops ..." for an effect decided per drop.
template <class On, class Levels, class Shift>
std::string per_drop_why(const EffectPlan& plan, const char* what, On on, Levels levels, Shift shift) {
  if (plan.drops.empty()) return "no drops";
  size_t worst = 0, count = 0;
  for (size_t i = 0; i < plan.drops.size(); ++i) {
    count += on(plan.drops[i]);
    if (levels(plan.drops[i]) > levels(plan.drops[worst])) worst = i;
  }
  const std::string largest = "largest " + fixed(levels(plan.drops[worst]), 2) + " levels: " + what + " " +
                              fixed(shift(plan.drops[worst]), 3) + " px, drop " + std::to_string(worst) + ")";
  const std::string budget = fixed(kAutoBudgetLevels, 0) + " levels";
  if (count == 0) return std::string("every drop's ") + what + " changes a pixel by under " + budget + " (" + largest;
  return std::to_string(count) + " of " + std::to_string(plan.drops.size()) + " drops: the " + what +
         " changes a pixel by " + budget + " or more (" + largest + "; the other " +
         std::to_string(plan.drops.size() - count) + " skip it";
}

}  // namespace

double shift_levels(double shift_px, double radius_px, double blur_px) {
  const double width = std::max(1.0, blur_px), area = std::max(1.0, M_PI * blur_px * blur_px / 4.0);
  // The area the shift sweeps inside the disk: the shift (at most the disk's or the drop's
  // width) times the length of edge the disk holds (its width, or the drop's diameter when
  // the drop is smaller), and at most the drop; a pixel changes by its contrast at most.
  const double diameter = 2.0 * radius_px;
  const double swept = std::min(std::min({shift_px, width, diameter}) * std::min(width, diameter), M_PI * radius_px * radius_px);
  return std::min(kDropContrastLevels, kDropContrastLevels * swept / area);
}

double dispersion_spread_px(double sphere_radius_px, double contact_angle, double incidence, double n, double dn) {
  // Angles in the plane of incidence, from the glass normal: the ray inside the water runs at
  // r0, the cap's normal at the exit point is tilted by theta, the ray meets it at
  // alpha = r0 - theta and leaves at beta (sin beta = n sin alpha), heading psi = theta + beta.
  // A camera pixel is a point v of the base; the ray climbs the height z of the cap there, so
  // v = R sin(theta) - z tan(r0), z = R (cos(theta) - cos(tau)). At fixed v, a change of index
  // turns r0 (dr0/dn = -tan(r0) / n), which moves the exit point and the incidence; the shift
  // of the image is (dpsi/dn) dn / (dpsi/dv). Lengths in units of R.
  const double r0 = std::asin(std::sin(incidence) / n);
  const double critical = std::asin(1.0 / n);
  const double dr0 = -std::tan(r0) / n;
  const double cos_tau = std::cos(contact_angle);
  // dv/dtheta, and dalpha/dn at fixed v, at a normal tilt theta.
  auto dv_dtheta = [&](double theta) { return std::cos(theta) + std::sin(theta) * std::tan(r0); };
  auto dalpha_dn = [&](double theta) {
    const double dtheta = (std::cos(theta) - cos_tau) / (std::cos(r0) * std::cos(r0)) / dv_dtheta(theta) * dr0;
    return dr0 - dtheta;
  };
  double worst = 0;
  constexpr int kSteps = 64;  // normal tilts sampled on each side of the apex
  for (int i = -kSteps; i <= kSteps; ++i) {
    const double theta = contact_angle * i / kSteps;
    const double alpha = r0 - theta, s = n * std::sin(alpha);
    if (std::abs(s) >= 1.0 || dv_dtheta(theta) <= 0) continue;  // the dark band, or out of reach
    const double cos_beta = std::sqrt(1.0 - s * s);
    const double da = dalpha_dn(theta);
    const double dpsi_dn = (dr0 - da) + (std::sin(alpha) + n * std::cos(alpha) * da) / cos_beta;
    const double dpsi_dv = (1.0 - n * std::cos(alpha) / cos_beta) / dv_dtheta(theta);
    worst = std::max(worst, std::abs(dpsi_dn / dpsi_dv));
  }
  // The dark band's edges, where alpha = +-critical: they move by the change of alpha less
  // that of the critical angle (-1 / (n sqrt(n^2 - 1)) per unit index), over dalpha/dv.
  const double dcritical = -1.0 / (n * std::sqrt(n * n - 1.0));
  for (double side : {1.0, -1.0}) {
    const double theta = r0 - side * critical;
    if (std::abs(theta) > contact_angle || dv_dtheta(theta) <= 0) continue;
    worst = std::max(worst, std::abs(dalpha_dn(theta) - side * dcritical) * dv_dtheta(theta));
  }
  return dn * sphere_radius_px * worst;
}

double gravity_shift_px(double footprint_radius_px, double elongation, double flattening) {
  return footprint_radius_px * (elongation - flattening / elongation);
}

bool EffectPlan::dispersion_anywhere(const SceneConfig& config) const {
  if (!config.dispersion.enabled) return false;
  if (!dispersion_auto) return true;
  return std::any_of(drops.begin(), drops.end(), [](const DropEffects& d) { return d.dispersion; });
}

EffectPlan plan_effects(const SceneConfig& config, const SceneSample& scene, const Camera& camera, bool defocused) {
  EffectPlan plan;
  plan.dispersion_auto = config.dispersion.enabled && config.dispersion.automatic;
  plan.gravity_auto = config.gravity.enabled && config.gravity.automatic;
  plan.supersample_auto = config.supersample == Supersample::Auto;
  if (!plan.dispersion_auto && !plan.gravity_auto) return plan;
  const glm::dvec3 n = config.channel_indices();
  const double dn = std::abs(n.z - n.x);
  const glm::dvec3 normal = scene.glass.normal();
  for (const DropShape& shape : scene.drops) {
    DropEffects d;
    const glm::dvec3 centre = scene.glass.point(shape.center);
    // Seen square on at the centre's depth: an upper bound on the drop's scale in the image.
    const double px_per_cm = centre.z > 0 ? camera.fx / centre.z : INFINITY;
    d.radius_px = px_per_cm * shape.footprint_semi_axes().y;
    d.blur_px = drop_blur_px(config, scene, camera, shape, defocused);
    if (plan.dispersion_auto) {
      const double incidence = std::acos(std::min(1.0, std::abs(glm::dot(glm::normalize(centre), normal))));
      d.spread_px = dispersion_spread_px(px_per_cm * shape.sphere_radius() * shape.elongation, shape.contact_angle,
                                         incidence, n.y, dn);
      d.dispersion_levels = shift_levels(d.spread_px, d.radius_px, d.blur_px);
      d.dispersion = !(d.dispersion_levels < kAutoBudgetLevels);
    } else {
      d.dispersion = config.dispersion.enabled;
    }
    if (plan.gravity_auto) {
      d.gravity_px = gravity_shift_px(px_per_cm * shape.footprint_radius, shape.elongation, shape.flattening);
      d.gravity_levels = shift_levels(d.gravity_px, d.radius_px, d.blur_px);
      d.gravity = !(d.gravity_levels < kAutoBudgetLevels);
    } else {
      d.gravity = config.gravity.enabled;
    }
    plan.drops.push_back(d);
  }
  return plan;
}

std::vector<DropShape> rendered_shapes(const SceneSample& scene, const EffectPlan& plan) {
  std::vector<DropShape> shapes = scene.drops;
  if (!plan.gravity_auto) return shapes;
  for (size_t i = 0; i < shapes.size(); ++i) {
    if (plan.drops[i].gravity) continue;
    shapes[i].elongation = 1.0;
    shapes[i].flattening = 1.0;
  }
  return shapes;
}

std::string dispersion_why(const EffectPlan& plan) {
  return per_drop_why(
      plan, "colour spread", [](const DropEffects& d) { return d.dispersion; },
      [](const DropEffects& d) { return d.dispersion_levels; }, [](const DropEffects& d) { return d.spread_px; });
}

std::string gravity_why(const EffectPlan& plan) {
  return per_drop_why(
      plan, "shift of the deformed cap", [](const DropEffects& d) { return d.gravity; },
      [](const DropEffects& d) { return d.gravity_levels; }, [](const DropEffects& d) { return d.gravity_px; });
}

std::string supersample_why(long long aliasing_pixels, long long smooth_pixels, int samples_per_pixel) {
  if (samples_per_pixel <= 1) return "1 sample per pixel: nothing to supersample";
  return std::to_string(samples_per_pixel) + " samples at drop edges and in " + std::to_string(aliasing_pixels) +
         " inside pixels whose footprint on the background varies by " + fixed(kAutoBudgetLevels, 0) +
         " levels or more; " + std::to_string(smooth_pixels) + " inside pixels keep one";
}

}  // namespace raindrop

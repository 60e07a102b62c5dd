#include "raindrop/render/trails.h"

#include <cmath>

#include "raindrop/render/scene.h"

namespace raindrop {
namespace {

constexpr double kDeg = M_PI / 180.0;

}  // namespace

double drop_volume(const DropShape& d) {
  const double R = d.sphere_radius(), h = R * (1.0 - std::cos(d.contact_angle));
  return M_PI * h * h * (3.0 * R - h) / 3.0 * d.elongation * d.flattening * d.outline.mean_square();
}

double drop_width(const DropShape& d) { return 2.0 * d.footprint_radius * d.outline.s_max(); }

bool drop_slides(const DropShape& d, double tilt, double hysteresis) {
  return drop_volume(d) * std::sin(tilt) >= drop_width(d) * hysteresis * kCapillaryLengthSquaredCm2;
}

double uphill_rim_distance(const DropShape& d) {
  // Uphill is -v on the glass; in the drop's frame, scaled by the elongation, the azimuth
  // whose cosine is 0 and sine -1.
  return d.footprint_radius * d.elongation * d.outline.s_at(0.0, -1.0);
}

void add_trails(std::vector<DropShape>* drops, const SceneConfig::Trails& options, double tilt, Rng& rng) {
  const size_t parents = drops->size();
  // Every drop's hysteresis first, so that which drops slide does not depend on the other
  // drops' trails (their lengths, caps and spacings are drawn after).
  std::vector<double> hysteresis(parents);
  for (double& h : hysteresis) h = draw(options.hysteresis, rng);
  for (size_t i = 0; i < parents; ++i) {
    DropShape& drop = (*drops)[i];
    if (!drop_slides(drop, tilt, hysteresis[i])) continue;
    const double volume = drop_volume(drop), budget = options.max_volume_fraction * volume;
    const double length = draw(options.length_radii, rng) * drop.footprint_radius;
    // Caps along the line uphill from the rim, offsets measured from the rim: the first sits
    // on it (joined to the drop), each next one `spacing` times the two radii further, until
    // the trail's length is covered or its water would exceed the budget.
    std::vector<DropShape> trail;
    std::vector<double> offsets;
    double taken = 0, offset = 0, previous_radius = 0;
    while (static_cast<int>(trail.size()) < kMaxTrailCaps) {
      DropShape c;
      c.footprint_radius = draw(options.width, rng) * drop.footprint_radius;
      c.contact_angle = draw(options.contact_angle_deg, rng) * kDeg;
      if (!trail.empty()) offset += draw(options.spacing, rng) * (previous_radius + c.footprint_radius);
      const double v = drop_volume(c);
      if (offset > length || taken + v > budget) break;
      taken += v;
      previous_radius = c.footprint_radius;
      c.trail_of = static_cast<int>(i);
      trail.push_back(c);
      offsets.push_back(offset);
    }
    if (trail.empty()) continue;
    // Every other dimension kept, the volume goes as the footprint radius cubed.
    drop.footprint_radius *= std::cbrt((volume - taken) / volume);
    const double rim = uphill_rim_distance(drop);
    const glm::dvec2 centre = drop.center;  // `drop` dangles once the vector grows
    for (size_t k = 0; k < trail.size(); ++k) {
      trail[k].center = centre - glm::dvec2(0.0, rim + offsets[k]);
      drops->push_back(trail[k]);
    }
  }
}

}  // namespace raindrop

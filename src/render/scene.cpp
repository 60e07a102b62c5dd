#include "raindrop/render/scene.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "raindrop/common/error.h"
#include "raindrop/render/srgb.h"
#include "raindrop/render/coalesce.h"
#include "raindrop/render/trails.h"

namespace raindrop {
namespace {

constexpr double kDeg = M_PI / 180.0;

}  // namespace

double draw(const Range& r, Rng& rng) { return r.lo == r.hi ? r.lo : rng.uniform(r.lo, r.hi); }

SceneSample sample_scene(const SceneConfig& config, const Camera& camera, Rng& rng) {
  SceneSample s;
  s.glass.distance = draw(config.glass_distance_cm, rng);
  s.glass.tilt = draw(config.tilt_deg, rng) * kDeg;
  s.background_distance_cm = draw(config.background_distance_cm, rng);
  if (config.blur.enabled) {
    s.blur_diameter_px = draw(config.blur.diameter_px_2048, rng) * camera.width / 2048.0;
  }
  if (config.lens.enabled) {
    s.f_number = draw(config.lens.f_number, rng);
    s.focal_length_mm = draw(config.lens.focal_length_mm, rng);
  }
  const int random_drops = rng.uniform_int(static_cast<int>(config.drop_count.lo),
                                           static_cast<int>(config.drop_count.hi));
  s.drops_requested = random_drops + static_cast<int>(config.drops.size());

  // Glass area seen by one pixel is proportional to 1 / (d . n)^3 (d = (x', y', 1) the pixel's
  // ray, n the glass normal); accepting a uniformly drawn pixel with probability
  // w / w_max makes the drop centres uniform on the glass. w_max is at a frame corner row
  // (d . n is linear in the row and constant along it) unless some rows miss the glass.
  const glm::dvec3 n = s.glass.normal();
  // An irregular outline (drawn last, below) stays within this factor of the drop's circle.
  // Where footprints must stay apart, placement keeps that circle clear of the others; where
  // they may overlap, the circles placement counts overlaps with are the drops' own, so that
  // turning outlines on moves no drop.
  const double outline_bound =
      config.outline.enabled && !config.allow_overlap ? 1.0 + config.outline.peak_deviation.hi : 1.0;
  const double max_radius_cm =
      (config.size_param == DropSizeParam::FootprintRadius
           ? config.drop_size_cm.hi
           : config.drop_size_cm.hi * std::sin(config.contact_angle_deg.hi * kDeg)) *
      (config.gravity.enabled ? config.gravity.elongation.hi : 1.0);
  // Margin: a drop centre may lie this many pixels outside the frame, so drops get cut by
  // the frame edge as in real footage.
  const double margin = std::min(camera.fx * max_radius_cm / s.glass.distance,
                                 0.5 * std::min(camera.width, camera.height));
  const double x0 = -margin, x1 = camera.width - 1 + margin;
  const double y0 = -margin, y1 = camera.height - 1 + margin;
  auto weight = [&](double y) {
    const double dn = glm::dot(camera.ray_direction(0, y), n);  // independent of x
    return dn > 1e-9 ? 1.0 / (dn * dn * dn) : 0.0;
  };
  const double w_max = std::max(weight(y0), weight(y1));

  struct Placed { glm::dvec2 centre; double radius; };
  std::vector<Placed> placed;
  constexpr int kAttempts = 200;
  // Even with allow_overlap a drop may overlap at most this many placed drops, so no point of
  // the glass lies under more than kMaxOverlaps + 1 drops. Every ray is traced through the
  // drops over its pixel, so unbounded piles cost time without use (1000 large overlapping
  // drops took 50 s on a 128x64 frame, 5000 more than 4 minutes on small ones), and water
  // drops that touch merge: deep piles are not rain on glass. (Without overlaps the same test
  // with the gap keeps the old behaviour exactly.)
  constexpr int kMaxOverlaps = 4;
  const int overlaps_allowed = config.allow_overlap ? kMaxOverlaps : 0;
  const double gap = config.allow_overlap ? 0.0 : config.min_gap_cm;
  // The scene's own drops first, as given; the random ones keep clear of them.
  for (size_t i = 0; i < config.drops.size(); ++i) {
    const PlacedDrop& p = config.drops[i];
    DropShape shape;
    shape.contact_angle = p.contact_angle_deg * kDeg;
    shape.footprint_radius =
        p.size_param == DropSizeParam::FootprintRadius ? p.size_cm : p.size_cm * std::sin(shape.contact_angle);
    if (p.at_pixel) {
      const glm::dvec3 ray = camera.ray_direction(p.x, p.y);
      const auto t = s.glass.intersect({0, 0, 0}, ray);
      if (!t)
        throw Error("scene '" + config.name + "': drops[" + std::to_string(i) + "]: the camera does not see the glass at pixel (" +
                    std::to_string(p.x) + ", " + std::to_string(p.y) + ")");
      shape.center = s.glass.coords(*t * ray);
    } else {
      shape.center = {p.x, p.y};
      // Behind the camera (or beside it) the glass is nowhere in view, and a drop there has no
      // image: its circle of confusion, spread and shift came out NaN in the manifest.
      // (The footprint's depth varies by its radius times cos(tilt) about its centre's.)
      if (s.glass.point(shape.center).z <= shape.footprint_radius * outline_bound * std::abs(std::cos(s.glass.tilt)))
        throw Error("scene '" + config.name + "': drops[" + std::to_string(i) + "]: the glass at (" +
                    std::to_string(p.x) + ", " + std::to_string(p.y) + ") cm is not in front of the camera");
    }
    placed.push_back({shape.center, shape.footprint_radius * outline_bound});
    s.drops.push_back(shape);
  }
  for (int i = 0; i < random_drops; ++i) {
    DropShape shape;
    const double size = config.size_distribution == SizeDistribution::LogUniform
                            ? std::exp(draw({std::log(config.drop_size_cm.lo), std::log(config.drop_size_cm.hi)}, rng))
                            : draw(config.drop_size_cm, rng);
    shape.contact_angle = draw(config.contact_angle_deg, rng) * kDeg;
    shape.footprint_radius = config.size_param == DropSizeParam::FootprintRadius
                                 ? size
                                 : size * std::sin(shape.contact_angle);
    if (config.gravity.enabled) {
      shape.elongation = draw(config.gravity.elongation, rng);
      shape.flattening = draw(config.gravity.flattening, rng);
    }
    const double radius = shape.footprint_radius * shape.elongation * outline_bound;
    for (int attempt = 0; attempt < kAttempts && w_max > 0; ++attempt) {
      const double px = rng.uniform(x0, x1), py = rng.uniform(y0, y1);
      if (rng.uniform() * w_max > weight(py)) continue;
      const auto t = s.glass.intersect({0, 0, 0}, camera.ray_direction(px, py));
      if (!t) continue;
      shape.center = s.glass.coords(*t * camera.ray_direction(px, py));
      int overlaps = 0;
      for (const Placed& p : placed) {
        if (glm::length(p.centre - shape.center) < p.radius + radius + gap && ++overlaps > overlaps_allowed) break;
      }
      if (overlaps > overlaps_allowed) continue;
      placed.push_back({shape.center, radius});
      s.drops.push_back(shape);
      break;
    }
  }
  // Touching drops merge (coalesce.h): before the outlines, which are drawn per drop, so the
  // merged drops are round and later draws do not depend on the drops' positions.
  if (config.coalesce) coalesce_drops(&s.drops);
  if (config.highlights.enabled) {
    s.highlights.threshold = static_cast<float>(srgb_to_linear(config.highlights.threshold));
    s.highlights.gain = static_cast<float>(draw(config.highlights.gain, rng));
  }
  // Outlines last, so that turning them on changes no earlier draw (placement only keeps the
  // larger bounding circles apart). The circle is shrunk to keep the footprint's area.
  if (config.outline.enabled) {
    for (DropShape& shape : s.drops) {
      const double peak = draw(config.outline.peak_deviation, rng);
      shape.outline = Outline::draw(peak, config.outline.modes, rng);
      shape.footprint_radius /= std::sqrt(shape.outline.mean_square());
    }
  }
  // Trails after everything else, so that turning them on changes no other draw; a drop that
  // slid only shrinks by the water it left behind (trails.h).
  if (config.trails.enabled) {
    add_trails(&s.drops, config.trails, s.glass.tilt, rng);
    // A long trail up a tilted glass can run past the camera's plane, where nothing is in view
    // (its caps' projections were NaN). Those caps are left out after every draw, so the rest
    // of the scene is drawn as before; their water stays taken from the drop.
    s.drops.erase(std::remove_if(s.drops.begin(), s.drops.end(),
                                 [&](const DropShape& d) {
                                   return d.trail_of >= 0 &&
                                          s.glass.point(d.center).z <= d.footprint_radius * std::abs(std::cos(s.glass.tilt));
                                 }),
                  s.drops.end());
  }
  // The plane of focus last of all, for the same reason: a scene focused on its background
  // draws nothing here. On the glass: where the optical axis meets it (depth N).
  if (config.lens.enabled && config.lens.focus == SceneConfig::Focus::Glass) s.focus_distance_cm = s.glass.distance;
  if (config.lens.enabled && config.lens.focus == SceneConfig::Focus::Distance)
    s.focus_distance_cm = draw(config.lens.focus_distance_cm, rng);
  return s;
}

}  // namespace raindrop

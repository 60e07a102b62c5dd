#include "raindrop/render/aperture_reach.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace raindrop {

ApertureReach::ApertureReach(const std::vector<Drop>& drops, double aperture_radius_cm, double focus_cm)
    : inv_focus_(1.0 / focus_cm) {
  // Padded far beyond any rounding of the tests below and of the drops' own intersections
  // (DropAccel pads its boxes by 1e-6 of their coordinates for the same reason).
  const double a = aperture_radius_cm * (1 + 1e-6) + 1e-9;
  spheres_.reserve(drops.size());
  for (const Drop& drop : drops) {
    glm::dvec3 lo, hi;
    drop.bounds(&lo, &hi);
    Sphere s;
    s.centre = 0.5 * (lo + hi);
    s.radius = 0.5 * glm::length(hi - lo) * (1 + 1e-6) + 1e-6 * (glm::length(lo) + glm::length(hi)) + 1e-9;
    s.z0 = s.centre.z - s.radius;
    s.z1 = s.centre.z + s.radius;
    s.cone_reach = a * std::max(std::abs(1 - s.z0 * inv_focus_), std::abs(1 - s.z1 * inv_focus_)) + s.radius;
    spheres_.push_back(s);
  }
}

bool ApertureReach::cone_meets(int drop, const glm::dvec3& focus) const {
  const Sphere& s = spheres_[static_cast<size_t>(drop)];
  // The cone's axis at depths z0 and z1: the pixel's pinhole ray, (z / F) focus.
  const double ax = focus.x * inv_focus_, ay = focus.y * inv_focus_;
  const double x0 = s.z0 * ax, y0 = s.z0 * ay;
  const double ex = (s.z1 - s.z0) * ax, ey = (s.z1 - s.z0) * ay;
  // The sphere's centre against the segment from (x0, y0) along (ex, ey).
  const double px = s.centre.x - x0, py = s.centre.y - y0;
  const double len2 = ex * ex + ey * ey;
  const double t = len2 > 0 ? std::clamp((px * ex + py * ey) / len2, 0.0, 1.0) : 0.0;
  const double dx = px - t * ex, dy = py - t * ey;
  // Slack for the rounding of this test itself.
  const double reach = s.cone_reach * (1 + 1e-9);
  return dx * dx + dy * dy <= reach * reach;
}

bool ApertureReach::ray_meets(int drop, const glm::dvec3& origin, const glm::dvec3& dir) const {
  const Sphere& s = spheres_[static_cast<size_t>(drop)];
  const glm::dvec3 v = s.centre - origin;
  const glm::dvec3 c = glm::cross(v, dir);
  const double r = s.radius * (1 + 1e-9);
  return glm::dot(c, c) <= r * r * glm::dot(dir, dir);
}

}  // namespace raindrop

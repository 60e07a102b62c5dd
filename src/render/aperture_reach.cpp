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
    // Two spheres hold the drop; the smaller is kept. The box's: around its bounding box. The
    // footprint's: centred on the footprint, as wide as its longer semi-axis. A cap of contact
    // angle at most 90 degrees lies within that distance of the footprint's centre (in the frame
    // where it is a spherical cap of footprint radius r, a point of it at height z >= 0 lies at
    // distance^2 r^2 - 2 z (R - h) <= r^2; an irregular outline lies under the cap of its widest
    // radius, drop.h; gravity's stretch along the slope, at least 1, and flattening, at most 1,
    // scale no distance by more than the stretch). For a drop on a tilted glass the box's sphere
    // is about 1.4 times wider: with this one the reference has about an eighth fewer pixels near
    // windshield drops to trace (docs/RESULTS.md 4.69), most of whose rays would have missed.
    // Padded by the drop's coordinates and the aperture's radius: a mesh drop's triangles are met
    // by Embree in float, relative to a ray's origin, so its hits stray by about 1e-7 of the
    // distance from a lens point (up to the aperture's radius off the axis) to the drop.
    const double pad = 1e-6 * (glm::length(lo) + glm::length(hi) + aperture_radius_cm) + 1e-9;
    const double box_radius = 0.5 * glm::length(hi - lo) * (1 + 1e-6) + pad;
    const double footprint_radius = drop.shape().footprint_semi_axes().y * (1 + 1e-6) + pad;
    if (footprint_radius < box_radius) {
      s.centre = drop.centre();
      s.radius = footprint_radius;
    } else {
      s.centre = 0.5 * (lo + hi);
      s.radius = box_radius;
    }
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

std::vector<std::vector<DropSpan>> ApertureReach::candidate_boxes(const Camera& camera, const SceneSample& scene,
                                                                  const std::vector<Drop>& drops) {
  const double fxy = std::max(camera.fx, camera.fy);  // the circle's larger axis in pixels
  const double frame_reach = 4.0 * (camera.width + camera.height);  // beyond it: the whole frame
  std::vector<std::vector<DropSpan>> rows(camera.height);
  for (size_t i = 0; i < drops.size(); ++i) {
    glm::dvec3 lo, hi;
    drops[i].bounds(&lo, &hi);
    double bx0 = -frame_reach, bx1 = camera.width + frame_reach, by0 = -frame_reach, by1 = camera.height + frame_reach;
    if (lo.z > 1e-9) {  // else it reaches behind the camera: the whole frame
      const double reach = std::max({0.5 * scene.drop_coc_px(drops[i].shape(), fxy), 0.5 * scene.coc_px(lo.z, fxy),
                                     0.5 * scene.coc_px(hi.z, fxy)}) + 1.0;
      bx0 = by0 = INFINITY;
      bx1 = by1 = -INFINITY;
      for (int c = 0; c < 8; ++c) {
        const glm::dvec2 p = camera.project({(c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z});
        bx0 = std::min(bx0, p.x), bx1 = std::max(bx1, p.x), by0 = std::min(by0, p.y), by1 = std::max(by1, p.y);
      }
      bx0 -= reach, by0 -= reach, bx1 += reach, by1 += reach;
    }
    const int x0 = static_cast<int>(std::max(0.0, std::floor(bx0)));
    const int x1 = static_cast<int>(std::min(camera.width - 1.0, std::ceil(bx1)));
    const int y0 = static_cast<int>(std::max(0.0, std::floor(by0)));
    const int y1 = static_cast<int>(std::min(camera.height - 1.0, std::ceil(by1)));
    for (int y = y0; y <= y1 && x0 <= x1; ++y) rows[y].push_back({x0, x1, static_cast<int>(i)});
  }
  for (auto& r : rows)
    std::sort(r.begin(), r.end(), [](const DropSpan& a, const DropSpan& b) { return a.first < b.first; });
  return rows;
}

void ApertureReach::near_drops(const std::vector<DropSpan>& row_boxes, int x, const glm::dvec3& focus,
                               std::vector<int>* near) const {
  near->clear();
  for (const DropSpan& b : row_boxes) {
    if (b.first > x) break;
    if (b.last >= x && cone_meets(b.drop, focus)) near->push_back(b.drop);
  }
}

bool ApertureReach::ray_meets(int drop, const glm::dvec3& origin, const glm::dvec3& dir) const {
  const Sphere& s = spheres_[static_cast<size_t>(drop)];
  const glm::dvec3 v = s.centre - origin;
  const glm::dvec3 c = glm::cross(v, dir);
  const double r = s.radius * (1 + 1e-9);
  return glm::dot(c, c) <= r * r * glm::dot(dir, dir);
}

}  // namespace raindrop

#include "raindrop/render/drop.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace raindrop {

double DropShape::sphere_radius() const { return footprint_radius / std::sin(contact_angle); }

double DropShape::height() const {
  return flattening * sphere_radius() * (1.0 - std::cos(contact_angle));
}

Drop::Drop(const DropShape& shape, const GlassPlane& glass)
    : shape_(shape),
      c_(glass.point(shape.center)),
      u_(glass.across()),
      v_(glass.downhill()),
      n_(glass.normal()),
      radius_(shape.sphere_radius()),
      centre_height_(-shape.sphere_radius() * std::cos(shape.contact_angle)),
      rim_radius2_(shape.footprint_radius * shape.footprint_radius),
      inv_elongation_(1.0 / shape.elongation),
      inv_flattening_(1.0 / shape.flattening) {}

// Scaled local frame: x across, y downhill / elongation, z height / flattening.
glm::dvec3 Drop::to_local(const glm::dvec3& p) const { return dir_to_local(p - c_); }

glm::dvec3 Drop::dir_to_local(const glm::dvec3& d) const {
  return {glm::dot(d, u_), glm::dot(d, v_) * inv_elongation_, glm::dot(d, n_) * inv_flattening_};
}

std::optional<SurfaceHit> Drop::intersect(const glm::dvec3& origin, const glm::dvec3& dir,
                                          double t_min, double t_max,
                                          std::optional<DropSurface> start) const {
  const glm::dvec3 o = to_local(origin);
  const glm::dvec3 d = dir_to_local(dir);
  std::optional<SurfaceHit> best;
  auto consider = [&](double t, DropSurface s) {
    if (t > t_min && t < t_max && (!best || t < best->t)) best = SurfaceHit{t, s, {}};
  };

  // Flat base in the plane z = 0. A ray leaving the base cannot meet that plane again.
  if (start != DropSurface::Base && d.z != 0.0) {
    const double t = -o.z / d.z;
    const double x = o.x + t * d.x, y = o.y + t * d.y;
    if (x * x + y * y <= rim_radius2_) consider(t, DropSurface::Base);
  }

  // Curved surface: sphere of radius R centred at (0, 0, centre_height), part with z >= 0.
  const glm::dvec3 oc{o.x, o.y, o.z - centre_height_};
  const double a = glm::dot(d, d);
  const double b = glm::dot(oc, d);
  // A ray starting on the sphere has c = 0 up to rounding; setting it to 0 leaves the roots
  // t = 0 (dropped below) and t = -2b/a exactly.
  const double c = start == DropSurface::Cap ? 0.0 : glm::dot(oc, oc) - radius_ * radius_;
  const double disc = b * b - a * c;
  if (a > 0 && disc >= 0) {
    const double sq = std::sqrt(disc);
    // Numerically stable pair of roots (no cancellation between -b and sq).
    const double q = -(b + std::copysign(sq, b));
    double roots[2] = {q / a, q != 0 ? c / q : 0.0};
    if (start == DropSurface::Cap) {
      // Keep the root that is not the starting point.
      roots[0] = std::abs(roots[0]) > std::abs(roots[1]) ? roots[0] : roots[1];
      roots[1] = roots[0];
    }
    for (double t : roots) {
      if (o.z + t * d.z >= 0.0) consider(t, DropSurface::Cap);
    }
  }

  if (best) {
    const glm::dvec3 p = origin + best->t * dir;
    best->normal = best->surface == DropSurface::Base ? base_normal() : cap_normal(p);
  }
  return best;
}

glm::dvec3 Drop::cap_normal(const glm::dvec3& p) const {
  const glm::dvec3 l = to_local(p);
  // Sphere normal in the scaled frame, mapped back with the inverse transpose of the scaling.
  const glm::dvec3 m{l.x, l.y, l.z - centre_height_};
  const glm::dvec3 world = m.x * u_ + (m.y * inv_elongation_) * v_ + (m.z * inv_flattening_) * n_;
  const double len = glm::length(world);
  return len > 0 ? world / len : n_;
}

glm::dvec3 Drop::cap_point(double theta, double phi) const {
  const double x = radius_ * std::sin(theta) * std::cos(phi);
  const double y = radius_ * std::sin(theta) * std::sin(phi);
  const double z = std::max(0.0, centre_height_ + radius_ * std::cos(theta));
  return c_ + x * u_ + (y * shape_.elongation) * v_ + (z * shape_.flattening) * n_;
}

void Drop::bounds(glm::dvec3* lo, glm::dvec3* hi) const {
  const glm::dvec2 ab = shape_.footprint_semi_axes();
  const double h = shape_.height();
  *lo = glm::dvec3(1e300);
  *hi = glm::dvec3(-1e300);
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 p = c_ + ((i & 1) ? ab.x : -ab.x) * u_ + ((i & 2) ? ab.y : -ab.y) * v_ +
                         ((i & 4) ? h : 0.0) * n_;
    *lo = glm::min(*lo, p);
    *hi = glm::max(*hi, p);
  }
}

}  // namespace raindrop

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
  if (!shape_.outline.circular()) {
    auto hit = intersect_irregular(o, d, t_min, t_max, start);
    if (hit) hit->normal = hit->surface == DropSurface::Base ? base_normal() : cap_normal(origin + hit->t * dir);
    return hit;
  }
  std::optional<SurfaceHit> best;
  auto consider = [&](double t, DropSurface s) {
    if (t > t_min && t < t_max && (!best || t < best->t)) best = SurfaceHit{t, s, {}};
  };

  // Flat base in the plane z = 0. A ray leaving the base cannot meet that plane again.
  if (start != DropSurface::Base && d.z != 0.0) {
    const double t = -o.z / d.z;
    const double x = o.x + t * d.x, y = o.y + t * d.y;
    if (x * x + y * y <= rim_radius2_) consider(t, DropSurface::Base);
    // A ray heading out of the glass (d.z > 0) through the base is below the plane before it
    // and the cap lies above it: the base is its nearest hit, and the sphere's roots (a square
    // root and two divisions, for most camera rays) need not be asked. Every camera ray that
    // meets a drop first meets it here.
    if (best && d.z > 0.0) {
      best->normal = base_normal();
      return best;
    }
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

double Drop::implicit(const glm::dvec3& l) const {
  const double rho2 = l.x * l.x + l.y * l.y;
  const double dz = l.z - centre_height_;
  if (rho2 == 0.0) return dz * dz - radius_ * radius_;  // on the axis the outline does not matter
  const double inv_rho = 1.0 / std::sqrt(rho2);
  const double s = shape_.outline.s_at(l.x * inv_rho, l.y * inv_rho);
  return rho2 / (s * s) + dz * dz - radius_ * radius_;
}

bool Drop::contains(const glm::dvec3& p) const {
  const glm::dvec3 l = to_local(p);
  return l.z >= 0.0 && implicit(l) <= 0.0;
}

// The stretched cap has no closed-form intersection. Along the pieces of the ray where the
// surface can be (below), the implicit function is sampled at steps finer than the outline's
// smallest lobe and than the height, and the first sign change is refined by the Illinois
// method to the limit of double precision. Sign changes closer together than a step (a ray
// grazing a lobe) can be missed: the test against a fine march (tests/render/test_outline.cpp)
// measures how often.
std::optional<SurfaceHit> Drop::intersect_irregular(const glm::dvec3& o, const glm::dvec3& d, double t_min,
                                                    double t_max, std::optional<DropSurface> start) const {
  const Outline& outline = shape_.outline;
  const double a = shape_.footprint_radius;
  const double height = radius_ + centre_height_;  // scaled frame
  std::optional<SurfaceHit> best;

  // Flat base: inside the outline where the ray meets z = 0.
  if (start != DropSurface::Base && d.z != 0.0) {
    const double t = -o.z / d.z;
    if (t > t_min && t < t_max) {
      const double x = o.x + t * d.x, y = o.y + t * d.y, rho2 = x * x + y * y;
      const double inv_rho = rho2 > 0.0 ? 1.0 / std::sqrt(rho2) : 0.0;
      const double rim = rho2 > 0.0 ? a * outline.s_at(x * inv_rho, y * inv_rho) : a;
      if (rho2 <= rim * rim) best = SurfaceHit{t, DropSurface::Base, {}};
    }
  }

  // The stretched cap lies between two caps of circular outline, radially scaled by s_min
  // (inner: all water) and s_max (envelope: holds all the water), both spheroids in this frame
  // with closed-form intervals along the ray. The surface can only be crossed inside the
  // envelope and outside the inner cap, so only those one or two pieces of the ray are searched:
  // a ray through the water skips the part where it is certainly wet.
  const double t_lo = start == DropSurface::Cap ? std::max(t_min, 1e-9 * std::max(a, height) / std::sqrt(glm::dot(d, d)))
                                                : t_min;
  const double t_hi = best ? best->t : t_max;
  auto interval = [&](double k, double* lo, double* hi) {  // the ray inside the cap scaled by k
    const glm::dvec3 os{o.x / k, o.y / k, o.z - centre_height_}, ds{d.x / k, d.y / k, d.z};
    const double qa = glm::dot(ds, ds), qb = glm::dot(os, ds), qc = glm::dot(os, os) - radius_ * radius_;
    const double disc = qb * qb - qa * qc;
    if (!(qa > 0.0) || disc < 0.0) return false;
    const double sq = std::sqrt(disc);
    *lo = (-qb - sq) / qa, *hi = (-qb + sq) / qa;
    if (d.z > 0.0) {
      *lo = std::max(*lo, -o.z / d.z);
    } else if (d.z < 0.0) {
      *hi = std::min(*hi, -o.z / d.z);
    } else if (o.z < 0.0) {
      return false;
    }
    return *lo < *hi;
  };
  double e0, e1;
  if (!interval(outline.s_max(), &e0, &e1)) return best;
  // Rounding of the closed forms: widen the envelope's piece, narrow the inner one.
  const double pad = 1e-9 * (e1 - e0) + 1e-12 * (std::abs(e0) + std::abs(e1));
  e0 = std::max(e0 - pad, t_lo), e1 = std::min(e1 + pad, t_hi);
  if (!(e0 < e1)) return best;
  double pieces[2][2] = {{e0, e1}, {e1, e1}};
  double i0, i1;
  if (interval(outline.s_min(), &i0, &i1) && i1 - i0 > 2 * pad) {
    pieces[0][1] = std::clamp(i0 + pad, e0, e1);
    pieces[1][0] = std::clamp(i1 - pad, e0, e1);
  }

  // Step: a fifth of the narrowest lobe (the rim's arc over the highest mode's half period at
  // the smallest radius) and of the height.
  const double len = std::sqrt(glm::dot(d, d));
  const int modes = static_cast<int>(outline.cos_terms().size()) + 1;
  const double lobe = a * outline.s_min() * M_PI / (modes + 1);
  const double step = 0.2 * std::min(lobe, height) / len;
  auto g = [&](double t) { return implicit(o + t * d); };
  for (const auto& piece : pieces) {
    const double t0 = piece[0], t1 = piece[1];
    if (!(t0 < t1)) continue;
    const int n = std::clamp(static_cast<int>(std::ceil((t1 - t0) / step)), 2, 4096);
    double ta = t0, ga = g(ta);
    for (int i = 1; i <= n; ++i) {
      const double tb = t0 + (t1 - t0) * i / n;
      const double gb = g(tb);
      if ((ga < 0.0) != (gb < 0.0)) {
        // Illinois: regula falsi that halves the stale end's value, superlinear and bracketed.
        double lo = ta, hi = tb, glo = ga, ghi = gb;
        int side = 0;
        for (int it = 0; it < 100 && hi - lo > 1e-14 * std::max(std::abs(lo), std::abs(hi)) + 1e-300; ++it) {
          double tm = (lo * ghi - hi * glo) / (ghi - glo);
          if (!(tm > lo && tm < hi)) tm = 0.5 * (lo + hi);
          const double gm = g(tm);
          if (gm == 0.0) {
            lo = hi = tm;
            break;
          }
          if ((gm < 0.0) == (glo < 0.0)) {
            lo = tm, glo = gm;
            if (side == -1) ghi *= 0.5;
            side = -1;
          } else {
            hi = tm, ghi = gm;
            if (side == 1) glo *= 0.5;
            side = 1;
          }
        }
        const double t = 0.5 * (lo + hi);
        if (t > t_min && t < t_max && (!best || t < best->t)) best = SurfaceHit{t, DropSurface::Cap, {}};
        return best;
      }
      ta = tb, ga = gb;
    }
  }
  return best;
}

glm::dvec3 Drop::cap_normal(const glm::dvec3& p) const {
  const glm::dvec3 l = to_local(p);
  // Sphere normal in the scaled frame, mapped back with the inverse transpose of the scaling.
  glm::dvec3 m{l.x, l.y, l.z - centre_height_};
  if (!shape_.outline.circular()) {
    // Half the gradient of the implicit function rho^2 / s^2 + (z - zc)^2 - R^2, with
    // d phi / dx = -y / rho^2 and d phi / dy = x / rho^2.
    double s, ds;
    shape_.outline.s_and_slope(std::atan2(l.y, l.x), &s, &ds);
    const double s2 = s * s, k = ds / (s2 * s);
    m = {l.x / s2 + k * l.y, l.y / s2 - k * l.x, l.z - centre_height_};
  }
  const glm::dvec3 world = m.x * u_ + (m.y * inv_elongation_) * v_ + (m.z * inv_flattening_) * n_;
  const double len = glm::length(world);
  return len > 0 ? world / len : n_;
}

glm::dvec3 Drop::cap_point(double theta, double phi) const {
  const double stretch = shape_.outline.circular() ? 1.0 : shape_.outline.s(phi);
  const double x = stretch * radius_ * std::sin(theta) * std::cos(phi);
  const double y = stretch * radius_ * std::sin(theta) * std::sin(phi);
  const double z = std::max(0.0, centre_height_ + radius_ * std::cos(theta));
  return c_ + x * u_ + (y * shape_.elongation) * v_ + (z * shape_.flattening) * n_;
}

glm::dvec3 Drop::envelope_point(double theta, double phi) const {
  const double stretch = shape_.outline.s_max();
  const double x = stretch * radius_ * std::sin(theta) * std::cos(phi);
  const double y = stretch * radius_ * std::sin(theta) * std::sin(phi);
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

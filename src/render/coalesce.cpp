#include "raindrop/render/coalesce.h"

#include <cmath>

#include "raindrop/render/trails.h"

namespace raindrop {
namespace {

// Volume of a round spherical cap with footprint radius 1 and contact angle `tau`, cm^3 per cm^3.
double unit_cap_volume(double tau) {
  const double R = 1.0 / std::sin(tau), h = R * (1.0 - std::cos(tau));
  return M_PI * h * h * (3.0 * R - h) / 3.0;
}

double enclosing_radius(const DropShape& d) { return d.footprint_radius * d.elongation; }

bool overlap(const DropShape& a, const DropShape& b) {
  const glm::dvec2 d = a.center - b.center;
  const double r = enclosing_radius(a) + enclosing_radius(b);
  return d.x * d.x + d.y * d.y < r * r;
}

}  // namespace

DropShape merge_drops(const DropShape& a, const DropShape& b) {
  const double va = drop_volume(a), vb = drop_volume(b), v = va + vb;
  const double wa = va / v, wb = vb / v;
  DropShape m;
  m.center = wa * a.center + wb * b.center;
  m.contact_angle = wa * a.contact_angle + wb * b.contact_angle;
  m.elongation = wa * a.elongation + wb * b.elongation;
  m.flattening = wa * a.flattening + wb * b.flattening;
  // drop_volume = a^3 unit_cap_volume(tau) elongation flattening (a round outline: <s^2> = 1).
  m.footprint_radius = std::cbrt(v / (unit_cap_volume(m.contact_angle) * m.elongation * m.flattening));
  return m;
}

int coalesce_drops(std::vector<DropShape>* drops) {
  std::vector<DropShape>& d = *drops;
  int merges = 0;
  // The first overlapping pair in order, merged into its first drop, until none is left: simple
  // rather than fast (a few hundred drops at most: under n^3 / 2 tests of two circles).
  for (;;) {
    bool merged = false;
    for (size_t i = 0; i < d.size() && !merged; ++i) {
      for (size_t j = i + 1; j < d.size(); ++j) {
        if (!overlap(d[i], d[j])) continue;
        d[i] = merge_drops(d[i], d[j]);
        d.erase(d.begin() + static_cast<std::ptrdiff_t>(j));
        ++merges;
        merged = true;
        break;
      }
    }
    if (!merged) return merges;
  }
}

}  // namespace raindrop

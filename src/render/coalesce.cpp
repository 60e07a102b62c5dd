#include "raindrop/render/coalesce.h"

#include <algorithm>
#include <cmath>

#include "raindrop/render/trails.h"

namespace raindrop {
namespace {

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
  // drop_volume goes with a^3 at a fixed angle, stretch and flattening (a round outline): the
  // water of the same drop with a footprint radius of 1 sets a.
  m.footprint_radius = 1.0;
  m.footprint_radius = std::cbrt(v / drop_volume(m));
  return m;
}

int coalesce_drops(std::vector<DropShape>* drops) {
  std::vector<DropShape>& d = *drops;
  int merges = 0;
  // Invariant: no two of the drops before i overlap. Drop i takes in every drop after it that it
  // touches, growing as it goes; if it touches one before it, that one takes it in instead and
  // the scan goes on from there (the drops in between are checked again as they come). Each
  // check of a drop is one pass over the others: O(n^2 + merges n) tests of two circles.
  for (size_t i = 0; i < d.size();) {
    size_t touched = d.size();
    for (size_t j = 0; j < d.size(); ++j) {
      if (j != i && overlap(d[i], d[j])) {
        touched = j;
        break;
      }
    }
    if (touched == d.size()) {
      ++i;
      continue;
    }
    const size_t keep = std::min(i, touched), gone = std::max(i, touched);
    d[keep] = merge_drops(d[keep], d[gone]);
    d.erase(d.begin() + static_cast<std::ptrdiff_t>(gone));
    ++merges;
    i = keep;
  }
  return merges;
}

}  // namespace raindrop

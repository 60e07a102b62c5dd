#include "raindrop/render/disk_kernel.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <vector>

namespace raindrop {
namespace {

// Area of the unit pixel [x-0.5,x+0.5]x[y-0.5,y+0.5] inside the disk of radius r, by a
// 16x16 midpoint rule (exact for pixels entirely in or out; error < 1/256 of a pixel on the
// rim, far below 8-bit resolution after normalisation).
double pixel_area_in_disk(int x, int y, double r) {
  // Entirely inside (farthest corner within r) or outside (nearest point beyond r): exact.
  const double fx = std::abs(x) + 0.5, fy = std::abs(y) + 0.5;
  if (fx * fx + fy * fy <= r * r) return 1.0;
  const double nx = std::max(std::abs(x) - 0.5, 0.0), ny = std::max(std::abs(y) - 0.5, 0.0);
  if (nx * nx + ny * ny >= r * r) return 0.0;
  constexpr int kSub = 16;
  int inside = 0;
  for (int j = 0; j < kSub; ++j) {
    const double yy = y - 0.5 + (j + 0.5) / kSub;
    auto in = [&](int i) {
      const double xx = x - 0.5 + (i + 0.5) / kSub;
      return xx * xx + yy * yy <= r * r;
    };
    if (x == 0) {
      for (int i = 0; i < kSub; ++i) inside += in(i);
      continue;
    }
    // Off the centre column the sub-points' |xx| grows one way along the row (and so does the
    // rounded xx * xx + yy * yy): the points inside are a run from the end nearer the centre.
    // Its length from the circle's chord, then checked and corrected with the same test, so
    // the count is the one point by point.
    const auto nth = [&](int m) { return x > 0 ? m : kSub - 1 - m; };  // m-th point from the centre's side
    const double chord = r * r - yy * yy;
    int n = 0;
    if (chord > 0) {
      const double guess = (std::sqrt(chord) - std::abs(x) + 0.5) * kSub + 0.5;
      n = static_cast<int>(std::clamp(std::floor(guess), 0.0, static_cast<double>(kSub)));
    }
    while (n < kSub && in(nth(n))) ++n;
    while (n > 0 && !in(nth(n - 1))) --n;
    inside += n;
  }
  return static_cast<double>(inside) / (kSub * kSub);
}

}  // namespace

std::vector<KernelRow> disk_rows(double diameter, bool antialiased, bool split_runs) {
  const double r = 0.5 * diameter;
  const int R = static_cast<int>(std::ceil(r + 0.5));
  std::vector<KernelRow> rows;
  if (r <= 0.5) {
    // The disk lies inside the centre pixel: the exact kernel is the identity (a midpoint
    // rule would miss a tiny disk entirely and leave no weight at all).
    KernelRow row;
    if (split_runs) {
      row.run_lo = row.run_hi = 0;
    } else {
      row.taps.push_back({0, 1.0f});
    }
    rows.push_back(row);
    return rows;
  }
  // The areas depend on |dx| and |dy| only, and are the same with the two swapped (the
  // sub-points of pixel -x are those of x negated, exactly: dyadic fractions of small
  // integers): one octant computed, the rest read from it.
  std::vector<double> octant;
  if (antialiased) {
    octant.resize(static_cast<size_t>(R + 1) * (R + 1));
    for (int b = 0; b <= R; ++b)
      for (int a = 0; a <= b; ++a) octant[static_cast<size_t>(b) * (R + 1) + a] = pixel_area_in_disk(a, b, r);
  }
  auto area = [&](int dx, int dy) {
    const int a = std::min(std::abs(dx), std::abs(dy)), b = std::max(std::abs(dx), std::abs(dy));
    return octant[static_cast<size_t>(b) * (R + 1) + a];
  };
  for (int dy = -R; dy <= R; ++dy) {
    KernelRow row;
    row.dy = dy;
    for (int dx = -R; dx <= R; ++dx) {
      const double w = antialiased ? area(dx, dy) : (dx * dx + dy * dy <= r * r ? 1.0 : 0.0);
      if (w <= 0) continue;
      if (split_runs && w >= 1.0 && (row.run_lo > row.run_hi || dx == row.run_hi + 1)) {
        if (row.run_lo > row.run_hi) row.run_lo = dx;
        row.run_hi = dx;
      } else {
        row.taps.push_back({dx, static_cast<float>(w)});
      }
    }
    if (row.run_lo <= row.run_hi || !row.taps.empty()) rows.push_back(std::move(row));
  }
  return rows;
}

}  // namespace raindrop

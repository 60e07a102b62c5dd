#include "raindrop/render/disk_kernel.h"

#include <algorithm>
#include <cmath>

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
    for (int i = 0; i < kSub; ++i) {
      const double xx = x - 0.5 + (i + 0.5) / kSub;
      inside += xx * xx + yy * yy <= r * r;
    }
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
  for (int dy = -R; dy <= R; ++dy) {
    KernelRow row;
    row.dy = dy;
    for (int dx = -R; dx <= R; ++dx) {
      const double w = antialiased ? pixel_area_in_disk(dx, dy, r) : (dx * dx + dy * dy <= r * r ? 1.0 : 0.0);
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

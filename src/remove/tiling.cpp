#include "raindrop/remove/tiling.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "raindrop/common/error.h"

namespace raindrop::removal {
namespace {

int round_down(int v, int a) { return v / a * a; }
int round_up(int v, int a) { return (v + a - 1) / a * a; }

// Weight of the window left of cut j at coordinate x: 1 before the ramp, 0 after it.
float left_weight(const AxisLayout& l, int j, int x) {
  const int c = l.cut[j], r = l.ramp[j];
  if (x < c - r) return 1.0f;
  if (x >= c + r) return 0.0f;
  const double t = (x + 0.5 - (c - r)) / (2.0 * r);  // in (0, 1) across the ramp
  return static_cast<float>(0.5 + 0.5 * std::cos(M_PI * t));
}

}  // namespace

void check_tile_options(int tile, int overlap) {
  if (tile < 0) throw Error("--tile must be >= 0 (0: never tile), got " + std::to_string(tile));
  if (overlap < 0) throw Error("--tile-overlap must be >= 0, got " + std::to_string(overlap));
  if (tile == 0) return;
  if (tile < 64) throw Error("--tile must be 0 or at least 64, got " + std::to_string(tile));
  if (2LL * overlap >= tile)  // in 64 bits: twice a large overlap wraps around in an int
    throw Error("--tile-overlap " + std::to_string(overlap) + " must be less than half of --tile " + std::to_string(tile));
}

float AxisLayout::weight(int i, int x) const {
  float w = 1.0f;
  if (i + 1 < count()) w = left_weight(*this, i, x);
  if (i > 0) w *= 1.0f - left_weight(*this, i - 1, x);
  return w;
}

AxisLayout layout_axis(int length, int tile, int overlap, int align) {
  AxisLayout l;
  if (tile <= 0 || length <= tile) {
    l.begin = {0};
    l.end = {length};
    return l;
  }
  // Rounding the starts down to `align` can shrink an overlap by align - 1: plan with a bit
  // more overlap, and with windows a bit smaller so the last one (which ends at `length`)
  // stays within the tile.
  const long long o = overlap + align - 1;
  long long t = round_down(tile, align) - align;
  // Starts are then >= (t - o) / 2 apart, so they stay distinct after rounding to `align`.
  t = std::max<long long>(t, o + 2LL * align);
  const long long n = std::max<long long>(2, (length - o + (t - o) - 1) / (t - o));
  long long win = (length + (n - 1) * o + n - 1) / n;
  win = round_up(static_cast<int>(win), align);
  for (long long i = 0; i < n; ++i) {
    int b = round_down(static_cast<int>(i * (length - win) / (n - 1)), align);
    if (i + 1 == n) b = round_down(static_cast<int>(length - win), align);
    l.begin.push_back(b);
    l.end.push_back(i + 1 == n ? length : static_cast<int>(std::min<long long>(b + win, length)));
  }
  for (long long i = 0; i + 1 < n; ++i) {
    const int a = l.begin[i + 1], e = l.end[i];
    l.cut.push_back((a + e) / 2);
    l.ramp.push_back((e - a) / 4);
  }
  // Neighbouring ramps must not overlap (possible only when windows are barely larger than
  // twice the overlap), or three windows would share a pixel and the weights would not sum to 1.
  for (size_t j = 0; j < l.cut.size(); ++j) {
    if (j > 0) l.ramp[j] = std::min(l.ramp[j], (l.cut[j] - l.cut[j - 1]) / 2);
    if (j + 1 < l.cut.size()) l.ramp[j] = std::min(l.ramp[j], (l.cut[j + 1] - l.cut[j]) / 2);
  }
  return l;
}

}  // namespace raindrop::removal

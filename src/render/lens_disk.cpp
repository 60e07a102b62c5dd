#include "raindrop/render/lens_disk.h"

#include <algorithm>

#include "raindrop/render/pinhole_lanes.h"

// The lanes' vectors and per-function targets are GCC's on x86-64, as pinhole_lanes.cpp's;
// elsewhere every point is lens_disk_point's own.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define RAINDROP_LENS_LANES 1
#else
#define RAINDROP_LENS_LANES 0
#endif

namespace raindrop {
namespace {

#if RAINDROP_LENS_LANES
#pragma GCC diagnostic ignored "-Wpsabi"
#pragma GCC push_options
#define LENS_NS lens_sse2
#define LENS_LEVEL 0
#include "lens_disk_kernel.inc"
#undef LENS_NS
#undef LENS_LEVEL
#pragma GCC pop_options

#pragma GCC push_options
#pragma GCC target("avx2")
#define LENS_NS lens_avx2
#define LENS_LEVEL 1
#include "lens_disk_kernel.inc"
#undef LENS_NS
#undef LENS_LEVEL
#pragma GCC pop_options

#pragma GCC push_options
#pragma GCC target("avx512f")
#define LENS_NS lens_avx512
#define LENS_LEVEL 2
#include "lens_disk_kernel.inc"
#undef LENS_NS
#undef LENS_LEVEL
#pragma GCC pop_options
#endif

}  // namespace

void lens_disk_points(int x, int y, int k, double radius, glm::dvec2* out) {
  const int n = k * k;
#if RAINDROP_LENS_LANES
  // In chunks of 64 strata (a multiple of every width), the last one padded by repeating its
  // last stratum; the lanes at the width the pinhole lanes use (PinholeLanes::level).
  constexpr int kChunk = 64;
  alignas(64) double si[kChunk], sj[kChunk], px[kChunk], py[kChunk];
  alignas(64) unsigned long salt[kChunk];
  const int level = PinholeLanes::level();
  const int width = level == 2 ? 8 : level == 1 ? 4 : 2;
  int i = 0, j = 0;  // the stratum of sample `first + c`, counted without divisions
  for (int first = 0; first < n; first += kChunk) {
    const int count = std::min(kChunk, n - first);
    const int padded = (count + width - 1) / width * width;
    for (int c = 0; c < count; ++c) {
      si[c] = i, sj[c] = j, salt[c] = static_cast<unsigned long>(first + c);
      if (++i == k) i = 0, ++j;
    }
    for (int c = count; c < padded; ++c) si[c] = si[count - 1], sj[c] = sj[count - 1], salt[c] = salt[count - 1];
    if (level == 2) {
      lens_avx512::points(x, y, si, sj, salt, padded, k, radius, px, py);
    } else if (level == 1) {
      lens_avx2::points(x, y, si, sj, salt, padded, k, radius, px, py);
    } else {
      lens_sse2::points(x, y, si, sj, salt, padded, k, radius, px, py);
    }
    for (int c = 0; c < count; ++c) out[first + c] = glm::dvec2(px[c], py[c]);
  }
#else
  for (int sample = 0; sample < n; ++sample) out[sample] = lens_disk_point(x, y, sample % k, sample / k, k, radius);
#endif
}

}  // namespace raindrop

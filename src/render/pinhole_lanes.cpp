#include "raindrop/render/pinhole_lanes.h"

#include <algorithm>
#include <atomic>
#include <cstring>
#include <limits>

#include <glm/geometric.hpp>

// The kernel's vectors, per-function targets and builtins are GCC's on x86-64 (Clang ignores
// `#pragma GCC target`); other builds keep the tracer's own path (available() is false).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define RAINDROP_PINHOLE_LANES 1
#include <immintrin.h>
#else
#define RAINDROP_PINHOLE_LANES 0
#endif

namespace raindrop {
namespace {

#if RAINDROP_PINHOLE_LANES

// The kernel once per register width, each compiled for its own instruction set. Its
// vectors never cross a function boundary (every helper is inlined), so the
// warning that passing them by value would change the ABI does not apply (GCC gives it at
// the end of the file: off for all of it).
#pragma GCC diagnostic ignored "-Wpsabi"
#pragma GCC push_options
#define LANES_NS lanes_sse2
#define LANES_LEVEL 0
#include "pinhole_lanes_kernel.inc"
#undef LANES_NS
#undef LANES_LEVEL
#pragma GCC pop_options

#pragma GCC push_options
#pragma GCC target("avx2")
#define LANES_NS lanes_avx2
#define LANES_LEVEL 1
#include "pinhole_lanes_kernel.inc"
#undef LANES_NS
#undef LANES_LEVEL
#pragma GCC pop_options

#pragma GCC push_options
#pragma GCC target("avx512f")
#define LANES_NS lanes_avx512
#define LANES_LEVEL 2
#include "pinhole_lanes_kernel.inc"
#undef LANES_NS
#undef LANES_LEVEL
#pragma GCC pop_options

// The kernel function `f` of register width `level` (PinholeLanes::level).
#define LANES_AT(level, f) ((level) == 2 ? lanes_avx512::f : (level) == 1 ? lanes_avx2::f : lanes_sse2::f)

#endif  // RAINDROP_PINHOLE_LANES

std::atomic<int> forced_level{-1};

int widest_level() {
#if RAINDROP_PINHOLE_LANES
  static const int level = __builtin_cpu_supports("avx512f") ? 2 : __builtin_cpu_supports("avx2") ? 1 : 0;
  return level;
#else
  return 0;
#endif
}

}  // namespace

int PinholeLanes::level() {
  const int forced = forced_level.load(std::memory_order_relaxed);
  return forced >= 0 ? std::min(forced, widest_level()) : widest_level();
}

void PinholeLanes::force_level(int level) { forced_level.store(level, std::memory_order_relaxed); }

bool PinholeLanes::available() { return RAINDROP_PINHOLE_LANES != 0; }

bool PinholeLanes::applies(const DropAccel& accel) {
  if (!available() || !accel.disjoint() || accel.options().kind != GeometryOptions::Kind::Exact) return false;
  for (const Drop& d : accel.drops())
    if (!d.shape().outline.circular()) return false;
  return true;
}

PinholeLanes::PinholeLanes(const Camera& camera, const DropAccel& accel, const GlassPlane& glass,
                           double background_z, double n_water, TirMode tir, bool fresnel)
    : accel_(accel) {
  // Every constant computed here as the scalar code computes it (same expressions, glm's).
  const glm::dvec3 point = glass.origin(), normal = glass.normal();
  scene_.cx = camera.cx, scene_.cy = camera.cy, scene_.fx = camera.fx, scene_.fy = camera.fy;
  for (int i = 0; i < 3; ++i) scene_.gp[i] = point[i], scene_.gn[i] = normal[i];
  scene_.top = accel.slab_top();
  scene_.h0 = glm::dot(glm::dvec3(0.0) - point, normal);
  scene_.eta_in = 1.0 / n_water;
  scene_.eta_out = n_water;
  scene_.tir_black = tir == TirMode::Black;
  scene_.fresnel = fresnel;
  scene_.background_z = background_z;
  drops_.reserve(accel.drops().size());
  for (const Drop& drop : accel.drops()) {
    const Drop::Frame f = drop.frame();
    lanes_detail::DropConstants k{};
    for (int i = 0; i < 3; ++i) k.c[i] = f.c[i], k.u[i] = f.u[i], k.v[i] = f.v[i], k.n[i] = f.n[i];
    k.radius = f.radius, k.centre_height = f.centre_height, k.inv_e = f.inv_elongation, k.inv_f = f.inv_flattening;
    const double a = drop.shape().footprint_radius;
    k.rim2 = a * a;
    // Drop::to_local(camera centre), and the sphere's constant term for that origin.
    const glm::dvec3 rel = glm::dvec3(0.0) - f.c;
    const glm::dvec3 o{glm::dot(rel, f.u), glm::dot(rel, f.v) * f.inv_elongation, glm::dot(rel, f.n) * f.inv_flattening};
    const glm::dvec3 oc{o.x, o.y, o.z - f.centre_height};
    for (int i = 0; i < 3; ++i) k.o[i] = o[i];
    k.oc_z = oc.z;
    k.c_sq = glm::dot(oc, oc) - f.radius * f.radius;
    const glm::dvec3 hn = drop.base_normal();
    for (int i = 0; i < 3; ++i) k.hn[i] = hn[i];
    drops_.push_back(k);
  }
}

DropPath PinholeLanes::Row::path(int x) const {
  DropPath p;
  p.hit = true;
  p.first_drop = drop[x];
  p.dark = dark(x);
  p.escaped_in = escaped_in(x);
  p.events = state[x] == kTrapped ? 1 : 2;
  p.transmittance = transmittance[x];
  if (!p.dark) {
    p.origin = glm::dvec3(ox[x], oy[x], oz[x]);
    p.dir = glm::dvec3(dx[x], dy[x], dz[x]);
  }
  return p;
}

namespace {

// The scratch grows to the widest row (or the most rays) it is given.
void grow(PinholeLanes::Row* row, int x_end) {
  if (row->outcome.size() >= static_cast<size_t>(x_end)) return;
  const size_t n = static_cast<size_t>(x_end);
  for (auto* v : {&row->ox, &row->oy, &row->oz, &row->dx, &row->dy, &row->dz, &row->seen_x, &row->seen_y, &row->t,
                  &row->range, &row->transmittance})
    v->resize(n);
  row->outcome.resize(n);
  row->drop.resize(n);
  row->state.resize(n);
  row->base.resize(n);
}

}  // namespace

// Whether the ray traced to i in the lanes left the common path: a cap met from outside, off
// the common path on the way, or out of the drop within the slab with another drop in reach.
bool PinholeLanes::alone(const Row& r, int i) const {
  const std::uint8_t state = r.state[i];
  return !r.base[i] || state == kAlone ||
         ((state & ~kEscaped) == kOutSlab &&
          accel_.may_meet_after_exit(r.drop[i], glm::dvec3(r.ox[i], r.oy[i], r.oz[i]),
                                     glm::dvec3(r.dx[i], r.dy[i], r.dz[i]), r.range[i]));
}

int PinholeLanes::trace_rays(const lanes_detail::RayArrays& rays, int n, const std::vector<int>& drops,
                             Row* row) const {
  grow(row, n);
  Row& r = *row;
  std::fill(r.t.begin(), r.t.begin() + n, std::numeric_limits<double>::infinity());
  std::fill(r.drop.begin(), r.drop.begin() + n, -1);
  CV_Assert(available());
  const int level = PinholeLanes::level();
#if RAINDROP_PINHOLE_LANES
  const auto first_hits = LANES_AT(level, ray_first_hits);
  const auto common_paths = LANES_AT(level, ray_common_paths);
#else
  const auto first_hits = [](auto&&...) {};
  const auto common_paths = [](auto&&...) {};
  (void)level;
#endif
  for (int drop : drops)
    first_hits(scene_, drops_[static_cast<size_t>(drop)], drop, rays, n, r.t.data(), r.drop.data(), r.base.data());
  int traced = 0;
  for (int drop : drops) {
    common_paths(scene_, drops_[static_cast<size_t>(drop)], drop, rays, n, r.t.data(), r.drop.data(), r.base.data(),
                 r.state.data(), r.ox.data(), r.oy.data(), r.oz.data(), r.dx.data(), r.dy.data(), r.dz.data(),
                 r.range.data(), r.seen_x.data(), r.seen_y.data(), r.transmittance.data());
  }
  for (int i = 0; i < n; ++i) {
    if (r.drop[i] < 0) {
      r.outcome[i] = Outcome::Miss;
      continue;
    }
    const bool by_itself = alone(r, i);
    r.outcome[i] = by_itself ? Outcome::Alone : Outcome::Path;
    traced += !by_itself;
  }
  return traced;
}

int PinholeLanes::trace_row(int y, const std::vector<DropSpan>& spans, Row* row) const {
  int x_end = 0;
  for (const DropSpan& s : spans) x_end = std::max(x_end, s.last + 1);
  grow(row, x_end);
  for (const DropSpan& s : spans) {
    std::fill(row->t.begin() + s.first, row->t.begin() + s.last + 1, std::numeric_limits<double>::infinity());
    std::fill(row->drop.begin() + s.first, row->drop.begin() + s.last + 1, -1);
  }
  CV_Assert(available());
  const int level = PinholeLanes::level();
  const double ry = (static_cast<double>(y) - scene_.cy) / scene_.fy;  // Camera::ray_direction's
  Row& r = *row;
#if RAINDROP_PINHOLE_LANES
  const auto first_hits = LANES_AT(level, first_hits);
  const auto common_paths = LANES_AT(level, common_paths);
#else
  const auto first_hits = [](auto&&...) {};
  const auto common_paths = [](auto&&...) {};
  (void)level;
#endif
  for (const DropSpan& s : spans) {
    first_hits(scene_, drops_[static_cast<size_t>(s.drop)], s.drop, ry, s.first, s.last, r.t.data(), r.drop.data(),
               r.base.data());
  }
  int traced = 0;
  for (const DropSpan& s : spans) {
    common_paths(scene_, drops_[static_cast<size_t>(s.drop)], s.drop, ry, s.first, s.last, r.t.data(), r.drop.data(),
                 r.base.data(), r.state.data(), r.ox.data(), r.oy.data(), r.oz.data(), r.dx.data(), r.dy.data(),
                 r.dz.data(), r.range.data(), r.seen_x.data(), r.seen_y.data(), r.transmittance.data());
    // The outcome of every pixel of the span whose nearest hit is this drop (a pixel without
    // any hit: Miss, each time a span covers it).
    for (int x = s.first; x <= s.last; ++x) {
      const int drop = r.drop[x];
      if (drop < 0) {
        r.outcome[x] = Outcome::Miss;
        continue;
      }
      if (drop != s.drop) continue;
      const bool by_itself = alone(r, x);
      r.outcome[x] = by_itself ? Outcome::Alone : Outcome::Path;
      traced += !by_itself;
    }
  }
  return traced;
}

}  // namespace raindrop

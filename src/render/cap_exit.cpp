#include "raindrop/render/cap_exit.h"

#include <emmintrin.h>

#include <algorithm>

namespace raindrop {
namespace {

// Two doubles in one SSE2 register (GCC/Clang vector extension): +, -, *, / are the
// packed instructions, each lane rounded as the scalar operation would be.
typedef double d2 __attribute__((vector_size(16)));
typedef long long m2 __attribute__((vector_size(16)));  // lane masks: all ones or zero

inline d2 splat(double v) { return d2{v, v}; }
inline d2 sqrt2(d2 v) { return reinterpret_cast<d2>(_mm_sqrt_pd(reinterpret_cast<__m128d>(v))); }
inline d2 select(m2 mask, d2 yes, d2 no) {
  return reinterpret_cast<d2>((reinterpret_cast<m2>(yes) & mask) | (reinterpret_cast<m2>(no) & ~mask));
}
// std::copysign: the magnitude of `mag`, the sign bit of `sign`.
inline d2 copysign2(d2 mag, d2 sign) {
  const m2 bit = m2{static_cast<long long>(0x8000000000000000ULL), static_cast<long long>(0x8000000000000000ULL)};
  return reinterpret_cast<d2>((reinterpret_cast<m2>(mag) & ~bit) | (reinterpret_cast<m2>(sign) & bit));
}

// Three coordinates of two lanes.
struct V2 {
  d2 x, y, z;
};
inline d2 dot(const V2& a, const V2& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }  // glm's order

constexpr int kLanes = 8;

}  // namespace

void exit_through_caps(const Drop* const* drops, const glm::dvec3* origins, const glm::dvec3* dirs,
                       const double* t_max, int n, CapExit* out) {
  // Structure of arrays, lanes past n repeating the last ray (their answers are dropped).
  alignas(16) double ox[kLanes], oy[kLanes], oz[kLanes], dx[kLanes], dy[kLanes], dz[kLanes], tmax[kLanes];
  alignas(16) double cx[kLanes], cy[kLanes], cz[kLanes], ux[kLanes], uy[kLanes], uz[kLanes];
  alignas(16) double vx[kLanes], vy[kLanes], vz[kLanes], nx[kLanes], ny[kLanes], nz[kLanes];
  alignas(16) double radius[kLanes], centre[kLanes], inv_e[kLanes], inv_f[kLanes];
  for (int i = 0; i < kLanes; ++i) {
    const int k = std::min(i, n - 1);
    const Drop::Frame f = drops[k]->frame();
    ox[i] = origins[k].x, oy[i] = origins[k].y, oz[i] = origins[k].z;
    dx[i] = dirs[k].x, dy[i] = dirs[k].y, dz[i] = dirs[k].z;
    tmax[i] = t_max[k];
    cx[i] = f.c.x, cy[i] = f.c.y, cz[i] = f.c.z;
    ux[i] = f.u.x, uy[i] = f.u.y, uz[i] = f.u.z;
    vx[i] = f.v.x, vy[i] = f.v.y, vz[i] = f.v.z;
    nx[i] = f.n.x, ny[i] = f.n.y, nz[i] = f.n.z;
    radius[i] = f.radius, centre[i] = f.centre_height, inv_e[i] = f.inv_elongation, inv_f[i] = f.inv_flattening;
  }
  auto load = [](const double* a, int k) { return *reinterpret_cast<const d2*>(a + k); };
  const d2 zero = splat(0.0);
  for (int k = 0; k < n; k += 2) {
    const V2 origin{load(ox, k), load(oy, k), load(oz, k)};
    const V2 dir{load(dx, k), load(dy, k), load(dz, k)};
    const V2 c{load(cx, k), load(cy, k), load(cz, k)};
    const V2 u{load(ux, k), load(uy, k), load(uz, k)};
    const V2 v{load(vx, k), load(vy, k), load(vz, k)};
    const V2 nn{load(nx, k), load(ny, k), load(nz, k)};
    const d2 R = load(radius, k), zc = load(centre, k), ie = load(inv_e, k), iff = load(inv_f, k);
    const d2 tm = load(tmax, k);
    // Drop::to_local and dir_to_local: the scaled local frame, where the cap is spherical.
    auto to_local = [&](const V2& p) { return V2{dot(p, u), dot(p, v) * ie, dot(p, nn) * iff}; };
    const V2 o = to_local(V2{origin.x - c.x, origin.y - c.y, origin.z - c.z});
    const V2 d = to_local(dir);
    // The sphere's roots (the base is where the ray starts: not asked).
    const V2 oc{o.x, o.y, o.z - zc};
    const d2 a = dot(d, d);
    const d2 b = dot(oc, d);
    const d2 cc = dot(oc, oc) - R * R;
    const d2 disc = b * b - a * cc;
    const m2 solvable = (a > zero) & (disc >= zero);
    const d2 sq = sqrt2(select(solvable, disc, zero));
    const d2 q = -(b + copysign2(sq, b));
    const d2 r0 = q / a;
    const m2 q_nonzero = q != zero;
    const d2 r1 = select(q_nonzero, cc / select(q_nonzero, q, splat(1.0)), zero);
    // Drop::intersect's `consider`, root 0 then root 1: on the cap (z >= 0), in (0, t_max),
    // nearer than the best so far.
    const m2 ok0 = solvable & (o.z + r0 * d.z >= zero) & (r0 > zero) & (r0 < tm);
    const m2 ok1 = solvable & (o.z + r1 * d.z >= zero) & (r1 > zero) & (r1 < tm) & (~ok0 | (r1 < r0));
    const m2 hit = ok0 | ok1;
    const d2 t = select(ok1, r1, r0);
    // Drop::cap_normal at origin + t * dir.
    const V2 p{origin.x + t * dir.x, origin.y + t * dir.y, origin.z + t * dir.z};
    const V2 l = to_local(V2{p.x - c.x, p.y - c.y, p.z - c.z});
    const V2 m{l.x, l.y, l.z - zc};
    const d2 my = m.y * ie, mz = m.z * iff;
    const V2 world{m.x * u.x + my * v.x + mz * nn.x, m.x * u.y + my * v.y + mz * nn.y, m.x * u.z + my * v.z + mz * nn.z};
    const d2 len = sqrt2(dot(world, world));
    const m2 positive = len > zero;
    const d2 safe = select(positive, len, splat(1.0));
    const V2 normal{select(positive, world.x / safe, nn.x), select(positive, world.y / safe, nn.y),
                    select(positive, world.z / safe, nn.z)};
    for (int j = 0; j < 2 && k + j < n; ++j) {
      CapExit& e = out[k + j];
      e.hit = hit[j] != 0;
      e.t = t[j];
      e.normal = glm::dvec3(normal.x[j], normal.y[j], normal.z[j]);
    }
  }
}

}  // namespace raindrop

#include "raindrop/render/drop_accel.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include <embree3/rtcore.h>
#include <glm/geometric.hpp>
#include <glm/vector_relational.hpp>

#include "raindrop/common/error.h"

namespace raindrop {
namespace {

// One Embree device for the process: creating one costs milliseconds, queries on committed
// scenes are thread-safe.
RTCDevice shared_device() {
  static RTCDevice device = [] {
    RTCDevice d = rtcNewDevice("verbose=0");
    if (!d) throw Error("could not create an Embree device");
    return d;
  }();
  return device;
}

// Intersect context extended with the double-precision rays (Embree's are float) and the
// surface a ray starts on, as in Embree's tutorials on extended contexts. A single-ray query
// uses lane 0; a packet query (intersect8) one lane per ray, found by the ray's id.
constexpr int kPacket = 8;
struct ExactContext {
  RTCIntersectContext base;
  const std::vector<Drop>* drops;
  glm::dvec3 origin[kPacket], dir[kPacket];
  double t_min[kPacket];  // the query's lower bound in double (Embree's is a float)
  const DropHit* from;    // single-ray queries only
  // Per lane, the nearest hit so far (t infinite: none). Kept in double: Embree's float tfar
  // cannot tell apart two drops met within a float's rounding (merged drops, where caps
  // cross), and the answer must not depend on the order Embree visits them in, which differs
  // between single rays and packets.
  DropHit best[kPacket];
  void reset(int lanes) {
    for (int i = 0; i < lanes; ++i) best[i].t = std::numeric_limits<double>::infinity();
  }
};

void exact_bounds(const RTCBoundsFunctionArguments* args) {
  const auto* drops = static_cast<const std::vector<Drop>*>(args->geometryUserPtr);
  glm::dvec3 lo, hi;
  (*drops)[args->primID].bounds(&lo, &hi);
  // Pad by a relative epsilon so that float rounding never clips the true cap.
  const glm::dvec3 pad = 1e-5 * (glm::abs(lo) + glm::abs(hi)) + 1e-6;
  lo -= pad;
  hi += pad;
  args->bounds_o->lower_x = static_cast<float>(lo.x);
  args->bounds_o->lower_y = static_cast<float>(lo.y);
  args->bounds_o->lower_z = static_cast<float>(lo.z);
  args->bounds_o->upper_x = static_cast<float>(hi.x);
  args->bounds_o->upper_y = static_cast<float>(hi.y);
  args->bounds_o->upper_z = static_cast<float>(hi.z);
}

void exact_intersect(const RTCIntersectFunctionNArguments* args) {
  auto* ctx = reinterpret_cast<ExactContext*>(args->context);
  RTCRayHitN* rayhit = args->rayhit;
  RTCRayN* ray = RTCRayHitN_RayN(rayhit, args->N);
  RTCHitN* hit_n = RTCRayHitN_HitN(rayhit, args->N);
  const unsigned prim = args->primID;
  for (unsigned i = 0; i < args->N; ++i) {
    if (!args->valid[i]) continue;
    const unsigned lane = RTCRayN_id(ray, args->N, i);
    std::optional<DropSurface> start;
    if (ctx->from && ctx->from->drop == static_cast<int>(prim)) start = ctx->from->surface;
    float& tfar = RTCRayN_tfar(ray, args->N, i);
    DropHit& best = ctx->best[lane];
    // Up to and including the best so far: an exact tie goes to the lower drop index.
    const double t_max = std::min(static_cast<double>(tfar), std::nextafter(best.t, INFINITY));
    const auto hit = (*ctx->drops)[prim].intersect(ctx->origin[lane], ctx->dir[lane], ctx->t_min[lane], t_max, start);
    if (!hit || hit->t > best.t || (hit->t == best.t && static_cast<int>(prim) > best.drop)) continue;
    // tfar rounded up, so that Embree never culls a box that may hold a nearer hit.
    float t_float = static_cast<float>(hit->t);
    if (static_cast<double>(t_float) < hit->t) t_float = std::nextafter(t_float, INFINITY);
    tfar = t_float;
    RTCHitN_Ng_x(hit_n, args->N, i) = static_cast<float>(hit->normal.x);
    RTCHitN_Ng_y(hit_n, args->N, i) = static_cast<float>(hit->normal.y);
    RTCHitN_Ng_z(hit_n, args->N, i) = static_cast<float>(hit->normal.z);
    RTCHitN_u(hit_n, args->N, i) = RTCHitN_v(hit_n, args->N, i) = 0.f;
    RTCHitN_primID(hit_n, args->N, i) = prim;
    RTCHitN_geomID(hit_n, args->N, i) = args->geomID;
    RTCHitN_instID(hit_n, args->N, i, 0) = RTC_INVALID_GEOMETRY_ID;
    best = DropHit{hit->t, static_cast<int>(prim), hit->surface, hit->normal};
  }
}

// The boxes' indices sorted by their lower x: the sweeps below stop scanning where the x-gap
// alone rules a box out.
std::vector<size_t> by_lower_x(const std::vector<glm::dvec3>& lo) {
  std::vector<size_t> order(lo.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return lo[a].x < lo[b].x; });
  return order;
}

// Per drop, the `k` drops whose bounding boxes are nearest to its own, nearest first, and
// the distance of the next one (infinite when there is none). Boxes sorted by their lower x:
// once a box's x-gap alone exceeds the k-th best distance found so far, no box further in that
// direction can enter the list, so typical scenes cost far less than all pairs.
template <int k, class Neighbours>
void nearest_boxes(const std::vector<glm::dvec3>& lo, const std::vector<glm::dvec3>& hi, std::vector<Neighbours>* out) {
  const size_t n = lo.size();
  const std::vector<size_t> order = by_lower_x(lo);
  double widest = 0;
  for (size_t i = 0; i < n; ++i) widest = std::max(widest, hi[i].x - lo[i].x);
  auto distance = [&](size_t a, size_t b) {
    return glm::length(glm::max(glm::dvec3(0.0), glm::max(lo[a] - hi[b], lo[b] - hi[a])));
  };
  out->assign(n, Neighbours{});
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (size_t s = 0; s < n; ++s) {
    const size_t a = order[s];
    // The k + 1 best so far, sorted: the list, then the first one left out.
    int best_drop[k + 1];
    double best[k + 1];
    int count = 0;
    auto bound = [&] { return count == k + 1 ? best[k] : kInf; };
    auto offer = [&](size_t b) {
      const double dist = distance(a, b);
      if (dist >= bound()) return;
      int i = count < k + 1 ? count++ : k;
      for (; i > 0 && best[i - 1] > dist; --i) best[i] = best[i - 1], best_drop[i] = best_drop[i - 1];
      best[i] = dist;
      best_drop[i] = static_cast<int>(b);
    };
    // Boxes further right start at or after lo[b].x: their x-gap is at least lo[b].x - hi[a].x.
    for (size_t m = s + 1; m < n && !(lo[order[m]].x - hi[a].x > bound()); ++m) offer(order[m]);
    // Boxes further left end before lo[b].x + widest: their x-gap is at least lo[a].x - lo[b].x - widest.
    for (size_t m = s; m-- > 0 && !(lo[a].x - lo[order[m]].x - widest > bound());) offer(order[m]);
    Neighbours& nb = (*out)[a];
    nb.count = std::min(count, k);
    for (int i = 0; i < nb.count; ++i) nb.drop[i] = best_drop[i], nb.distance[i] = best[i];
    nb.beyond = count == k + 1 ? best[k] : kInf;
  }
}

// Per box, the other boxes it meets (sorted by lower x, each scan stops at the first box
// that starts beyond its upper x).
std::vector<std::vector<int>> overlapping_boxes(const std::vector<glm::dvec3>& lo, const std::vector<glm::dvec3>& hi) {
  const size_t n = lo.size();
  const std::vector<size_t> order = by_lower_x(lo);
  std::vector<std::vector<int>> out(n);
  for (size_t s = 0; s < n; ++s) {
    const size_t a = order[s];
    for (size_t m = s + 1; m < n && lo[order[m]].x <= hi[a].x; ++m) {
      const size_t b = order[m];
      if (glm::all(glm::lessThanEqual(lo[a], hi[b])) && glm::all(glm::lessThanEqual(lo[b], hi[a]))) {
        out[a].push_back(static_cast<int>(b));
        out[b].push_back(static_cast<int>(a));
      }
    }
  }
  return out;
}

// Whether origin + t * dir, t in [0, t_max], meets the box [lo, hi] (slab test in double).
bool segment_meets_box(const glm::dvec3& origin, const glm::dvec3& dir, double t_max, const glm::dvec3& lo,
                       const glm::dvec3& hi) {
  double t0 = 0, t1 = t_max;
  for (int c = 0; c < 3; ++c) {
    if (dir[c] == 0.0) {
      if (origin[c] < lo[c] || origin[c] > hi[c]) return false;
      continue;
    }
    const double inv = 1.0 / dir[c];
    double ta = (lo[c] - origin[c]) * inv, tb = (hi[c] - origin[c]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (!(t0 <= t1)) return false;
  }
  return true;
}

// Float bounds widened by a relative 1e-6 (about 8 float ulps) so the float traversal never
// clips the double-precision query.
float float_tfar(double t_max) {
  return std::isfinite(t_max) ? static_cast<float>(t_max * (1 + 1e-6) + 1e-6) : std::numeric_limits<float>::infinity();
}
float float_tnear(double t_min) { return static_cast<float>(std::max(0.0, t_min * (1 - 1e-6) - 1e-6)); }

}  // namespace

std::string GeometryOptions::describe() const {
  if (kind == Kind::Exact) return "exact";
  return "mesh-" + std::to_string(segments) + (smooth_normals ? "-smooth" : "-flat");
}

GeometryOptions GeometryOptions::parse(const std::string& text) {
  GeometryOptions o;
  if (text == "exact") return o;
  o.kind = Kind::Mesh;
  int segments = 0;
  char normals[16] = {0};
  if (std::sscanf(text.c_str(), "mesh-%d-%15s", &segments, normals) == 2 && segments >= 4 &&
      segments <= kMaxMeshSegments && (std::string(normals) == "smooth" || std::string(normals) == "flat")) {
    o.segments = segments;
    o.smooth_normals = std::string(normals) == "smooth";
    return o;
  }
  throw Error("geometry '" + text + "' is not 'exact' or 'mesh-<segments>-smooth|flat' (segments 4.." +
              std::to_string(kMaxMeshSegments) + ")");
}

struct DropAccel::Impl {
  RTCScene scene = nullptr;
  // Mesh only: per triangle, its drop and surface; per vertex, the true surface normal.
  std::vector<int> tri_drop;
  std::vector<DropSurface> tri_surface;
  std::vector<glm::vec3> vertex_normal;
  std::vector<unsigned> indices;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
  }
};

DropAccel::DropAccel(const std::vector<Drop>& drops, const GeometryOptions& options)
    : drops_(drops), options_(options), impl_(std::make_unique<Impl>()) {
  for (const Drop& d : drops_) max_height_ = std::max(max_height_, d.shape().height());
  // Boxes padded far beyond the rounding of the slab test, so that a skipped query never
  // had a hit to find.
  box_lo_.resize(drops_.size());
  box_hi_.resize(drops_.size());
  for (size_t i = 0; i < drops_.size(); ++i) {
    drops_[i].bounds(&box_lo_[i], &box_hi_[i]);
    const glm::dvec3 pad = 1e-6 * (glm::abs(box_lo_[i]) + glm::abs(box_hi_[i])) + 1e-9;
    box_lo_[i] -= pad;
    box_hi_[i] += pad;
  }
  if (options.kind == GeometryOptions::Kind::Exact) nearest_boxes<kExitNeighbours>(box_lo_, box_hi_, &exit_neighbours_);
  box_overlaps_ = overlapping_boxes(box_lo_, box_hi_);
  RTCDevice device = shared_device();
  impl_->scene = rtcNewScene(device);
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
  if (options.kind == GeometryOptions::Kind::Exact) {
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(geom, static_cast<unsigned>(drops_.size()));
    rtcSetGeometryUserData(geom, &drops_);
    rtcSetGeometryBoundsFunction(geom, exact_bounds, &drops_);
    rtcSetGeometryIntersectFunction(geom, exact_intersect);
    rtcCommitGeometry(geom);
    rtcAttachGeometry(impl_->scene, geom);
    rtcReleaseGeometry(geom);
  } else {
    const int segs = options.segments;
    const int rings = std::max(2, segs / 4);
    std::vector<glm::vec3> verts;
    auto& idx = impl_->indices;
    for (int d = 0; d < static_cast<int>(drops_.size()); ++d) {
      const Drop& drop = drops_[d];
      const double tau = drop.shape().contact_angle;
      // Cap: apex vertex, then `rings` rings down to the rim (the last ring is the rim).
      const unsigned apex = static_cast<unsigned>(verts.size());
      verts.push_back(glm::vec3(drop.cap_point(0, 0)));
      impl_->vertex_normal.push_back(glm::vec3(drop.cap_normal(drop.cap_point(0, 0))));
      for (int r = 1; r <= rings; ++r) {
        for (int s = 0; s < segs; ++s) {
          const glm::dvec3 p = drop.cap_point(tau * r / rings, 2 * M_PI * s / segs);
          verts.push_back(glm::vec3(p));
          impl_->vertex_normal.push_back(glm::vec3(drop.cap_normal(p)));
        }
      }
      auto ring_vertex = [&](int r, int s) { return apex + 1 + (r - 1) * segs + (s % segs); };
      auto add = [&](unsigned a, unsigned b, unsigned c, DropSurface surface) {
        idx.insert(idx.end(), {a, b, c});
        impl_->tri_drop.push_back(d);
        impl_->tri_surface.push_back(surface);
      };
      for (int s = 0; s < segs; ++s) add(apex, ring_vertex(1, s), ring_vertex(1, s + 1), DropSurface::Cap);
      for (int r = 1; r < rings; ++r) {
        for (int s = 0; s < segs; ++s) {
          add(ring_vertex(r, s), ring_vertex(r + 1, s), ring_vertex(r + 1, s + 1), DropSurface::Cap);
          add(ring_vertex(r, s), ring_vertex(r + 1, s + 1), ring_vertex(r, s + 1), DropSurface::Cap);
        }
      }
      // Base: fan from the footprint centre over its own copy of the rim ring. The copy
      // carries the flat base's normal; sharing the cap's rim vertices would blend the cap's
      // rim normals into the base under smooth shading.
      const unsigned centre = static_cast<unsigned>(verts.size());
      // (An irregular outline is star-shaped about the centre, so the fan covers it.)
      verts.push_back(glm::vec3(drop.shape().outline.circular() ? 0.5 * (drop.cap_point(tau, 0) + drop.cap_point(tau, M_PI))
                                                                : drop.centre()));
      impl_->vertex_normal.push_back(glm::vec3(drop.base_normal()));
      for (int s = 0; s < segs; ++s) {
        verts.push_back(verts[ring_vertex(rings, s)]);
        impl_->vertex_normal.push_back(glm::vec3(drop.base_normal()));
      }
      for (int s = 0; s < segs; ++s) add(centre, centre + 1 + (s + 1) % segs, centre + 1 + s, DropSurface::Base);
    }
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0,
                                                           RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                           verts.size()));
    for (size_t i = 0; i < verts.size(); ++i) {
      vb[3 * i] = verts[i].x;
      vb[3 * i + 1] = verts[i].y;
      vb[3 * i + 2] = verts[i].z;
    }
    auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0,
                                                              RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                                              idx.size() / 3));
    std::copy(idx.begin(), idx.end(), ib);
    rtcCommitGeometry(geom);
    rtcAttachGeometry(impl_->scene, geom);
    rtcReleaseGeometry(geom);
  }
  rtcCommitScene(impl_->scene);
  if (rtcGetDeviceError(device) != RTC_ERROR_NONE) throw Error("Embree failed to build the drop scene");
}

DropAccel::~DropAccel() = default;

void DropAccel::intersect_packet(const glm::dvec3* origins, const glm::dvec3* dirs, const double* t_min,
                                 const double* t_max, int n, std::optional<DropHit>* hits) const {
  if (options_.kind != GeometryOptions::Kind::Exact || n <= 1) {
    for (int i = 0; i < n; ++i) hits[i] = intersect(origins[i], dirs[i], nullptr, t_min[i], t_max[i]);
    return;
  }
  alignas(32) int valid[kPacket];
  alignas(32) RTCRayHit8 rh;
  ExactContext ctx;
  rtcInitIntersectContext(&ctx.base);
  ctx.drops = &drops_;
  ctx.reset(kPacket);
  ctx.from = nullptr;
  for (int i = 0; i < kPacket; ++i) {
    valid[i] = i < n ? -1 : 0;
    const int k = std::min(i, n - 1);  // lanes past n repeat the last ray, masked out
    ctx.origin[i] = origins[k];
    ctx.dir[i] = dirs[k];
    ctx.t_min[i] = t_min[k];
    rh.ray.org_x[i] = static_cast<float>(origins[k].x);
    rh.ray.org_y[i] = static_cast<float>(origins[k].y);
    rh.ray.org_z[i] = static_cast<float>(origins[k].z);
    rh.ray.dir_x[i] = static_cast<float>(dirs[k].x);
    rh.ray.dir_y[i] = static_cast<float>(dirs[k].y);
    rh.ray.dir_z[i] = static_cast<float>(dirs[k].z);
    rh.ray.tnear[i] = std::max(float_tnear(t_min[k]), 0.f);
    rh.ray.tfar[i] = float_tfar(t_max[k]);
    rh.ray.time[i] = 0.f;
    rh.ray.mask[i] = 0xFFFFFFFFu;
    rh.ray.id[i] = static_cast<unsigned>(i);
    rh.ray.flags[i] = 0;
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  rtcIntersect8(valid, impl_->scene, &ctx.base, &rh);
  for (int i = 0; i < n; ++i) {
    if (rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) {
      hits[i] = std::nullopt;
    } else {
      hits[i] = ctx.best[i];
    }
  }
}

bool DropAccel::in_other_water(const glm::dvec3& p, int drop) const {
  for (int other : box_overlaps_[drop])
    if (drops_[other].contains(p)) return true;
  return false;
}

bool DropAccel::may_meet_after_exit(int drop, const glm::dvec3& origin, const glm::dvec3& dir, double t_max) const {
  if (!exit_skip_ || exit_neighbours_.empty() || !drops_[drop].shape().outline.circular()) return true;
  const ExitNeighbours& nb = exit_neighbours_[drop];
  // Every point of the segment lies within its length of the origin, which is inside this
  // drop's box: a box further than that from this drop's box is out of reach.
  const double reach = t_max * glm::length(dir) * (1 + 1e-6);
  if (!(reach < nb.beyond)) return true;
  for (int i = 0; i < nb.count && nb.distance[i] <= reach; ++i) {
    const int other = nb.drop[i];
    if (segment_meets_box(origin, dir, t_max * (1 + 1e-6), box_lo_[other], box_hi_[other])) return true;
  }
  return false;
}

std::optional<DropHit> DropAccel::intersect_inside(const glm::dvec3& origin, const glm::dvec3& dir,
                                                   const DropHit& from, double t_max) const {
  if (!disjoint_ || options_.kind != GeometryOptions::Kind::Exact) return intersect(origin, dir, &from, 0.0, t_max);
  const auto hit = drops_[from.drop].intersect(origin, dir, 0.0, t_max, from.surface);
  if (!hit) return std::nullopt;
  return DropHit{hit->t, from.drop, hit->surface, hit->normal};
}

std::optional<DropHit> DropAccel::intersect(const glm::dvec3& origin, const glm::dvec3& dir,
                                            const DropHit* from, double t_min, double t_max) const {
  RTCRayHit rh;
  rh.ray.org_x = static_cast<float>(origin.x);
  rh.ray.org_y = static_cast<float>(origin.y);
  rh.ray.org_z = static_cast<float>(origin.z);
  rh.ray.dir_x = static_cast<float>(dir.x);
  rh.ray.dir_y = static_cast<float>(dir.y);
  rh.ray.dir_z = static_cast<float>(dir.z);
  rh.ray.time = 0.f;
  rh.ray.tfar = float_tfar(t_max);
  const float tnear = float_tnear(t_min);
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;

  if (options_.kind == GeometryOptions::Kind::Exact) {
    ExactContext ctx;
    rtcInitIntersectContext(&ctx.base);
    ctx.drops = &drops_;
    ctx.reset(1);
    ctx.origin[0] = origin;
    ctx.dir[0] = dir;
    ctx.from = from;
    ctx.t_min[0] = t_min;
    rh.ray.tnear = std::max(tnear, 0.f);
    rtcIntersect1(impl_->scene, &ctx.base, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
    return ctx.best[0];
  }

  // Mesh: the starting triangle is avoided with a small offset along the ray, 1e-4 of the
  // direction's length in cm (1 um for a unit direction), far below a drop's size and far
  // above float rounding at these distances.
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  rh.ray.tnear = std::max(std::max(tnear, 0.f), from ? static_cast<float>(1e-4 / glm::length(dir)) : 0.f);
  rtcIntersect1(impl_->scene, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  const unsigned tri = rh.hit.primID;
  DropHit hit;
  hit.t = rh.ray.tfar;
  hit.drop = impl_->tri_drop[tri];
  hit.surface = impl_->tri_surface[tri];
  const float u = rh.hit.u, v = rh.hit.v;
  const unsigned* t = &impl_->indices[3 * tri];
  const glm::dvec3 smooth((1 - u - v) * impl_->vertex_normal[t[0]] +
                          u * impl_->vertex_normal[t[1]] + v * impl_->vertex_normal[t[2]]);
  if (options_.smooth_normals) {
    hit.normal = smooth;
  } else {
    // The facet's own normal, turned to the outside (the side of the true normals) so the
    // result does not depend on the winding convention.
    hit.normal = glm::dvec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
    if (glm::dot(hit.normal, smooth) < 0) hit.normal = -hit.normal;
  }
  const double len = glm::length(hit.normal);
  hit.normal = len > 0 ? hit.normal / len : drops_[hit.drop].base_normal();
  return hit;
}

}  // namespace raindrop

#include "raindrop/render/tracer.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <vector>

#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "raindrop/common/rng.h"
#include "raindrop/render/aperture_reach.h"
#include "raindrop/render/background.h"
#include "raindrop/render/background_range.h"
#include "raindrop/render/cap_exit.h"
#include "raindrop/render/defocus.h"
#include "raindrop/render/lens_disk.h"
#include "raindrop/render/linear_frame.h"
#include "raindrop/render/optics.h"
#include "raindrop/render/pinhole_lanes.h"
#include "raindrop/render/scratch_pool.h"
#include "raindrop/render/sky.h"
#include "raindrop/render/spans.h"
#include "raindrop/render/srgb.h"

namespace raindrop {
namespace {

constexpr int kMaxEvents = 16;  // surface crossings/reflections followed before giving up
// Overlapping drops: how far past a crossing (relative to the distance from the camera, cm)
// the tracer looks to tell whether the ray is in water there. Far above double rounding at
// these distances, far below any drop's size.
constexpr double kHair = 1e-9;

// The glass plane's normal and a point on it, computed once per frame (GlassPlane derives
// them from the tilt with a sine and a cosine each time it is asked).
struct GlassFrame {
  glm::dvec3 normal, point;
  explicit GlassFrame(const GlassPlane& g) : normal(g.normal()), point(g.origin()) {}
};

// All drops lie in the slab between the glass plane and the tallest cap (DropAccel::slab_top):
// each query is limited to the part of the ray inside that slab (padded), so Embree can prune
// early.

// The part [t_min, t_max] of o + t d inside the slab; false when the ray cannot meet it.
bool slab_range(const glm::dvec3& o, const glm::dvec3& d, const GlassFrame& glass, double top, double* t_min,
                double* t_max) {
  const double h0 = glm::dot(o - glass.point, glass.normal), dn = glm::dot(d, glass.normal);
  *t_min = 0;
  *t_max = std::numeric_limits<double>::infinity();
  if (std::abs(dn) > 1e-12) {
    const double t_bottom = -h0 / dn, t_top = (top - h0) / dn;
    const double pad = 1e-6 * (std::abs(t_bottom) + std::abs(t_top)) + 1e-7;
    *t_min = std::max(0.0, std::min(t_bottom, t_top) - pad);
    *t_max = std::max(t_bottom, t_top) + pad;
    return *t_max > *t_min;  // else the slab is behind the ray
  }
  return !(h0 < -1e-9 || h0 > top);  // parallel to the glass: inside the slab or never
}

// `first`, if given: the answer to the first query (DropAccel::intersect_packet asked it
// for several rays at once).
template <bool kFresnel>
DropPath trace_path(const glm::dvec3& origin, const glm::dvec3& dir0, double n_water, TirMode tir,
                    const DropAccel& accel, const GlassFrame& glass, const std::optional<DropHit>* first = nullptr) {
  DropPath path;
  glm::dvec3 o = origin, d = glm::normalize(dir0);
  DropHit current;
  bool on_surface = false, inside = false;
  const glm::dvec3& normal = glass.normal;
  const double top = accel.slab_top();
  // Overlapping drops (merged drops, a trail and its drop) are one body of water: a drop's
  // surface inside another's water is no boundary, and a ray crosses it unbent. Those
  // crossings are not events; they are bounded apart (each moves the ray on).
  const bool merged = !accel.disjoint();
  int crossings = 0;
  for (int event = 0; event < kMaxEvents;) {
    double t_min, t_max;
    if (!slab_range(o, d, glass, top, &t_min, &t_max)) break;
    // Just out of a drop, with no other drop in reach: nothing more to meet, and no query to
    // ask (DropAccel::may_meet_after_exit).
    if (on_surface && !inside && !accel.may_meet_after_exit(current.drop, o, d, t_max)) break;
    std::optional<DropHit> hit;
    if (event == 0 && first) {
      hit = *first;
    } else if (merged && on_surface) {
      // A surface met within a hair of where the ray starts is one it crosses there, at the
      // same point (the bases of overlapping drops all lie on the glass; the caps of a drop
      // placed twice coincide): whether the ray is in water beyond it is settled below, by
      // looking a hair further. Asking again would find those surfaces back and forth.
      hit = accel.intersect(o, d, &current, std::max(t_min, kHair * (1.0 + glm::length(o))), t_max);
    } else {
      hit = inside ? accel.intersect_inside(o, d, current, t_max)
                   : accel.intersect(o, d, on_surface ? &current : nullptr, t_min, t_max);
    }
    if (!hit) break;
    if (!path.hit) {
      path.hit = true;
      path.first_drop = hit->drop;
    }
    const bool entering = glm::dot(d, hit->normal) < 0;
    if (merged) {
      // In water after the crossing: in this drop's (entering it) or in another's.
      const glm::dvec3 p = o + hit->t * d;
      const bool water_after = entering || accel.in_other_water(p + kHair * (1.0 + glm::length(p)) * d, hit->drop);
      if (water_after == inside) {
        o = p;
        current = *hit;
        on_surface = true;
        if (++crossings > 4 * kMaxEvents) break;
        continue;
      }
    }
    ++event;
    ++path.events;
    const glm::dvec3 facing = entering ? hit->normal : -hit->normal;
    const double eta = entering ? 1.0 / n_water : n_water;
    const auto refracted = refract(d, facing, eta);
    if constexpr (kFresnel) {
      path.transmittance *= 1.0 - fresnel_reflectance(-glm::dot(d, facing), eta);
    }
    o = o + hit->t * d;
    current = *hit;
    on_surface = true;
    if (refracted) {
      d = *refracted;
      inside = entering;
    } else if (tir == TirMode::Black) {
      path.dark = true;
      return path;
    } else {
      d = reflect(d, facing);
    }
  }
  if (inside) {
    // Still in the water after kMaxEvents (a ray trapped by repeated total internal
    // reflection): no light comes out of it towards the camera.
    path.dark = true;
    return path;
  }
  // A ray heading back through the glass sees the car interior.
  path.escaped_in = path.hit && glm::dot(d, normal) <= 0;
  path.origin = o;
  path.dir = d;
  return path;
}

}  // namespace

glm::dvec2 background_pixel(const DropPath& p, const Camera& camera, double background_z) {
  // Rays that never reach the background plane (d.z ~ 0 or below, e.g. straight up into the
  // sky) are followed to a point at infinity along a slightly forward-tilted direction; the
  // border mode then decides what is seen there.
  const double dz = std::max(p.dir.z, 1e-6);
  if (p.dir.z > 1e-6 && p.origin.z < background_z) {
    const double t = (background_z - p.origin.z) / p.dir.z;
    return camera.project(p.origin + t * p.dir);
  }
  return {camera.fx * p.dir.x / dz + camera.cx, camera.fy * p.dir.y / dz + camera.cy};
}

DropPath trace_through_drops(const glm::dvec3& origin, const glm::dvec3& dir, double n_water, TirMode tir,
                             bool fresnel, const DropAccel& accel, const GlassPlane& glass) {
  const GlassFrame frame(glass);
  return fresnel ? trace_path<true>(origin, dir, n_water, tir, accel, frame)
                 : trace_path<false>(origin, dir, n_water, tir, accel, frame);
}

namespace {

struct Sample {
  bool hit = false;
  int drop = -1;
  bool dark = false;
  bool off_frame = false;
  glm::dvec3 rgb{0};
  glm::dvec2 xy{NAN, NAN};  // the background point seen (the green path's); NaN: none
  // (set_miss and Kernel::finish_into write these defaults field by field: keep them alike.)
};
// *s = Sample{}, field by field (the aperture paths set millions a frame; the compiler made
// the assignment a string store, slow to start for 56 bytes).
inline void set_miss(Sample* s) {
  s->hit = false;
  s->drop = -1;
  s->dark = false;
  s->off_frame = false;
  s->rgb = glm::dvec3(0.0);
  s->xy = glm::dvec2(NAN, NAN);
}

template <bool kFresnel, bool kDispersion>
class Kernel {
 public:
  // `plan`: with dispersion auto, the drops whose colours are traced apart.
  // `lockstep`: camera rays on the common path traced side by side (trace_through_one_drop;
  // only where drops are disjoint).
  // `margin`: `clean` is the frame widened by it (LensTrace).
  Kernel(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
         const SceneSample& scene, const DropAccel& accel, const EffectPlan* plan, bool lockstep, int margin)
      : bg_(clean, config.border),
        camera_(camera),
        scene_(scene),
        glass_(scene.glass),
        accel_(accel),
        tir_(config.tir),
        interior_(config.fresnel.enabled ? config.fresnel.interior_rgb : glm::dvec3(0.0)),
        n_rgb_(config.channel_indices()),
        disperse_(plan && plan->dispersion_auto ? &plan->drops : nullptr),
        lockstep_(lockstep && accel.disjoint()),
        exact_caps_(accel.options().kind == GeometryOptions::Kind::Exact) {
    bg_.set_margin(margin);
    if (config.sky.enabled) {
      const cv::Rect frame(margin, margin, clean.cols - 2 * margin, clean.rows - 2 * margin);
      bg_.set_sky(estimate_sky_rgb(clean(frame & cv::Rect(0, 0, clean.cols, clean.rows)), config.sky.gain),
                  config.sky.fade_rows * (clean.rows - 2 * margin));
    }
  }

  Sample sample(double px, double py) const { return sample_ray(glm::dvec3(0.0), camera_.ray_direction(px, py)); }

  // A ray from `origin` (a point of the lens, z = 0) along `dir`.
  Sample sample_ray(const glm::dvec3& origin, const glm::dvec3& dir) const {
    Sample s;
    if constexpr (!kDispersion) {
      const DropPath p = trace_path<kFresnel>(origin, dir, n_rgb_.y, tir_, accel_, glass_);
      s.hit = p.hit;
      if (!s.hit) return s;
      s.drop = p.first_drop;
      s.dark = p.dark;
      s.rgb = shade(p, &s.off_frame, &s.xy);
    } else if (disperse_) {
      // Auto: the green path first; the drop it meets says whether red and blue are traced
      // apart or take its colour (their shift there is imperceptible, effect_policy.h).
      const DropPath g = trace_path<kFresnel>(origin, dir, n_rgb_.y, tir_, accel_, glass_);
      if (!g.hit) return s;
      s.hit = true;
      s.drop = g.first_drop;
      s.dark = g.dark;
      s.rgb = shade(g, &s.off_frame, &s.xy);
      if (!(*disperse_)[g.first_drop].dispersion) return s;
      for (int c : {0, 2}) {
        bool off = false;
        s.rgb[c] = shade(trace_path<kFresnel>(origin, dir, n_rgb_[c], tir_, accel_, glass_), &off)[c];
      }
    } else {
      // One path per colour channel: the green path decides hit and drop (all three meet the
      // same first surface, whose position does not depend on the index).
      for (int c = 0; c < 3; ++c) {
        const DropPath p = trace_path<kFresnel>(origin, dir, n_rgb_[c], tir_, accel_, glass_);
        if (!p.hit) return s;  // same first hit for every channel
        bool off = false;
        s.rgb[c] = shade(p, &off, c == 1 ? &s.xy : nullptr)[c];
        if (c == 1) {
          s.hit = true;
          s.drop = p.first_drop;
          s.dark = p.dark;
          s.off_frame = off;
        }
      }
    }
    return s;
  }

  // sample() in steps, without dispersion: the green (or only) paths of the camera rays
  // through up to 8 pixels xs of row py, their first queries asked as one Embree packet; then
  // each path's background point (seen_point) and its sample (finish). run() traces a row's
  // rays before any of their background look-ups, which miss the cache: independent
  // look-ups overlap.
  // Returns how many of the rays were traced side by side (trace_through_one_drop).
  int trace_camera_packet(const int* xs, int n, double py, DropPath* paths) const {
    glm::dvec3 origins[8], dirs[8];
    for (int i = 0; i < n; ++i) {
      origins[i] = glm::dvec3(0.0);
      dirs[i] = camera_.ray_direction(xs[i], py);
    }
    return trace_packet(origins, dirs, n, paths);
  }

  // The green (or only) paths of n <= 8 rays origins[i] + t dirs[i] (any length), their first
  // queries asked as one Embree packet, those on the common path traced side by side
  // (trace_through_one_drop, with lockstep), the others one at a time: what trace_path gives
  // each, to the bit. Returns how many were traced side by side.
  int trace_packet(const glm::dvec3* origins, const glm::dvec3* raw_dirs, int n, DropPath* paths) const {
    glm::dvec3 dirs[8];
    double t_min[8], t_max[8];
    int ask[8], asked = 0;  // the rays that meet the slab, whose first query is asked
    const double top = accel_.slab_top();
    for (int i = 0; i < n; ++i) {
      dirs[i] = glm::normalize(raw_dirs[i]);
      if (slab_range(origins[i], dirs[i], glass_, top, &t_min[i], &t_max[i])) ask[asked++] = i;
    }
    glm::dvec3 ask_origins[8], ask_dirs[8];
    double ask_min[8], ask_max[8];
    for (int k = 0; k < asked; ++k) {
      ask_origins[k] = origins[ask[k]];
      ask_dirs[k] = dirs[ask[k]];
      ask_min[k] = t_min[ask[k]];
      ask_max[k] = t_max[ask[k]];
    }
    std::optional<DropHit> hits[8];
    accel_.intersect_packet(ask_origins, ask_dirs, ask_min, ask_max, asked, hits);
    std::optional<DropHit> first[8];
    for (int k = 0; k < asked; ++k) first[ask[k]] = hits[k];
    bool traced[8] = {};
    if (lockstep_) trace_through_one_drop(origins, dirs, first, n, paths, traced);
    int side_by_side = 0;
    for (int i = 0; i < n; ++i) {
      if (traced[i]) {
        ++side_by_side;
      } else {
        paths[i] = trace_path<kFresnel>(origins[i], raw_dirs[i], n_rgb_.y, tir_, accel_, glass_, &first[i]);
      }
    }
    return side_by_side;
  }
  bool lockstep() const { return lockstep_; }

  // Rays 0..n-1 of one pixel, `ray(i, &origin, &dir)` giving each (dir unnormalised), handed in
  // order to `use(i, origin, sample)`: 8 at a time through trace_packet where rays are traced
  // side by side (no dispersion), else one by one through sample_ray; each gets what sample_ray
  // gives it, to the bit. Returns how many were traced side by side.
  template <class Ray, class Use>
  std::int64_t trace_rays(int n, const Ray& ray, const Use& use) const {
    if (n <= 0) return 0;  // (an aperture pixel's rays all taken by the lanes: no packet to make)
    if (kDispersion || !lockstep_) {
      for (int i = 0; i < n; ++i) {
        glm::dvec3 origin, dir;
        ray(i, &origin, &dir);
        use(i, origin, sample_ray(origin, dir));
      }
      return 0;
    }
    std::int64_t side_by_side = 0;
    glm::dvec3 origins[8], dirs[8];
    DropPath paths[8];
    for (int first = 0; first < n; first += 8) {
      const int m = std::min(8, n - first);
      for (int i = 0; i < m; ++i) ray(first + i, &origins[i], &dirs[i]);
      side_by_side += trace_packet(origins, dirs, m, paths);
      for (int i = 0; i < m; ++i) use(first + i, origins[i], paths[i].hit ? finish(paths[i], seen_point(paths[i])) : Sample{});
    }
    return side_by_side;
  }

  // The rays of a packet that take the common path, traced side by side: in through
  // a drop's base, out through its cap, and on to the street with no other drop in reach
  // (or black in the dark band). One ray's path is a chain of square roots and divisions,
  // each waiting on the one before; a stage at a time over all the rays gives the processor
  // independent work to overlap. Each step is trace_path's own arithmetic in the same order,
  // so the result is the same to the bit (tests/render/test_tracer.cpp, Lockstep.*, compare
  // with the lock-step off).
  // A ray that leaves the common path at any step (a first hit on a cap, total internal
  // reflection traced on, another drop within reach) is marked untraced and traced again
  // from the start by trace_path, which handles everything.
  void trace_through_one_drop(const glm::dvec3* origins, const glm::dvec3* dirs, const std::optional<DropHit>* first,
                              int n, DropPath* paths, bool* traced) const {
    glm::dvec3 o[8], d[8];
    DropHit current[8];
    double t_range[8];
    int lane[8], live = 0;
    // Event 0: in through the base of the drop the first query found.
    for (int i = 0; i < n; ++i) {
      if (!first[i]) continue;
      const DropHit& hit = *first[i];
      d[i] = dirs[i];
      if (!(glm::dot(d[i], hit.normal) < 0)) continue;  // met a cap from outside
      const double eta = 1.0 / n_rgb_.y;
      const auto refracted = refract(d[i], hit.normal, eta);
      if (!refracted) continue;
      DropPath& path = paths[i];
      path = DropPath();
      path.hit = true;
      path.first_drop = hit.drop;
      path.events = 1;
      if constexpr (kFresnel) path.transmittance *= 1.0 - fresnel_reflectance(-glm::dot(d[i], hit.normal), eta);
      o[i] = origins[i] + hit.t * d[i];
      current[i] = hit;
      d[i] = *refracted;
      lane[live++] = i;
    }
    // Event 1: out through the drop's cap (its only surface a ray inside can meet when
    // drops are disjoint).
    const double top = accel_.slab_top();
    double t_lo;
    std::optional<DropHit> exit_hit[8];
    // Rays in through the base of an exact cap of circular outline leave through that cap: the
    // closed form, two rays at a time (exit_through_caps, Drop::intersect's answer to the bit).
    // Others ask the accelerator one at a time.
    const Drop* cap_drops[8];
    glm::dvec3 cap_o[8], cap_d[8];
    double cap_t[8];
    int cap_lane[8], caps = 0;
    for (int k = 0; k < live; ++k) {
      const int i = lane[k];
      exit_hit[i] = std::nullopt;
      if (!slab_range(o[i], d[i], glass_, top, &t_lo, &t_range[i])) continue;
      const Drop& drop = accel_.drops()[current[i].drop];
      if (exact_caps_ && current[i].surface == DropSurface::Base && drop.shape().outline.circular()) {
        cap_drops[caps] = &drop;
        cap_o[caps] = o[i];
        cap_d[caps] = d[i];
        cap_t[caps] = t_range[i];
        cap_lane[caps++] = i;
      } else {
        exit_hit[i] = accel_.intersect_inside(o[i], d[i], current[i], t_range[i]);
      }
    }
    if (caps > 0) {
      CapExit exits[8];
      exit_through_caps(cap_drops, cap_o, cap_d, cap_t, caps, exits);
      for (int k = 0; k < caps; ++k) {
        if (exits[k].hit) exit_hit[cap_lane[k]] = DropHit{exits[k].t, current[cap_lane[k]].drop, DropSurface::Cap, exits[k].normal};
      }
    }
    int still = 0;
    for (int k = 0; k < live; ++k) {
      const int i = lane[k];
      DropPath& path = paths[i];
      if (!exit_hit[i]) {  // no way out found: trapped, as trace_path ends it
        path.dark = true;
        traced[i] = true;
        continue;
      }
      const DropHit& hit = *exit_hit[i];
      if (glm::dot(d[i], hit.normal) < 0) continue;  // entering from inside: not the common path
      const glm::dvec3 facing = -hit.normal;
      const double eta = n_rgb_.y;
      const auto refracted = refract(d[i], facing, eta);
      if (!refracted && tir_ != TirMode::Black) continue;  // internal reflection traced on
      ++path.events;
      if constexpr (kFresnel) path.transmittance *= 1.0 - fresnel_reflectance(-glm::dot(d[i], facing), eta);
      if (!refracted) {  // the dark band
        path.dark = true;
        traced[i] = true;
        continue;
      }
      o[i] = o[i] + hit.t * d[i];
      current[i] = hit;
      d[i] = *refracted;
      lane[still++] = i;
    }
    // Event 2: on to the street, unless another drop may be in reach.
    for (int k = 0; k < still; ++k) {
      const int i = lane[k];
      if (slab_range(o[i], d[i], glass_, top, &t_lo, &t_range[i]) &&
          accel_.may_meet_after_exit(current[i].drop, o[i], d[i], t_range[i]))
        continue;
      DropPath& path = paths[i];
      path.escaped_in = glm::dot(d[i], glass_.normal) <= 0;
      path.origin = o[i];
      path.dir = d[i];
      traced[i] = true;
    }
  }
  // The background point a path sees (NaN: none, for a dark path or one into the car).
  glm::dvec2 seen_point(const DropPath& p) const {
    if (p.dark || p.escaped_in) return {NAN, NAN};
    return background_pixel(p, camera_, scene_.background_distance_cm);
  }
  void prefetch(const glm::dvec2& xy) const {
    if (!std::isnan(xy.x)) bg_.prefetch(xy.x, xy.y);
  }
  // What shading reads of a path that met a drop.
  struct PathEnd {
    int drop;
    bool dark, escaped_in;
    double transmittance;
  };
  static PathEnd end_of(const DropPath& p) { return {p.first_drop, p.dark, p.escaped_in, p.transmittance}; }
  Sample finish(const DropPath& p, const glm::dvec2& xy) const { return p.hit ? finish(end_of(p), xy) : Sample{}; }
  Sample finish(const PathEnd& p, const glm::dvec2& xy) const {
    Sample s;
    finish_into(p, xy, &s);
    return s;
  }
  // The same written into *s field by field: a Sample built on the stack and copied stalled
  // every aperture ray on a store its copy's wider loads could not forward.
  void finish_into(const PathEnd& p, const glm::dvec2& xy, Sample* s) const {
    s->hit = true;
    s->drop = p.drop;
    s->dark = p.dark;
    s->off_frame = false;
    s->xy = glm::dvec2(NAN, NAN);
    s->rgb = shade_at(p, xy, &s->off_frame, &s->xy);
  }

  glm::dvec3 clean_pixel(int x, int y) const { return bg_.pixel(x, y); }
  const BackgroundSampler& background() const { return bg_; }

 private:
  // `seen_at`, if given, receives the background point seen (left alone for a dark ray or one
  // that reaches the car's interior).
  glm::dvec3 shade(const DropPath& p, bool* off_frame, glm::dvec2* seen_at = nullptr) const {
    return shade_at(end_of(p), seen_point(p), off_frame, seen_at);
  }
  // The same with the background point seen already computed (seen_point).
  glm::dvec3 shade_at(const PathEnd& p, const glm::dvec2& xy, bool* off_frame, glm::dvec2* seen_at = nullptr) const {
    if (p.dark) return glm::dvec3(0.0);
    glm::dvec3 seen;
    if (p.escaped_in) {
      seen = interior_;
    } else {
      *off_frame = !bg_.inside(xy.x, xy.y);
      seen = bg_.sample(xy.x, xy.y);
      if (seen_at) *seen_at = xy;
    }
    if constexpr (kFresnel) {
      // Light reflected at the surfaces instead of transmitted comes from the car side.
      return p.transmittance * seen + (1.0 - p.transmittance) * interior_;
    }
    return seen;
  }

  BackgroundSampler bg_;
  const Camera& camera_;
  const SceneSample& scene_;
  const GlassFrame glass_;
  const DropAccel& accel_;
  TirMode tir_;
  glm::dvec3 interior_;
  glm::dvec3 n_rgb_;
  const std::vector<DropEffects>* disperse_;
  bool lockstep_;
  bool exact_caps_;  // intersect_inside answers from the drop's closed form (not a mesh)
};

// Andrew's monotone chain, in double precision (counter-clockwise, no repeated point).
void convex_hull(std::vector<glm::dvec2> points, std::vector<glm::dvec2>* hull) {
  std::sort(points.begin(), points.end(), [](const glm::dvec2& a, const glm::dvec2& b) {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
  });
  auto cross = [](const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
  };
  hull->assign(2 * points.size(), glm::dvec2(0));
  size_t k = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    while (k >= 2 && cross((*hull)[k - 2], (*hull)[k - 1], points[i]) <= 0) --k;
    (*hull)[k++] = points[i];
  }
  for (size_t i = points.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross((*hull)[k - 2], (*hull)[k - 1], points[i]) <= 0) --k;
    (*hull)[k++] = points[i];
  }
  hull->resize(k > 1 ? k - 1 : k);
}

// One drop's part of candidate_spans: the rows (y, x0, x1) its image can reach.
struct RowSpan {
  int y, x0, x1;
};
void drop_rows(const Camera& camera, const Drop& drop, std::vector<RowSpan>* out) {
  auto add_rows = [&](double y0, double y1, double x0, double x1) {
    const int ix0 = static_cast<int>(std::max(0.0, std::floor(x0)));
    const int ix1 = static_cast<int>(std::min(camera.width - 1.0, std::ceil(x1)));
    const int iy0 = static_cast<int>(std::max(0.0, std::floor(y0)));
    const int iy1 = static_cast<int>(std::min(camera.height - 1.0, std::ceil(y1)));
    for (int y = iy0; y <= iy1 && ix0 <= ix1; ++y) out->push_back({y, ix0, ix1});
  };
  constexpr int kAzimuths = 48, kRings = 4;
  std::vector<glm::dvec2> points, hull;
  bool behind = false;
  const double tau = drop.shape().contact_angle;
  for (int r = 0; r <= kRings && !behind; ++r) {
    for (int a = 0; a < (r == 0 ? 1 : kAzimuths); ++a) {
      const glm::dvec3 p = drop.envelope_point(tau * r / kRings, 2 * M_PI * a / kAzimuths);
      if (p.z <= 1e-9) {
        behind = true;
        break;
      }
      points.push_back(camera.project(p));
    }
  }
  if (behind || points.size() < 3) {  // reaches behind the camera: trace the whole frame
    add_rows(0, camera.height - 1, 0, camera.width - 1);
    return;
  }
  convex_hull(points, &hull);
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const auto& p : hull) {
    x0 = std::min(x0, p.x), x1 = std::max(x1, p.x), y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
  }
  if (!(x1 >= -camera.width && x0 <= 2.0 * camera.width && y1 >= -camera.height && y0 <= 2.0 * camera.height))
    return;  // far outside the frame
  // Padding: the sampled hull lies inside the true one by at most the sagitta of the
  // largest sampling step (< 1% of the size here), plus a pixel for rasterisation.
  const double pad = 1.0 + 0.01 * std::max(x1 - x0, y1 - y0);
  if (x1 - x0 > 4.0 * camera.width || y1 - y0 > 4.0 * camera.height) {  // huge: bounds will do
    add_rows(y0 - pad, y1 + pad, x0 - pad, x1 + pad);
    return;
  }
  // For each row, the x-extent of the hull within the band [y - pad, y + pad], padded.
  const int iy0 = static_cast<int>(std::max(0.0, std::floor(y0 - pad)));
  const int iy1 = static_cast<int>(std::min(camera.height - 1.0, std::ceil(y1 + pad)));
  if (iy0 > iy1) return;
  std::vector<double> lo(iy1 - iy0 + 1, 1e300), hi(iy1 - iy0 + 1, -1e300);
  for (size_t i = 0; i < hull.size(); ++i) {
    const glm::dvec2 a = hull[i], b = hull[(i + 1) % hull.size()];
    const int ra = std::max(iy0, static_cast<int>(std::floor(std::min(a.y, b.y) - pad)));
    const int rb = std::min(iy1, static_cast<int>(std::ceil(std::max(a.y, b.y) + pad)));
    for (int y = ra; y <= rb; ++y) {
      // Part of the edge inside the band, by its parameter range.
      double s0 = 0, s1 = 1;
      const double dy = b.y - a.y;
      if (std::abs(dy) > 1e-12) {
        double u0 = (y - pad - a.y) / dy, u1 = (y + pad - a.y) / dy;
        if (u0 > u1) std::swap(u0, u1);
        s0 = std::max(s0, u0);
        s1 = std::min(s1, u1);
      } else if (std::abs(a.y - y) > pad) {
        continue;
      }
      if (s0 > s1) continue;
      const double xa = a.x + s0 * (b.x - a.x), xb = a.x + s1 * (b.x - a.x);
      lo[y - iy0] = std::min({lo[y - iy0], xa, xb});
      hi[y - iy0] = std::max({hi[y - iy0], xa, xb});
    }
  }
  for (int y = iy0; y <= iy1; ++y) {
    if (lo[y - iy0] > hi[y - iy0]) continue;
    add_rows(y, y, lo[y - iy0] - pad, hi[y - iy0] + pad);
  }
}

// Per image row, the merged x-intervals that can show a drop. A drop's cap is convex, so
// its image is the convex hull of its projected surface (of its convex envelope for an
// irregular outline, drop.h); the hull of a dense sample of rim
// and cap points, padded by more than the sampling error, bounds it conservatively. Rays
// outside these intervals cannot meet a drop and are not traced.
// `by_drop`, if given, receives the same intervals per drop, unmerged (PinholeLanes). The
// drops' hulls are found in parallel, the rows merged in parallel.
std::vector<std::vector<std::pair<int, int>>> candidate_spans(const Camera& camera, const DropAccel& accel,
                                                              std::vector<std::vector<DropSpan>>* by_drop = nullptr) {
  const std::vector<Drop>& drops = accel.drops();
  std::vector<std::vector<RowSpan>> parts(drops.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, drops.size(), 4), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) drop_rows(camera, drops[i], &parts[i]);
  });
  std::vector<std::vector<std::pair<int, int>>> rows(camera.height);
  if (by_drop) by_drop->assign(camera.height, {});
  for (size_t i = 0; i < parts.size(); ++i) {
    for (const RowSpan& s : parts[i]) {
      rows[s.y].push_back({s.x0, s.x1});
      if (by_drop) (*by_drop)[s.y].push_back({s.x0, s.x1, static_cast<int>(i)});
    }
  }
  tbb::parallel_for(tbb::blocked_range<int>(0, camera.height, 64), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y < r.end(); ++y) merge_spans(rows[y]);
  });
  return rows;
}

}  // namespace

std::vector<std::vector<DropSpan>> drop_candidate_spans(const Camera& camera, const DropAccel& accel) {
  std::vector<std::vector<DropSpan>> by_drop;
  candidate_spans(camera, accel, &by_drop);
  return by_drop;
}

namespace {

// A traced ray's colour in linear light, lifted where the scene lifts highlights
// (highlights.h): what the aperture paths average. Decoded by the table (within 2e-7 of the
// formula: srgb.h), as the fast path decodes: a pow per channel was a twentieth of the
// reference's time.
glm::dvec3 lifted_linear(const Sample& s, const HighlightLift& lift) {
  const SrgbTables& tables = SrgbTables::get();
  double rgb[3];
  for (int c = 0; c < 3; ++c) rgb[c] = tables.decode(static_cast<float>(s.rgb[c]));
  lift.apply(rgb);
  return {rgb[0], rgb[1], rgb[2]};
}

// Label used to find edges: drop index, with dark-band pixels distinguished.
inline int edge_class(int label, bool dark) { return label < 0 ? -1 : 2 * label + (dark ? 1 : 0); }

// Past this many drops in a pixel's cone, its rays are not tested one by one against them
// (Embree's query tests them faster).
constexpr size_t kMaxDropsTestedPerRay = 8;
// Past this many, a pixel's rays go to Embree's query instead of the lanes, which try every
// drop in the cone on every ray.
constexpr size_t kMaxDropsInLanes = 8;

// Scratch for trace_pixel_rays: a pixel's rays for the lanes (origins x, y, z and directions
// x, y, z, padded to a register) and their results.
struct LaneScratch {
  PinholeLanes::Row row;
  std::vector<double> rays[6];
};
struct RaysTraced {
  std::int64_t side_by_side = 0, in_lanes = 0;
};

// A pixel's rays `asked` (indices into origins and dirs, the directions unnormalised), each
// given its Sample in seen_by[ray]: in the lanes where `lanes` is given, against `near` (every
// drop those rays can meet), and the rays that leave the common path there, or all of them
// without lanes, by kernel.trace_rays; to the bit what trace_rays gives each. `asked` is left
// holding the rays traced alone.
template <class K>
RaysTraced trace_pixel_rays(const K& kernel, const PinholeLanes* lanes, const std::vector<int>& near,
                            const glm::dvec3* origins, const glm::dvec3* dirs, std::vector<int>* asked,
                            LaneScratch* scratch, Sample* seen_by) {
  RaysTraced out;
  const int m = static_cast<int>(asked->size());
  if (lanes && m > 0) {
    const int padded = (m + 7) / 8 * 8;
    for (auto& v : scratch->rays)
      if (v.size() < static_cast<size_t>(padded)) v.resize(static_cast<size_t>(padded));
    auto& r = scratch->rays;
    for (int i = 0; i < padded; ++i) {
      const int ray = (*asked)[std::min(i, m - 1)];
      const glm::dvec3 d = glm::normalize(dirs[ray]);  // as trace_packet normalises it
      r[0][i] = origins[ray].x, r[1][i] = origins[ray].y, r[2][i] = origins[ray].z;
      r[3][i] = d.x, r[4][i] = d.y, r[5][i] = d.z;
    }
    const lanes_detail::RayArrays arrays{r[0].data(), r[1].data(), r[2].data(), r[3].data(), r[4].data(), r[5].data()};
    const PinholeLanes::Row& row = scratch->row;
    out.in_lanes = lanes->trace_rays(arrays, m, near, &scratch->row);
    out.side_by_side = out.in_lanes;
    int left = 0;
    for (int i = 0; i < m; ++i) {
      const int ray = (*asked)[i];
      switch (row.outcome[i]) {
        case PinholeLanes::Outcome::Miss:
          set_miss(&seen_by[ray]);
          break;
        case PinholeLanes::Outcome::Path: {
          // As seen_point: no background point for a dark ray or one into the car.
          const bool black = row.dark(i), escaped = row.escaped_in(i);
          const glm::dvec2 xy = black || escaped ? glm::dvec2(NAN, NAN) : glm::dvec2(row.seen_x[i], row.seen_y[i]);
          kernel.finish_into(typename K::PathEnd{row.drop[i], black, escaped, row.transmittance[i]}, xy, &seen_by[ray]);
          break;
        }
        case PinholeLanes::Outcome::Alone:
          (*asked)[left++] = ray;
          break;
      }
    }
    asked->resize(static_cast<size_t>(left));
  }
  out.side_by_side += kernel.trace_rays(
      static_cast<int>(asked->size()),
      [&](int i, glm::dvec3* origin, glm::dvec3* dir) {
        *origin = origins[(*asked)[i]];
        *dir = dirs[(*asked)[i]];
      },
      [&](int i, const glm::dvec3&, const Sample& s) { seen_by[(*asked)[i]] = s; });
  return out;
}

template <bool kFresnel, bool kDispersion>
TraceResult run(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                const SceneSample& scene, const DropAccel& accel, const EffectPlan* plan, const TraceStrategy& strategy,
                const LensTrace* lens) {
  const int margin = lens ? lens->margin : 0;
  const Kernel<kFresnel, kDispersion> kernel(clean, camera, config, scene, accel, plan, strategy.lockstep, margin);
  TraceResult out;
  out.label = scratch_mat(camera.height, camera.width, CV_32S);  // -1 (no drop) row by row in pass 1
  out.color = scratch_mat(camera.height, camera.width, CV_32FC3);  // written at drop pixels only
  // Edge classes are only needed to find the pixels to supersample.
  const int k = static_cast<int>(std::lround(std::sqrt(config.samples_per_pixel)));
  const bool need_classes = k > 1 && config.supersample != Supersample::All;
  cv::Mat classes = need_classes ? cv::Mat(camera.height, camera.width, CV_32S, cv::Scalar(-1)) : cv::Mat();
  // Auto supersampling: the background point each drop pixel's ray saw (NaN: the dark band,
  // infinite: the car's interior), whose distance to its neighbours' is the pixel's footprint
  // on the background.
  const bool automatic = k > 1 && config.supersample == Supersample::Auto;
  cv::Mat seen_at = automatic ? cv::Mat(camera.height, camera.width, CV_32FC2, cv::Scalar::all(NAN)) : cv::Mat();
  std::optional<BackgroundRange> variation;
  if (automatic) variation.emplace(clean, kernel.background());
  // The pinhole pass in SIMD lanes where they apply (pinhole_lanes.h): the same bits.
  std::optional<PinholeLanes> lanes;
  std::vector<std::vector<DropSpan>> drop_spans;
  if constexpr (!kDispersion) {
    if (strategy.lanes && kernel.lockstep() && PinholeLanes::applies(accel))
      lanes.emplace(camera, accel, scene.glass, scene.background_distance_cm, config.channel_indices().y, config.tir,
                    kFresnel);
  }
  out.spans = candidate_spans(camera, accel, lanes ? &drop_spans : nullptr);
  const auto& spans = out.spans;
  std::atomic<std::int64_t> candidates{0}, drops{0}, dark{0}, off{0}, supersampled{0}, aliasing{0}, smooth{0},
      lockstep{0}, in_lanes{0};
  std::vector<int> row_lo(camera.height, camera.width), row_hi(camera.height, -1);

  // Pass 1: one ray through every candidate pixel's centre.
  tbb::parallel_for(tbb::blocked_range<int>(0, camera.height, 8), [&](const tbb::blocked_range<int>& r) {
    std::int64_t n_cand = 0, n_drop = 0, n_dark = 0, n_off = 0, n_lock = 0, n_lanes = 0;
    struct Pending {
      int x;
      typename Kernel<kFresnel, kDispersion>::PathEnd end;
      glm::dvec2 xy;
    };
    std::vector<Pending> pending;
    PinholeLanes::Row lane_row;
    for (int y = r.begin(); y < r.end(); ++y) {
      auto* label = out.label.ptr<int>(y);
      std::fill(label, label + camera.width, -1);
      int* cls = need_classes ? classes.ptr<int>(y) : nullptr;
      auto* rgb = out.color.ptr<cv::Vec3f>(y);
      auto keep = [&](int x, const Sample& s) {
        ++n_drop;
        row_lo[y] = std::min(row_lo[y], x);
        row_hi[y] = std::max(row_hi[y], x);
        n_dark += s.dark;
        n_off += s.off_frame;
        label[x] = s.drop;
        if (cls) cls[x] = edge_class(s.drop, s.dark);
        if (automatic && !s.dark) {
          // A ray that saw no street saw the car's interior: marked infinite.
          seen_at.at<cv::Vec2f>(y, x) = std::isnan(s.xy.x) ? cv::Vec2f(INFINITY, INFINITY)
                                                          : cv::Vec2f(static_cast<float>(s.xy.x), static_cast<float>(s.xy.y));
        }
        rgb[x] = cv::Vec3f(static_cast<float>(s.rgb.x), static_cast<float>(s.rgb.y), static_cast<float>(s.rgb.z));
      };
      if constexpr (kDispersion) {
        for (const auto& [x0, x1] : spans[y]) {
          for (int x = x0; x <= x1; ++x) {
            ++n_cand;
            const Sample s = kernel.sample(x, y);
            if (s.hit) keep(x, s);
          }
        }
      } else {
        // The row's rays first, then their background look-ups, each started a few pixels
        // ahead of its use: the look-ups land anywhere in the frame (a drop shows a minified
        // view of it) and miss the cache, and the tracing between two of them is too long
        // for the processor to overlap the misses by itself. Same arithmetic, same result.
        pending.clear();
        int xs[8], queued = 0;
        DropPath paths[8];
        auto flush = [&] {
          n_lock += kernel.trace_camera_packet(xs, queued, y, paths);
          for (int i = 0; i < queued; ++i)
            if (paths[i].hit) pending.push_back({xs[i], kernel.end_of(paths[i]), kernel.seen_point(paths[i])});
          queued = 0;
        };
        if (lanes) {
          // The lanes trace most rays; those that leave the common path go to flush().
          const int traced_here = lanes->trace_row(y, drop_spans[y], &lane_row);
          n_lock += traced_here;
          n_lanes += traced_here;
          for (const auto& [x0, x1] : spans[y]) {
            for (int x = x0; x <= x1; ++x) {
              ++n_cand;
              const PinholeLanes::Outcome o = lane_row.outcome[x];
              if (o == PinholeLanes::Outcome::Path) {
                // As seen_point: no background point for a dark ray or one into the car.
                // Each field stored in place: a whole Pending built on the stack and copied was
                // reloaded 16 bytes at a time over its narrower stores, which the processor cannot
                // forward (a stall per ray, a quarter of this loop's time).
                const bool black = lane_row.dark(x), escaped = lane_row.escaped_in(x);
                Pending& p = pending.emplace_back();
                p.x = x;
                p.end.drop = lane_row.drop[x];
                p.end.dark = black;
                p.end.escaped_in = escaped;
                p.end.transmittance = lane_row.transmittance[x];
                p.xy = black || escaped ? glm::dvec2(NAN, NAN) : glm::dvec2(lane_row.seen_x[x], lane_row.seen_y[x]);
              } else if (o == PinholeLanes::Outcome::Alone) {
                xs[queued++] = x;
                if (queued == 8) flush();
              }
            }
          }
        } else {
          for (const auto& [x0, x1] : spans[y]) {
            for (int x = x0; x <= x1; ++x) {
              ++n_cand;
              xs[queued++] = x;
              if (queued == 8) flush();
            }
          }
        }
        if (queued > 0) flush();
        constexpr size_t kAhead = 8;
        for (size_t i = 0; i < std::min(kAhead, pending.size()); ++i) kernel.prefetch(pending[i].xy);
        for (size_t i = 0; i < pending.size(); ++i) {
          if (i + kAhead < pending.size()) kernel.prefetch(pending[i + kAhead].xy);
          keep(pending[i].x, kernel.finish(pending[i].end, pending[i].xy));
        }
      }
    }
    candidates += n_cand;
    drops += n_drop;
    dark += n_dark;
    off += n_off;
    lockstep += n_lock;
    in_lanes += n_lanes;
  });

  int box_x0 = camera.width, box_x1 = -1, box_y0 = camera.height, box_y1 = -1;
  for (int y = 0; y < camera.height; ++y) {
    if (row_hi[y] < 0) continue;
    box_x0 = std::min(box_x0, row_lo[y]), box_x1 = std::max(box_x1, row_hi[y]);
    box_y0 = std::min(box_y0, y), box_y1 = y;
  }
  out.drop_box = box_x1 < 0 ? cv::Rect() : cv::Rect(box_x0, box_y0, box_x1 - box_x0 + 1, box_y1 - box_y0 + 1);

  // The pixels LensTrace averages over the aperture: those of a flagged drop and those next
  // to one that met no drop (the lens spreads a drop by under half a pixel, so its coverage
  // reaches at most the next pixel). Chosen from the pinhole labels before any changes.
  const bool sample_lens = lens != nullptr && lens->any_sampled() && scene.aperture_cm() > 0;
  cv::Mat lens_pixels;
  if (sample_lens) {
    CV_Assert(lens->sampled.size() == accel.drops().size());
    lens_pixels = cv::Mat(camera.height, camera.width, CV_8U, cv::Scalar(0));
    auto flagged = [&](int d) { return d >= 0 && lens->sampled[static_cast<size_t>(d)] != 0; };
    tbb::parallel_for(tbb::blocked_range<int>(0, camera.height, 8), [&](const tbb::blocked_range<int>& r) {
      for (int y = r.begin(); y < r.end(); ++y) {
        const int* label = out.label.ptr<int>(y);
        auto* pick = lens_pixels.ptr<std::uint8_t>(y);
        for (const auto& [x0, x1] : spans[y]) {
          for (int x = x0; x <= x1; ++x) {
            if (flagged(label[x])) {
              pick[x] = 1;
              continue;
            }
            if (label[x] >= 0) continue;  // another drop's pixel keeps its pinhole ray
            for (int dy = -1; dy <= 1 && !pick[x]; ++dy) {
              const int yy = y + dy;
              if (yy < 0 || yy >= camera.height) continue;
              const int* row = out.label.ptr<int>(yy);
              for (int dx = -1; dx <= 1; ++dx) {
                const int xx = x + dx;
                if (xx >= 0 && xx < camera.width && flagged(row[xx])) {
                  pick[x] = 1;
                  break;
                }
              }
            }
          }
        }
      }
    });
  }

  // Auto: does the background vary over the pixel's footprint by more than the budget
  // (effect_policy.h)? The footprint is the largest step to a neighbour's sample: the pixel's
  // sub-samples lie within half a step of its centre's where the map from pixels to the
  // background is smooth. Where it is not (a neighbour's step is not matched by the opposite
  // one: the map folds or jumps), where a neighbour saw no street and on the frame's border
  // (no neighbour beyond it to show an edge there), the pixel is supersampled. The dark band
  // is black and its edges are class edges: flat. With traced internal reflection, rays that
  // are trapped, leave into the car or reach the street after reflections interleave in
  // slivers thinner than a pixel (the class does not tell them apart): supersampled. Without
  // it, a ray reaches the car's interior only when it leaves the cap heading back to the
  // glass (near a rim); such a pixel is flat only among neighbours that all did.
  auto aliases = [&](int x, int y) {
    if (x == 0 || y == 0 || x == camera.width - 1 || y == camera.height - 1) return true;
    const cv::Vec2f p = seen_at.at<cv::Vec2f>(y, x);
    if (std::isnan(p[0])) return config.tir != TirMode::Black;
    if (std::isinf(p[0])) {
      if (config.tir != TirMode::Black) return true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if (!std::isinf(seen_at.at<cv::Vec2f>(y + dy, x + dx)[0])) return true;
      return false;
    }
    double size = 0;
    constexpr int kPairs[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
    for (const auto& step : kPairs) {
      const cv::Vec2f a = seen_at.at<cv::Vec2f>(y + step[1], x + step[0]);
      const cv::Vec2f b = seen_at.at<cv::Vec2f>(y - step[1], x - step[0]);
      if (!std::isfinite(a[0]) || !std::isfinite(b[0])) return true;
      const double da = std::hypot(a[0] - p[0], a[1] - p[1]), db = std::hypot(b[0] - p[0], b[1] - p[1]);
      if (std::hypot(a[0] + b[0] - 2 * p[0], a[1] + b[1] - 2 * p[1]) > 0.5 * std::max(da, db)) return true;
      const double diagonal = step[0] != 0 && step[1] != 0 ? M_SQRT1_2 : 1.0;
      size = std::max(size, diagonal * std::max(da, db));
    }
    const glm::dvec3 spread = variation->range(p[0], p[1], size);
    return 255.0 * std::max({spread.x, spread.y, spread.z}) >= kAutoBudgetLevels;
  };

  // Pass 2: supersample drop pixels on an edge (a neighbour of another class: outside, other
  // drop, dark band), all drop pixels, or (auto) the edges and the inside pixels that alias,
  // on a stratified k x k grid. The mask stays the pixel-centre rule; sub-samples that miss
  // every drop see the clean pixel.
  if (k > 1) {
    tbb::parallel_for(tbb::blocked_range<int>(0, camera.height, 8), [&](const tbb::blocked_range<int>& r) {
      std::int64_t n_ss = 0, n_alias = 0, n_smooth = 0;
      for (int y = r.begin(); y < r.end(); ++y) {
        const int* label = out.label.ptr<int>(y);
        auto* rgb = out.color.ptr<cv::Vec3f>(y);
        for (const auto& [x0, x1] : spans[y]) {
          for (int x = x0; x <= x1; ++x) {
            if (label[x] < 0) continue;
            if (sample_lens && lens_pixels.at<std::uint8_t>(y, x)) continue;  // pass 3 samples it
            if (config.supersample != Supersample::All) {
              const int own = classes.at<int>(y, x);
              bool edge = false;
              for (int dy = -1; dy <= 1 && !edge; ++dy) {
                for (int dx = -1; dx <= 1 && !edge; ++dx) {
                  const int yy = y + dy, xx = x + dx;
                  if (yy < 0 || xx < 0 || yy >= camera.height || xx >= camera.width) continue;
                  edge = classes.at<int>(yy, xx) != own;
                }
              }
              if (!edge && !automatic) continue;
              if (!edge && !aliases(x, y)) {
                ++n_smooth;
                continue;
              }
              n_alias += !edge;
            }
            ++n_ss;
            glm::dvec3 sum(0.0);
            for (int j = 0; j < k; ++j) {
              for (int i = 0; i < k; ++i) {
                const Sample s = kernel.sample(x + (i + 0.5) / k - 0.5, y + (j + 0.5) / k - 0.5);
                sum += s.hit ? s.rgb : kernel.clean_pixel(x, y);
              }
            }
            sum /= static_cast<double>(k * k);
            rgb[x] = cv::Vec3f(static_cast<float>(sum.x), static_cast<float>(sum.y),
                               static_cast<float>(sum.z));
          }
        }
      }
      supersampled += n_ss;
      aliasing += n_alias;
      smooth += n_smooth;
    });
  }

  // Pass 3 (LensTrace): the chosen pixels average k x k rays from the lens disk through their
  // point on the plane of focus, each traced as the aperture reference traces it; the colour is
  // the mean, in linear light, of the rays that met a drop, the coverage their fraction.
  std::atomic<std::int64_t> lens_sampled{0};
  if (sample_lens) {
    // Rays from the lens see the street before the lens blurred it: their spread is that blur.
    std::optional<Kernel<kFresnel, kDispersion>> own_sharp;
    if (lens->sharp != nullptr) {
      CV_Assert(lens->sharp->size() == clean.size() && lens->sharp->type() == clean.type());
      own_sharp.emplace(*lens->sharp, camera, config, scene, accel, plan, strategy.lockstep, margin);
    }
    const Kernel<kFresnel, kDispersion>& lens_kernel = own_sharp ? *own_sharp : kernel;
    const HighlightLift& lift = scene.highlights;
    out.coverage = cv::Mat(camera.height, camera.width, CV_32F, cv::Scalar(1));
    const int kl = std::max(1, static_cast<int>(std::lround(std::sqrt(lens->samples))));
    const double radius = 0.5 * scene.aperture_cm();
    const double F = scene.focus_cm();
    // Ray `sample` of a pixel starts at lens stratum `sample mod kl^2` and aims at its point on
    // the plane of focus: the pixel's centre, or, where the scene supersamples (k x k per
    // pixel), a point of one stratum of the pixel's square, jittered by a hash as the lens
    // points are: the pixel's area as well as the aperture. The pixel's strata are paired with
    // the lens' in an order shuffled per pixel (in a fixed order, one side of the pixel would
    // always be seen from one side of the lens), and there are as many rays as the least common
    // multiple of the two grids' strata, so that every stratum of each weighs the same.
    const int cells = k > 1 ? k * k : 1;
    const int rays = std::lcm(kl * kl, cells);
    auto lens_origin = [&](int x, int y, int sample) {
      const int stratum = sample % (kl * kl);
      const glm::dvec2 p = lens_disk_point(x, y, stratum % kl, stratum / kl, kl, radius);
      return glm::dvec3(p.x, p.y, 0.0);
    };
    auto shuffle_cells = [&](int x, int y, std::vector<int>& order) {
      order.resize(cells);
      for (int i = 0; i < cells; ++i) order[i] = i;
      std::uint64_t h = pixel_hash(x, y, 0x9e3779b9ULL);
      for (int i = cells - 1; i > 0; --i) {
        h = mix64(h + static_cast<std::uint64_t>(i));
        std::swap(order[i], order[static_cast<int>(h % static_cast<std::uint64_t>(i + 1))]);
      }
    };
    auto focus_point = [&](int x, int y, int sample, const std::vector<int>& order) {
      if (cells == 1) return F * camera.ray_direction(x, y);
      const int cell = order[sample % cells];
      const glm::dvec2 jitter = unit_pair(pixel_hash(x, y, static_cast<std::uint64_t>(sample) | 0x5bd1e995ULL << 20));
      return F * camera.ray_direction(x + (cell % k + jitter.x) / k - 0.5, y + (cell / k + jitter.y) / k - 0.5);
    };
    // With one focus point per pixel (no supersampling), the rays in SIMD lanes where the
    // pinhole pass's are (pinhole_lanes.h): the same bits.
    const bool lens_lanes = lanes.has_value() && cells == 1;
    // The lanes' path takes a pixel's lens points all at once (lens_disk_points), one per ray:
    // it needs one ray per lens stratum, which one focus point per pixel gives.
    CV_Assert(!lens_lanes || rays == kl * kl);
    std::optional<ApertureReach> lens_reach;
    std::vector<std::vector<DropSpan>> lens_boxes;
    if (lens_lanes) {
      lens_reach.emplace(accel.drops(), radius, F);
      lens_boxes = ApertureReach::candidate_boxes(camera, scene, accel.drops());
    }
    std::atomic<std::int64_t> lens_lane_rays{0};
    tbb::parallel_for(tbb::blocked_range<int>(0, camera.height, 4), [&](const tbb::blocked_range<int>& r) {
      std::int64_t n_sampled = 0, n_lanes = 0;
      std::vector<int> order, near, asked;
      std::vector<glm::dvec3> origins(static_cast<size_t>(rays)), dirs(static_cast<size_t>(rays));
      std::vector<Sample> seen_by(static_cast<size_t>(rays));
      std::vector<glm::dvec2> lens_points(static_cast<size_t>(kl * kl));
      LaneScratch scratch;
      for (int y = r.begin(); y < r.end(); ++y) {
        int* label = out.label.ptr<int>(y);
        auto* rgb = out.color.ptr<cv::Vec3f>(y);
        float* cov = out.coverage.ptr<float>(y);
        const auto* pick = lens_pixels.ptr<std::uint8_t>(y);
        for (const auto& [x0, x1] : spans[y]) {
          for (int x = x0; x <= x1; ++x) {
            if (!pick[x]) continue;
            ++n_sampled;
            if (cells > 1) shuffle_cells(x, y, order);
            glm::dvec3 sum(0.0);
            int hits = 0, first = -1;
            const auto take = [&](const Sample& s) {
              // Only the flagged drops' light: a ray that meets another drop counts as a miss
              // here (that drop's own pixels carry it; a blurred one's layer would spread it
              // again). Two flagged drops in one pixel share its colour under the first one's label.
              if (!s.hit || !lens->sampled[static_cast<size_t>(s.drop)]) return;
              ++hits;
              if (first < 0) first = s.drop;
              sum += lifted_linear(s, lift);  // as the reference averages its rays
            };
            if (lens_lanes) {
              // One focus point per pixel: the drops its cone meets hold every drop its rays can
              // meet (ApertureReach), in the lanes where there are few; the samples taken in the
              // rays' order, as trace_rays hands them over.
              const glm::dvec3 focus = focus_point(x, y, 0, order);
              lens_reach->near_drops(lens_boxes[y], x, focus, &near);
              if (near.empty()) {
                label[x] = -1;  // no ray meets a drop
                continue;
              }
              asked.clear();
              lens_disk_points(x, y, kl, radius, lens_points.data());  // rays == kl^2 here
              for (int sample = 0; sample < rays; ++sample) {
                origins[sample] = glm::dvec3(lens_points[sample].x, lens_points[sample].y, 0.0);
                dirs[sample] = focus - origins[sample];
                asked.push_back(sample);
              }
              const RaysTraced traced =
                  trace_pixel_rays(lens_kernel, near.size() <= kMaxDropsInLanes ? &*lanes : nullptr, near,
                                   origins.data(), dirs.data(), &asked, &scratch, seen_by.data());
              n_lanes += traced.in_lanes;
              for (int sample = 0; sample < rays; ++sample) take(seen_by[sample]);
            } else {
              lens_kernel.trace_rays(
                  rays,
                  [&](int sample, glm::dvec3* origin, glm::dvec3* dir) {
                    *origin = lens_origin(x, y, sample);
                    *dir = focus_point(x, y, sample, order) - *origin;
                  },
                  [&](int, const glm::dvec3&, const Sample& s) { take(s); });
            }
            if (hits == 0) {
              label[x] = -1;
              continue;
            }
            if (label[x] < 0) label[x] = first;
            // Stored as the trace stores colours (sRGB, unlifted): the composite decodes and lifts
            // them again.
            double mean[3] = {sum[0] / hits, sum[1] / hits, sum[2] / hits};
            lift.restore(mean);
            for (int c = 0; c < 3; ++c) rgb[x][c] = static_cast<float>(linear_to_srgb(mean[c]));
            cov[x] = static_cast<float>(hits) / static_cast<float>(rays);
          }
        }
      }
      lens_sampled += n_sampled;
      lens_lane_rays += n_lanes;
    });
    out.stats.lens_lane_rays = lens_lane_rays;
    // Pixels next to a drop may have joined it.
    if (out.drop_box.area() > 0)
      out.drop_box = cv::Rect(out.drop_box.x - 1, out.drop_box.y - 1, out.drop_box.width + 2, out.drop_box.height + 2) &
                     cv::Rect(0, 0, camera.width, camera.height);
  }

  out.stats.candidate_pixels = candidates;
  out.stats.drop_pixels = drops;
  out.stats.dark_band_pixels = dark;
  out.stats.off_frame_pixels = off;
  out.stats.supersampled_pixels = supersampled;
  out.stats.aliasing_pixels = aliasing;
  out.stats.smooth_pixels = smooth;
  out.stats.lockstep_pixels = lockstep;
  out.stats.lane_pixels = in_lanes;
  out.stats.lens_sampled_pixels = lens_sampled;
  return out;
}

// The aperture reference: every pixel near a drop averages rays from a stratified grid of
// points on the lens disk, each aimed at the pixel's point on the plane of focus (z = F) and
// traced through the drops. Focused on the background (F = T), a ray that meets no drop lands
// exactly on the pixel's own point, so it sees the pixel's own clean colour. Focused elsewhere
// (`street`: the background's circle reaches half a pixel), it lands wherever its line meets
// z = T, and every pixel of the frame, near a drop or not, averages what its rays see there:
// the street's defocus follows from the rays, and the average of the rays alone is the clean
// image (ApertureResult::clean_linear).
template <bool kFresnel, bool kDispersion>
ApertureResult run_aperture(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                            const SceneSample& scene, const DropAccel& accel, int samples, const EffectPlan* plan,
                            const TraceStrategy& strategy, bool street, int margin) {
  const Kernel<kFresnel, kDispersion> kernel(clean, camera, config, scene, accel, plan, strategy.lockstep, margin);
  ApertureResult out;
  out.linear = cv::Mat(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  out.coverage = cv::Mat(camera.height, camera.width, CV_32F, cv::Scalar(0));
  const auto& lin = srgb8_to_linear_table();
  const HighlightLift& lift = scene.highlights;
  const int k = std::max(1, static_cast<int>(std::lround(std::sqrt(samples))));
  const double radius = 0.5 * scene.aperture_cm();
  // Pixels whose aperture cone can meet a drop: each drop's candidate box (ApertureReach), within
  // which the pixels and rays that cannot meet are culled: the rest would find none, and give
  // what an untraced pixel gives.
  const std::vector<Drop>& drops = accel.drops();
  const ApertureReach reach(drops, radius, scene.focus_cm());
  const std::vector<std::vector<DropSpan>> row_drops = ApertureReach::candidate_boxes(camera, scene, drops);
  std::vector<std::vector<Span>> rows(camera.height);
  for (int y = 0; y < camera.height; ++y) {
    for (const DropSpan& b : row_drops[y]) rows[y].push_back({b.first, b.last});
    merge_spans(rows[y]);
  }
  const double T = scene.background_distance_cm;
  const double F = scene.focus_cm();
  // The street a ray from lens point o through `focus` (z = F) meets on the plane z = T: the
  // frame in linear light (lifted), each pixel a square of constant light (the nearest pixel: a
  // bilinear look-up would add a blur of its own, widening a traced circle to about
  // sqrt(coc^2 + 8/3) px; over the disk, square pixels average to the fast path's antialiased
  // disk weights), continued past its edges as the border mode says (the fast path's defocus pads
  // the frame the same way).
  cv::Mat street_linear;
  if (street) {
    street_linear = lifted_linear(clean, lift);
    out.clean_linear = cv::Mat(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  }
  const BackgroundSampler& bg = kernel.background();
  auto street_seen = [&](const glm::dvec3& o, const glm::dvec3& focus) {
    const glm::dvec2 xy = camera.project(o + (T / F) * (focus - o));
    const int x = std::min(static_cast<int>(bg.fold(xy.x, camera.width) + 0.5), camera.width - 1);
    const int y = std::min(static_cast<int>(bg.fold(xy.y, camera.height) + 0.5), camera.height - 1);
    const cv::Vec3f& c = street_linear.at<cv::Vec3f>(y, x);
    return glm::dvec3(c[0], c[1], c[2]);
  };
  auto to_vec3f = [](const glm::dvec3& v) {
    return cv::Vec3f(static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z));
  };
  // A pixel's rays that take the common path traced in SIMD lanes (pinhole_lanes.h), as the
  // pinhole pass's are: the same bits.
  std::optional<PinholeLanes> lanes;
  if constexpr (!kDispersion) {
    if (strategy.lanes && kernel.lockstep() && PinholeLanes::applies(accel))
      lanes.emplace(camera, accel, scene.glass, scene.background_distance_cm, config.channel_indices().y, config.tir,
                    kFresnel);
  }
  std::atomic<std::int64_t> lockstep{0}, traced_rays{0}, lane_rays_traced{0};
  const int n = k * k;
  tbb::parallel_for(tbb::blocked_range<int>(0, camera.height, 4), [&](const tbb::blocked_range<int>& r) {
    std::int64_t n_lock = 0, n_traced = 0, n_lanes = 0;
    LaneScratch scratch;
    std::vector<int> near;  // the drops a pixel's cone can meet
    std::vector<glm::dvec3> origins(n), dirs(n);
    std::vector<int> asked;  // the rays that can meet one of them
    std::vector<Sample> seen_by(n);
    std::vector<glm::dvec2> lens(n);  // a pixel's lens points, sample = j k + i
    // A pixel none of whose rays meets a drop, off the background's focus: the street its rays
    // see, averaged (the rays' street, as a traced pixel averages it).
    const auto street_alone = [&](int x, int y, cv::Vec3f* rgb, cv::Vec3f* clean_rgb) {
      const glm::dvec3 focus = F * camera.ray_direction(x, y);
      glm::dvec3 sum(0.0);
      lens_disk_points(x, y, k, radius, lens.data());
      for (int sample = 0; sample < n; ++sample) sum += street_seen(glm::dvec3(lens[sample].x, lens[sample].y, 0.0), focus);
      *rgb = *clean_rgb = to_vec3f(sum / static_cast<double>(n));
    };
    for (int y = r.begin(); y < r.end(); ++y) {
      auto* out_rgb = out.linear.ptr<cv::Vec3f>(y);
      auto* out_cov = out.coverage.ptr<float>(y);
      const auto* src = clean.ptr<cv::Vec3b>(y);
      auto* out_clean = street ? out.clean_linear.ptr<cv::Vec3f>(y) : nullptr;
      // Off the background's focus, the pixels no drop's cone reaches see the street alone (the
      // others, below, average their rays' street beside their traced colour).
      if (street) {
        std::size_t span = 0;
        for (int x = 0; x < camera.width; ++x) {
          while (span < rows[y].size() && rows[y][span].second < x) ++span;
          if (span < rows[y].size() && rows[y][span].first <= x) continue;  // near a drop
          street_alone(x, y, &out_rgb[x], &out_clean[x]);
        }
      }
      const std::vector<DropSpan>& boxes_here = row_drops[y];
      for (const auto& [x0, x1] : rows[y]) {
        for (int x = x0; x <= x1; ++x) {
          const glm::dvec3 focus = F * camera.ray_direction(x, y);
          if (strategy.cull) {
            reach.near_drops(boxes_here, x, focus, &near);
          } else {
            near.clear();
            for (const DropSpan& b : boxes_here)
              if (b.first <= x && x <= b.last) near.push_back(b.drop);
          }
          if (near.empty()) {
            if (street) street_alone(x, y, &out_rgb[x], &out_clean[x]);
            continue;
          }
          // The rays, and which of them can meet a drop: in the lanes, all of them (the lanes'
          // closed form is the test); else each tested against the few drops its pixel's cone
          // meets (past a few, every ray goes to Embree's query).
          asked.clear();
          const bool in_lanes = lanes && near.size() <= kMaxDropsInLanes;
          const bool test_rays = strategy.cull && !in_lanes && near.size() <= kMaxDropsTestedPerRay;
          lens_disk_points(x, y, k, radius, lens.data());
          for (int sample = 0; sample < n; ++sample) {
            origins[sample] = glm::dvec3(lens[sample].x, lens[sample].y, 0.0);
            dirs[sample] = focus - origins[sample];
            bool can = !test_rays;
            for (size_t j = 0; j < near.size() && !can; ++j) can = reach.ray_meets(near[j], origins[sample], dirs[sample]);
            if (can) {
              asked.push_back(sample);
            } else {
              set_miss(&seen_by[sample]);
            }
          }
          n_traced += static_cast<std::int64_t>(asked.size());
          const RaysTraced traced = trace_pixel_rays(kernel, in_lanes ? &*lanes : nullptr, near, origins.data(),
                                                     dirs.data(), &asked, &scratch, seen_by.data());
          n_lock += traced.side_by_side;
          n_lanes += traced.in_lanes;
          float own_rgb[3] = {lin[src[x][0]], lin[src[x][1]], lin[src[x][2]]};
          lift.apply(own_rgb);  // what the pixel's clipped bytes stood for (highlights.h)
          const glm::dvec3 own(own_rgb[0], own_rgb[1], own_rgb[2]);
          glm::dvec3 sum(0.0), street_sum(0.0);
          int hits = 0;
          // In the rays' order, whichever were traced: the same sums as tracing them all.
          for (int sample = 0; sample < n; ++sample) {
            const Sample& s = seen_by[sample];
            // The street this ray would see without drops: the clean image's, and the rainy
            // image's where the ray meets no drop.
            glm::dvec3 seen = own;
            if (street) {
              seen = street_seen(origins[sample], focus);
              street_sum += seen;
            }
            if (!s.hit) {
              sum += seen;
              continue;
            }
            ++hits;
            sum += lifted_linear(s, lift);
          }
          if (street) out_clean[x] = to_vec3f(street_sum / static_cast<double>(n));
          if (hits == 0) {
            if (street) out_rgb[x] = out_clean[x];
            continue;
          }
          out_rgb[x] = to_vec3f(sum / static_cast<double>(n));
          out_cov[x] = static_cast<float>(hits) / static_cast<float>(n);
        }
      }
    }
    lockstep += n_lock;
    traced_rays += n_traced;
    lane_rays_traced += n_lanes;
  });
  out.traced_rays = traced_rays;
  out.lane_rays = lane_rays_traced;
  out.lockstep_rays = lockstep;
  return out;
}

}  // namespace

ApertureResult trace_aperture(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                              const SceneSample& scene, const DropAccel& accel, int samples, const EffectPlan* plan,
                              const TraceStrategy& strategy, int margin) {
  CV_Assert(clean.type() == CV_8UC3 && clean.cols == camera.width && clean.rows == camera.height);
  const bool fresnel = config.fresnel.enabled;
  const bool dispersion = plan ? plan->dispersion_anywhere(config) : config.dispersion.enabled;
  const bool street = scene.background_coc_px(camera.fx) >= kMinVisibleCocPx;
  if (fresnel && dispersion)
    return run_aperture<true, true>(clean, camera, config, scene, accel, samples, plan, strategy, street, margin);
  if (fresnel) return run_aperture<true, false>(clean, camera, config, scene, accel, samples, plan, strategy, street, margin);
  if (dispersion) return run_aperture<false, true>(clean, camera, config, scene, accel, samples, plan, strategy, street, margin);
  return run_aperture<false, false>(clean, camera, config, scene, accel, samples, plan, strategy, street, margin);
}

TraceResult trace_drops(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                        const SceneSample& scene, const DropAccel& accel, const EffectPlan* plan,
                        const TraceStrategy& strategy, const LensTrace* lens) {
  CV_Assert(clean.type() == CV_8UC3 && clean.cols == camera.width && clean.rows == camera.height);
  // Effects pick the kernel instantiation once per frame, not per pixel: a frame where auto
  // finds no drop that needs dispersion runs the kernel without it.
  const bool fresnel = config.fresnel.enabled;
  const bool dispersion = plan ? plan->dispersion_anywhere(config) : config.dispersion.enabled;
  if (fresnel && dispersion) return run<true, true>(clean, camera, config, scene, accel, plan, strategy, lens);
  if (fresnel) return run<true, false>(clean, camera, config, scene, accel, plan, strategy, lens);
  if (dispersion) return run<false, true>(clean, camera, config, scene, accel, plan, strategy, lens);
  return run<false, false>(clean, camera, config, scene, accel, plan, strategy, lens);
}

}  // namespace raindrop

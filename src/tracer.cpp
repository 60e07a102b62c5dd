#include "raindrop/tracer.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "raindrop/background.h"
#include "raindrop/optics.h"

namespace raindrop {
namespace {

constexpr int kMaxEvents = 16;  // surface crossings/reflections followed before giving up

template <bool kFresnel>
DropPath trace_path(const glm::dvec3& origin, const glm::dvec3& dir0, double n_water, TirMode tir,
                    const DropAccel& accel, const GlassPlane& glass) {
  DropPath path;
  glm::dvec3 o = origin, d = glm::normalize(dir0);
  DropHit current;
  bool on_surface = false, inside = false;
  for (int event = 0; event < kMaxEvents; ++event) {
    const auto hit = accel.intersect(o, d, on_surface ? &current : nullptr);
    if (!hit) break;
    ++path.events;
    if (!path.hit) {
      path.hit = true;
      path.first_drop = hit->drop;
    }
    const bool entering = glm::dot(d, hit->normal) < 0;
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
  path.escaped_in = path.hit && glm::dot(d, glass.normal()) <= 0;
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
  return fresnel ? trace_path<true>(origin, dir, n_water, tir, accel, glass)
                 : trace_path<false>(origin, dir, n_water, tir, accel, glass);
}

namespace {

struct Sample {
  bool hit = false;
  int drop = -1;
  bool dark = false;
  bool off_frame = false;
  glm::dvec3 rgb{0};
};

template <bool kFresnel, bool kDispersion>
class Kernel {
 public:
  Kernel(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
         const SceneSample& scene, const DropAccel& accel)
      : bg_(clean, config.border),
        camera_(camera),
        scene_(scene),
        accel_(accel),
        tir_(config.tir),
        interior_(config.fresnel.enabled ? config.fresnel.interior_rgb : glm::dvec3(0.0)),
        n_rgb_(config.channel_indices()) {}

  Sample sample(double px, double py) const {
    const glm::dvec3 dir = camera_.ray_direction(px, py);
    Sample s;
    if constexpr (!kDispersion) {
      const DropPath p = trace_path<kFresnel>(glm::dvec3(0.0), dir, n_rgb_.y, tir_, accel_, scene_.glass);
      s.hit = p.hit;
      if (!s.hit) return s;
      s.drop = p.first_drop;
      s.dark = p.dark;
      s.rgb = shade(p, &s.off_frame);
    } else {
      // One path per colour channel: the green path decides hit and drop (all three meet the
      // same first surface, whose position does not depend on the index).
      for (int c = 0; c < 3; ++c) {
        const DropPath p = trace_path<kFresnel>(glm::dvec3(0.0), dir, n_rgb_[c], tir_, accel_, scene_.glass);
        if (!p.hit) return s;  // same first hit for every channel
        bool off = false;
        s.rgb[c] = shade(p, &off)[c];
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

  glm::dvec3 clean_pixel(int x, int y) const { return bg_.pixel(x, y); }

 private:
  glm::dvec3 shade(const DropPath& p, bool* off_frame) const {
    if (p.dark) return glm::dvec3(0.0);
    glm::dvec3 seen;
    if (p.escaped_in) {
      seen = interior_;
    } else {
      const glm::dvec2 xy = background_pixel(p, camera_, scene_.background_distance_cm);
      *off_frame = !bg_.inside(xy.x, xy.y);
      seen = bg_.sample(xy.x, xy.y);
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
  const DropAccel& accel_;
  TirMode tir_;
  glm::dvec3 interior_;
  glm::dvec3 n_rgb_;
};

// Per image row, the merged x-intervals covered by some drop's screen-space bounds.
std::vector<std::vector<std::pair<int, int>>> candidate_spans(const Camera& camera,
                                                              const DropAccel& accel) {
  std::vector<std::vector<std::pair<int, int>>> rows(camera.height);
  for (const Drop& drop : accel.drops()) {
    glm::dvec3 lo, hi;
    drop.bounds(&lo, &hi);
    if (hi.z <= 1e-9) continue;  // entirely behind the camera
    // Corners of the box; a corner behind the camera makes the projection unbounded, so the
    // whole frame width/height is taken on that side.
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    bool behind = false;
    for (int i = 0; i < 8; ++i) {
      const glm::dvec3 p{(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z};
      if (p.z <= 1e-9) {
        behind = true;
        continue;
      }
      const glm::dvec2 q = camera.project(p);
      x0 = std::min(x0, q.x);
      x1 = std::max(x1, q.x);
      y0 = std::min(y0, q.y);
      y1 = std::max(y1, q.y);
    }
    if (behind) {
      x0 = y0 = -1e300;
      x1 = y1 = 1e300;
    }
    const int ix0 = static_cast<int>(std::max(0.0, std::floor(x0)));
    const int ix1 = static_cast<int>(std::min(camera.width - 1.0, std::ceil(x1)));
    const int iy0 = static_cast<int>(std::max(0.0, std::floor(y0)));
    const int iy1 = static_cast<int>(std::min(camera.height - 1.0, std::ceil(y1)));
    for (int y = iy0; y <= iy1 && ix0 <= ix1; ++y) rows[y].push_back({ix0, ix1});
  }
  for (auto& spans : rows) {
    std::sort(spans.begin(), spans.end());
    std::vector<std::pair<int, int>> merged;
    for (const auto& s : spans) {
      if (!merged.empty() && s.first <= merged.back().second + 1) {
        merged.back().second = std::max(merged.back().second, s.second);
      } else {
        merged.push_back(s);
      }
    }
    spans = std::move(merged);
  }
  return rows;
}

// Label used to find edges: drop index, with dark-band pixels distinguished.
inline int edge_class(int label, bool dark) { return label < 0 ? -1 : 2 * label + (dark ? 1 : 0); }

template <bool kFresnel, bool kDispersion>
TraceResult run(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                const SceneSample& scene, const DropAccel& accel) {
  const Kernel<kFresnel, kDispersion> kernel(clean, camera, config, scene, accel);
  TraceResult out;
  out.label = cv::Mat(camera.height, camera.width, CV_32S, cv::Scalar(-1));
  out.color = cv::Mat(camera.height, camera.width, CV_32FC3);
  cv::Mat classes(camera.height, camera.width, CV_32S, cv::Scalar(-1));
  const auto spans = candidate_spans(camera, accel);
  std::atomic<std::int64_t> candidates{0}, drops{0}, dark{0}, off{0}, supersampled{0};

  // Pass 1: one ray through every candidate pixel's centre.
  tbb::parallel_for(tbb::blocked_range<int>(0, camera.height, 8), [&](const tbb::blocked_range<int>& r) {
    std::int64_t n_cand = 0, n_drop = 0, n_dark = 0, n_off = 0;
    for (int y = r.begin(); y < r.end(); ++y) {
      auto* label = out.label.ptr<int>(y);
      auto* cls = classes.ptr<int>(y);
      auto* rgb = out.color.ptr<cv::Vec3f>(y);
      for (const auto& [x0, x1] : spans[y]) {
        for (int x = x0; x <= x1; ++x) {
          ++n_cand;
          const Sample s = kernel.sample(x, y);
          if (!s.hit) continue;
          ++n_drop;
          n_dark += s.dark;
          n_off += s.off_frame;
          label[x] = s.drop;
          cls[x] = edge_class(s.drop, s.dark);
          rgb[x] = cv::Vec3f(static_cast<float>(s.rgb.x), static_cast<float>(s.rgb.y),
                             static_cast<float>(s.rgb.z));
        }
      }
    }
    candidates += n_cand;
    drops += n_drop;
    dark += n_dark;
    off += n_off;
  });

  // Pass 2: supersample drop pixels on an edge (a neighbour of another class: outside, other
  // drop, dark band) or all drop pixels, on a stratified k x k grid. The mask stays the
  // pixel-centre rule; sub-samples that miss every drop see the clean pixel.
  const int k = static_cast<int>(std::lround(std::sqrt(config.samples_per_pixel)));
  if (k > 1) {
    tbb::parallel_for(tbb::blocked_range<int>(0, camera.height, 8), [&](const tbb::blocked_range<int>& r) {
      std::int64_t n_ss = 0;
      for (int y = r.begin(); y < r.end(); ++y) {
        const int* label = out.label.ptr<int>(y);
        auto* rgb = out.color.ptr<cv::Vec3f>(y);
        for (const auto& [x0, x1] : spans[y]) {
          for (int x = x0; x <= x1; ++x) {
            if (label[x] < 0) continue;
            if (config.supersample_edges_only) {
              const int own = classes.at<int>(y, x);
              bool edge = false;
              for (int dy = -1; dy <= 1 && !edge; ++dy) {
                for (int dx = -1; dx <= 1 && !edge; ++dx) {
                  const int yy = y + dy, xx = x + dx;
                  if (yy < 0 || xx < 0 || yy >= camera.height || xx >= camera.width) continue;
                  edge = classes.at<int>(yy, xx) != own;
                }
              }
              if (!edge) continue;
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
    });
  }

  out.stats.candidate_pixels = candidates;
  out.stats.drop_pixels = drops;
  out.stats.dark_band_pixels = dark;
  out.stats.off_frame_pixels = off;
  out.stats.supersampled_pixels = supersampled;
  return out;
}

}  // namespace

TraceResult trace_drops(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                        const SceneSample& scene, const DropAccel& accel) {
  CV_Assert(clean.type() == CV_8UC3 && clean.cols == camera.width && clean.rows == camera.height);
  // Effects pick the kernel instantiation once per frame, not per pixel.
  const bool fresnel = config.fresnel.enabled, dispersion = config.dispersion.enabled;
  if (fresnel && dispersion) return run<true, true>(clean, camera, config, scene, accel);
  if (fresnel) return run<true, false>(clean, camera, config, scene, accel);
  if (dispersion) return run<false, true>(clean, camera, config, scene, accel);
  return run<false, false>(clean, camera, config, scene, accel);
}

}  // namespace raindrop

#pragma once
// Traces the camera rays that can reach a drop through the drops to the background plane.
//
// A ray that meets no drop keeps its background pixel. One that does is refracted at every
// water surface it crosses (Snell, n = 1.333; normally the flat base, then the cap); where
// the ray inside the water meets the cap beyond the critical angle it is totally internally
// reflected and, as in the paper, the pixel is black: the dark band. The ray that leaves
// the drop is intersected with the background plane z = T and that point is projected back
// through the camera to a background pixel (bilinear).
//
// Only pixels inside the screen-space bounds of some drop are traced. Effects: Fresnel
// transmission and dispersion are template parameters of the per-pixel kernel, so a scene
// without them runs code that does not contain them.
#include <cstdint>
#include <utility>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <opencv2/core.hpp>

#include "raindrop/render/camera.h"
#include "raindrop/render/drop_accel.h"
#include "raindrop/render/effect_policy.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/scene_config.h"
#include "raindrop/render/spans.h"

namespace raindrop {

struct TraceStats {
  std::int64_t candidate_pixels = 0;   // pixels whose rays were traced
  std::int64_t drop_pixels = 0;        // of those, rays that met a drop (the mask)
  std::int64_t dark_band_pixels = 0;   // total internal reflection painted black
  std::int64_t off_frame_pixels = 0;   // background sample fell outside the frame
  std::int64_t supersampled_pixels = 0;
  // Supersample auto: inside pixels supersampled because their single sample aliases, and
  // those left at one sample (effect_policy.h).
  std::int64_t aliasing_pixels = 0;
  std::int64_t smooth_pixels = 0;
  std::int64_t lockstep_pixels = 0;  // camera rays traced side by side (TraceStrategy::lockstep)
};

struct TraceResult {
  cv::Mat label;  // CV_32S: -1 where no drop is met, else the index of the first drop met
  cv::Mat color;  // CV_32FC3 RGB in [0, 1]: the traced colour where label >= 0
  TraceStats stats;
  // Per row, the x-intervals that were traced (label is -1 everywhere else), and the
  // bounding box of the drop pixels: later passes visit only these.
  std::vector<std::vector<Span>> spans;
  cv::Rect drop_box;
};

// The path of one ray through the drops.
struct DropPath {
  bool hit = false;         // met a drop at all (a camera ray: the pixel is in the mask)
  int first_drop = -1;
  bool dark = false;        // ended in total internal reflection painted black, or trapped
  bool escaped_in = false;  // left the water heading back through the glass (car interior)
  double transmittance = 1; // product of Fresnel transmittances (1 without Fresnel)
  int events = 0;           // surface crossings and reflections
  glm::dvec3 origin{0}, dir{0};  // the ray leaving the last surface (unit direction)
};

// Follows origin + t * dir (t > 0) through the drops with refractive index n_water.
DropPath trace_through_drops(const glm::dvec3& origin, const glm::dvec3& dir, double n_water, TirMode tir,
                             bool fresnel, const DropAccel& accel, const GlassPlane& glass);

// Continuous image coordinates of the background point seen along a path's exit ray (the
// background plane is z = background_z); rays that never reach it are followed to infinity.
glm::dvec2 background_pixel(const DropPath& path, const Camera& camera, double background_z);

// How trace_drops and trace_aperture schedule their work; every choice gives the same result
// to the bit (tests hold them to each other).
struct TraceStrategy {
  // Camera rays (and a pixel's aperture rays, trace_aperture) that go in through one drop's
  // base and out through its cap traced 8 side by side, a step at a time (disjoint drops
  // only): their chains of square roots and divisions overlap instead of waiting on each
  // other. Off: every ray is traced alone after its first query (trace_drops still asks the
  // camera rays' first queries as Embree packets; trace_aperture asks one query per ray).
  bool lockstep = true;
};

// `clean` is the frame (CV_8UC3, RGB); `accel` holds the scene's drops. `plan`: the effects
// chosen per drop where the scene says "auto" (effect_policy.h); without one, every effect
// the scene names is simulated for every drop.
TraceResult trace_drops(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                        const SceneSample& scene, const DropAccel& accel, const EffectPlan* plan = nullptr,
                        const TraceStrategy& strategy = {});

// The thin-lens reference (SceneConfig::lens, method Aperture): `samples` rays per pixel
// from points spread over the aperture disk, focused on the scene's plane of focus. Where the
// background's own circle of confusion reaches half a pixel (focus off it), every pixel is
// traced, and the rays' view without drops is returned as the clean image.
struct ApertureResult {
  cv::Mat linear;        // CV_32FC3 linear RGB, where coverage > 0 (zero elsewhere; everywhere with clean_linear)
  cv::Mat coverage;      // CV_32F: the fraction of the aperture's rays that met a drop
  cv::Mat clean_linear;  // CV_32FC3 linear RGB of the street alone, focus off it; else empty
  std::int64_t lockstep_rays = 0;  // rays traced side by side (TraceStrategy::lockstep)
};
ApertureResult trace_aperture(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                              const SceneSample& scene, const DropAccel& accel, int samples,
                              const EffectPlan* plan = nullptr, const TraceStrategy& strategy = {});

}  // namespace raindrop

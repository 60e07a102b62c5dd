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
  std::int64_t lane_pixels = 0;      // of those, in SIMD lanes (TraceStrategy::lanes)
  std::int64_t lens_sampled_pixels = 0;  // pixels that averaged rays from the lens disk (LensTrace)
  std::int64_t lens_lane_rays = 0;       // of their rays, those that met a drop on its common path in SIMD lanes (TraceStrategy::lanes)
};

struct TraceResult {
  cv::Mat label;  // CV_32S: -1 where no drop is met, else the index of the first drop met
  cv::Mat color;  // CV_32FC3 RGB in [0, 1]: the traced colour where label >= 0
  // CV_32F: the fraction of the pixel's rays that met a drop where label >= 0, with sampled drops
  // (1 at the pixels it did not sample); empty without it (1 wherever label >= 0).
  cv::Mat coverage;
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

// Per image row, the pixels whose camera rays can reach each drop: one span per drop and row
// where its image (a conservative hull of it) covers the row. The pinhole trace's candidates
// are their union; exposed for tests.
std::vector<std::vector<DropSpan>> drop_candidate_spans(const Camera& camera, const DropAccel& accel);

// How trace_drops and trace_aperture schedule their work; every choice gives the same result
// to the bit (tests hold them to each other).
struct TraceStrategy {
  // Camera rays (and a pixel's aperture rays, trace_aperture) that go in through one drop's
  // base and out through its cap traced 8 side by side, a step at a time (disjoint drops
  // only): their chains of square roots and divisions overlap instead of waiting on each
  // other. Off: every ray is traced alone after its first query (trace_drops still asks the
  // camera rays' first queries as Embree packets; trace_aperture asks one query per ray).
  bool lockstep = true;
  // With lockstep, the pinhole pass's camera rays traced in SIMD lanes a drop at a time, and
  // the aperture reference's rays a pixel at a time (pinhole_lanes.h; exact disjoint caps of
  // circular outline, no dispersion).
  bool lanes = true;
  // The aperture reference's pixels and rays that cannot meet a drop (aperture_reach.h) left
  // untraced: what they would give is known. Off: every ray of every pixel near a drop traced.
  bool cull = true;
};

// What the thin-lens camera's layered path (renderer.cpp) adds to the pinhole trace.
//
// `margin`: `clean` is the frame widened by this many pixels on every side (the border mode's
// continuation of it), so that rays leaving the frame see the frame's continuation and the sky
// above it wherever the image's edge lies (BackgroundSampler::set_margin).
//
// `sampled`: drops in focus seen through a real aperture. A drop whose circle of confusion is
// under half a pixel keeps its outline where the pinhole puts it, but not what it shows inside:
// a drop shows the street minified many times, so rays that spread over a fraction of a pixel
// on the glass still see a wide patch of that view, and near the rim some of a pixel's rays are
// turned back by total internal reflection while others are not. The pixels on and next to
// these drops average `samples` rays from the lens disk (the aperture reference's stratified
// points) through their point on the plane of focus (spread over the pixel's square too where
// the scene supersamples k x k: then lcm(samples, k^2) rays), each traced to the sharp street (`sharp`,
// widened like `clean`; null: `clean` is sharp), as the reference traces them: the spread of
// the rays is the street's blur there. Their colour is the mean, in linear light, of the rays
// that met a drop, their coverage the fraction that did (TraceResult::coverage); a pixel none of
// whose rays met one leaves the drop. A ray that misses stands for the pixel's own (defocused)
// street, which the layered composite mixes in by coverage.
struct LensTrace {
  int margin = 0;
  std::vector<char> sampled;  // per drop of the accel: sampled through the aperture
  int samples = 16;           // per pixel (a square number: a k x k stratified grid on the disk)
  const cv::Mat* sharp = nullptr;
  bool any_sampled() const {
    for (char d : sampled)
      if (d) return true;
    return false;
  }
};

// `clean` is the frame (CV_8UC3, RGB); `accel` holds the scene's drops. `plan`: the effects
// chosen per drop where the scene says "auto" (effect_policy.h); without one, every effect
// the scene names is simulated for every drop. `lens`: the thin-lens camera's margin and
// sampled drops (none without it).
TraceResult trace_drops(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                        const SceneSample& scene, const DropAccel& accel, const EffectPlan* plan = nullptr,
                        const TraceStrategy& strategy = {}, const LensTrace* lens = nullptr);

// The thin-lens reference (SceneConfig::lens, method Aperture): `samples` rays per pixel
// from points spread over the aperture disk, focused on the scene's plane of focus. Where the
// background's own circle of confusion reaches half a pixel (focus off it), every pixel is
// traced, and the rays' view without drops is returned as the clean image.
struct ApertureResult {
  cv::Mat linear;        // CV_32FC3 linear RGB, where coverage > 0 (zero elsewhere; everywhere with clean_linear)
  cv::Mat coverage;      // CV_32F: the fraction of the aperture's rays that met a drop
  cv::Mat clean_linear;  // CV_32FC3 linear RGB of the street alone, focus off it; else empty
  std::int64_t lockstep_rays = 0;  // rays traced side by side (TraceStrategy::lockstep)
  std::int64_t traced_rays = 0;    // rays traced at all (the others cannot meet a drop: aperture_reach.h)
  std::int64_t lane_rays = 0;      // of those, the ones that met a drop and took its common path in SIMD lanes
                                   // (TraceStrategy::lanes; rays the lanes found missing every drop are not counted)
};
// `margin`: as LensTrace's.
ApertureResult trace_aperture(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                              const SceneSample& scene, const DropAccel& accel, int samples,
                              const EffectPlan* plan = nullptr, const TraceStrategy& strategy = {}, int margin = 0);

}  // namespace raindrop

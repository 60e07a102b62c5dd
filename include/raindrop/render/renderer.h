#pragma once
// One frame, start to finish, in memory: drops -> Embree scene -> trace -> blur -> 8-bit
// rainy image and 0/255 mask. No I/O; used by the CLI, the benchmark and the tests.
#include <vector>

#include <opencv2/core.hpp>

#include "raindrop/render/camera.h"
#include "raindrop/render/effect_policy.h"
#include "raindrop/render/scene.h"
#include "raindrop/render/scene_config.h"
#include "raindrop/render/tracer.h"

namespace raindrop {

struct FrameTimings {
  double background_ms = 0;  // the street defocused, where focus is off it (background_defocus.h)
  double accel_ms = 0;       // building the Embree scene
  double trace_ms = 0;
  double blur_ms = 0;
  double compose_ms = 0;  // 8-bit rainy image and mask
  double core_ms() const { return background_ms + accel_ms + trace_ms + blur_ms + compose_ms; }
};

struct RenderedFrame {
  cv::Mat rainy;  // CV_8UC3 RGB; equal to clean_or(input) wherever mask == 0
  cv::Mat mask;   // CV_8UC1, 0 or 255
  // With a thin-lens camera: the fraction of the aperture that sees a drop (CV_32F), the
  // mask being coverage >= the scene's mask_threshold; and each drop's circle of confusion
  // in pixels (0 where it is too small to see). Empty for a pinhole camera.
  cv::Mat alpha;
  std::vector<double> coc_px;
  // The camera's view without drops where it differs from the input: the background out of
  // focus (background_defocus.h). Empty where the input is that view (focus on the background,
  // or its circle under half a pixel). The clean image to write is clean_or(input).
  cv::Mat clean;
  const cv::Mat& clean_or(const cv::Mat& input) const { return clean.empty() ? input : clean; }
  bool defocused = false;  // the lens path ran (false: pinhole, or every circle < 0.5 px)
  // Drops in focus traced through the aperture (circles under half a pixel whose spread shows:
  // defocus.h, traced_through_aperture): by the layered path's LensTrace, or by the reference,
  // which traces every drop so.
  bool lens_sampled = false;
  int lens_sampled_drops = 0;
  // The highlights' lift ran (false: off, not defocused, or no pixel reached its threshold).
  bool highlights_lifted = false;
  EffectPlan effects;      // what the scene's "auto" effects decided, per drop
  TraceStats stats;
  FrameTimings timings;
  double coverage() const;  // fraction of mask pixels
};

// `clean`: CV_8UC3 RGB at the camera's size. Runs on the calling thread's TBB arena.
RenderedFrame render_frame(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                           const SceneSample& scene);

}  // namespace raindrop

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

#include <opencv2/core.hpp>

#include "raindrop/camera.h"
#include "raindrop/drop_accel.h"
#include "raindrop/scene.h"
#include "raindrop/scene_config.h"

namespace raindrop {

struct TraceStats {
  std::int64_t candidate_pixels = 0;   // pixels whose rays were traced
  std::int64_t drop_pixels = 0;        // of those, rays that met a drop (the mask)
  std::int64_t dark_band_pixels = 0;   // total internal reflection painted black
  std::int64_t off_frame_pixels = 0;   // background sample fell outside the frame
  std::int64_t supersampled_pixels = 0;
};

struct TraceResult {
  cv::Mat label;  // CV_32S: -1 where no drop is met, else the index of the first drop met
  cv::Mat color;  // CV_32FC3 RGB in [0, 1]: the traced colour where label >= 0
  TraceStats stats;
};

// `clean` is the frame (CV_8UC3, RGB); `accel` holds the scene's drops.
TraceResult trace_drops(const cv::Mat& clean, const Camera& camera, const SceneConfig& config,
                        const SceneSample& scene, const DropAccel& accel);

}  // namespace raindrop

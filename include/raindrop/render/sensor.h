#pragma once
// What the camera adds after the optics, to the rainy image only: sensor noise and JPEG
// compression (scene effect "sensor", off unless the scene names it).
//
// A real rainy photograph carries both over its drops as over everything else: the camera
// adds them after the light has passed the glass. A render without them has drops that are
// smoother than their surround (the drops blur the frame's own noise away), a cue no real
// photograph offers (docs/RESULTS.md 4.5). The clean image, the target a model learns to
// restore, stays as it was; so does the mask.
//
// Noise: independent Gaussian noise per pixel and channel on the 8-bit values, sigma drawn per
// sample from the scene's range (levels of 8 bits), rounded and clipped as a camera's
// quantiser does. Signal-independent (read noise); a shot-noise term is not modelled.
// JPEG: the noisy image encoded and decoded at a quality drawn per sample (libjpeg's scale,
// 1-100, in memory through libjpeg with 4:2:0 chroma, as OpenImageIO would), so that a model sees the block edges and ringing of a
// compressed photograph.
#include <cstdint>

#include <opencv2/core.hpp>

#include "raindrop/common/rng.h"
#include "raindrop/render/scene_config.h"

namespace raindrop {

struct SensorSample {
  double noise_sigma = 0;  // levels of 8 bits; 0: no noise
  int jpeg_quality = 0;    // 1-100; 0: not compressed
  bool any() const { return noise_sigma > 0 || jpeg_quality > 0; }
};

// The sample's draw (none when the scene has no sensor effect). Its own stream, so that turning
// the effect on changes no other draw of the sample.
SensorSample sample_sensor(const SceneConfig& config, std::uint64_t sample_seed);

// Applies noise, then JPEG, to `rgb` (CV_8UC3) in place; the noise field comes from `sample_seed`
// alone, so a sample renders the same at any thread count.
void apply_sensor(cv::Mat& rgb, const SensorSample& sensor, std::uint64_t sample_seed);

}  // namespace raindrop

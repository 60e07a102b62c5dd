#pragma once
// Turning an input image into the frame that is rendered: centre-crop to the output aspect
// ratio, resize to the output size, and carry the camera intrinsics along.
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "raindrop/render/camera.h"

namespace raindrop {

struct Frame {
  cv::Mat clean;  // CV_8UC3 RGB at the output size
  Camera camera;  // intrinsics at the output size
  std::string camera_origin;  // "cityscapes-json" or "default"
};

// `size`: output width x height, or empty to keep the input size. Downscaling uses area
// averaging (no aliasing), upscaling bilinear interpolation.
Frame make_frame(const cv::Mat& rgb8, const std::optional<Camera>& calibration,
                 const std::optional<cv::Size>& size);

}  // namespace raindrop

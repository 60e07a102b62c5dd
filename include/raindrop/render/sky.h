#pragma once
// The sky a drop looks into. A drop on the glass is a strong wide-angle lens: the rays it
// sends up into the camera's lower half of its image come from far above the frame, where a
// street photograph has sky. The frame itself holds only its lower edge, so the colour is
// estimated from the brightest part of the frame's top third.
#include <glm/vec3.hpp>
#include <opencv2/core.hpp>

namespace raindrop {

// Mean RGB (in [0, 1], sRGB-encoded like the frame) of the brightest tenth of the pixels in
// the top third of `rgb8` (CV_8UC3), times `gain`, clamped to 1.
glm::dvec3 estimate_sky_rgb(const cv::Mat& rgb8, double gain = 1.0);

}  // namespace raindrop

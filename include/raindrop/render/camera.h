#pragma once
// Pinhole camera at the origin looking along +z, OpenCV axes (x right, y down, z forward).
// Pixel centres are at integer coordinates: pixel (i, j) is centred on (i, j), as in OpenCV
// and the Cityscapes calibration files.
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace raindrop {

struct Camera {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;

  // Direction of the ray through image point (px, py); z component is 1 (not normalised).
  glm::dvec3 ray_direction(double px, double py) const {
    return {(px - cx) / fx, (py - cy) / fy, 1.0};
  }

  // Image point of a camera-space point in front of the camera (z > 0).
  glm::dvec2 project(const glm::dvec3& p) const {
    return {fx * p.x / p.z + cx, fy * p.y / p.z + cy};
  }

  // The same camera after scaling the image to new_width x new_height.
  Camera resized(int new_width, int new_height) const;
  // The same camera after cropping the image to the window starting at (x0, y0).
  Camera cropped(int x0, int y0, int new_width, int new_height) const;

  // Cityscapes' field of view (fx = 2262.52 at 2048 px) along the longer side, when no
  // calibration is known.
  static Camera default_for(int width, int height);
};

}  // namespace raindrop

#include "raindrop/render/camera.h"

#include <algorithm>

namespace raindrop {

Camera Camera::resized(int new_width, int new_height) const {
  // Pixel centres at integers: x' = (x + 0.5) * s - 0.5.
  const double sx = static_cast<double>(new_width) / width, sy = static_cast<double>(new_height) / height;
  Camera c = *this;
  c.fx = fx * sx;
  c.fy = fy * sy;
  c.cx = (cx + 0.5) * sx - 0.5;
  c.cy = (cy + 0.5) * sy - 0.5;
  c.width = new_width;
  c.height = new_height;
  return c;
}

Camera Camera::cropped(int x0, int y0, int new_width, int new_height) const {
  Camera c = *this;
  c.cx = cx - x0;
  c.cy = cy - y0;
  c.width = new_width;
  c.height = new_height;
  return c;
}

Camera Camera::default_for(int width, int height) {
  Camera c;
  // The field of view along the longer side, so portrait frames get the same lens.
  c.fx = c.fy = 2262.52 / 2048.0 * std::max(width, height);
  c.cx = 0.5 * (width - 1);
  c.cy = 0.5 * (height - 1);
  c.width = width;
  c.height = height;
  return c;
}

}  // namespace raindrop

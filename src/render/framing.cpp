#include "raindrop/render/framing.h"

#include <cmath>

#include <opencv2/imgproc.hpp>

#include "raindrop/common/error.h"

namespace raindrop {

Frame make_frame(const cv::Mat& rgb8, const std::optional<Camera>& calibration,
                 const std::optional<cv::Size>& size) {
  Frame f;
  Camera cam;
  if (calibration) {
    cam = *calibration;
    cam.width = rgb8.cols;
    cam.height = rgb8.rows;
    f.camera_origin = "cityscapes-json";
  } else {
    cam = Camera::default_for(rgb8.cols, rgb8.rows);
    f.camera_origin = "default";
  }
  if (!size || *size == rgb8.size()) {
    f.clean = rgb8;
    f.camera = cam;
    return f;
  }
  // Largest centred window with the output's aspect ratio.
  const double aspect = static_cast<double>(size->width) / size->height;
  int w = rgb8.cols, h = rgb8.rows;
  if (static_cast<double>(w) / h > aspect) {
    w = static_cast<int>(std::lround(h * aspect));
  } else {
    h = static_cast<int>(std::lround(w / aspect));
  }
  // An aspect ratio far from the frame's (--size 16384x16 of a 480x360 frame) leaves a window
  // under a pixel across: nothing to resize from.
  if (w < 1 || h < 1)
    throw Error("a " + std::to_string(rgb8.cols) + "x" + std::to_string(rgb8.rows) + " frame holds no window of " +
                std::to_string(size->width) + "x" + std::to_string(size->height) +
                "'s aspect ratio a pixel across: choose a --size nearer the frame's shape");
  const int x0 = (rgb8.cols - w) / 2, y0 = (rgb8.rows - h) / 2;
  cam = cam.cropped(x0, y0, w, h);
  const cv::Mat window = rgb8(cv::Rect(x0, y0, w, h));
  const bool down = size->width < w;
  cv::resize(window, f.clean, *size, 0, 0, down ? cv::INTER_AREA : cv::INTER_LINEAR);
  f.camera = cam.resized(size->width, size->height);
  return f;
}

}  // namespace raindrop

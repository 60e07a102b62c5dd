#include "raindrop/common/demo.h"

#include <cmath>

#include <opencv2/imgproc.hpp>

#include "raindrop/common/rng.h"

namespace raindrop {

cv::Mat demo_checkerboard(int width, int height) {
  cv::Mat img(height, width, CV_8UC3);
  const int cell = std::max(4, width / 32);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const bool white = ((x / cell) + (y / cell)) % 2 == 0;
      // A colour ramp across the board shows where in the scene a drop pixel looks.
      const auto r = static_cast<std::uint8_t>(white ? 235 : 40 + 150 * x / width);
      const auto g = static_cast<std::uint8_t>(white ? 235 : 40 + 150 * y / height);
      const auto b = static_cast<std::uint8_t>(white ? 235 : 120);
      img.at<cv::Vec3b>(y, x) = {r, g, b};
    }
  }
  return img;
}

cv::Mat demo_street(int width, int height) {
  cv::Mat img(height, width, CV_8UC3);
  const int horizon = height * 45 / 100;
  for (int y = 0; y < height; ++y) {
    const double t = static_cast<double>(y) / horizon;
    const cv::Vec3b sky(static_cast<uchar>(120 + 90 * t), static_cast<uchar>(160 + 70 * t), static_cast<uchar>(225 + 20 * t));
    for (int x = 0; x < width; ++x) img.at<cv::Vec3b>(y, x) = y < horizon ? sky : cv::Vec3b(70, 72, 75);
  }
  Rng rng(7);  // fixed layout
  int x = 0;
  while (x < width) {
    const int w = std::max(1, width / 14 + rng.uniform_int(0, width / 12));
    const int top = horizon - height / 10 - rng.uniform_int(0, height * 3 / 10);
    const cv::Scalar wall(rng.uniform_int(90, 200), rng.uniform_int(70, 160), rng.uniform_int(60, 140));
    cv::rectangle(img, {x, top}, {x + w, horizon + height / 20}, wall, cv::FILLED);
    // Steps of at least one pixel: tiny frames must not loop forever.
    for (int wy = top + height / 40; wy < horizon - height / 40; wy += std::max(1, height / 18)) {
      for (int wx = x + w / 8; wx < x + w - w / 8; wx += std::max(6, w / 4)) {
        cv::rectangle(img, {wx, wy}, {wx + std::max(3, w / 10), wy + height / 36}, cv::Scalar(40, 60, 90), cv::FILLED);
      }
    }
    x += w + rng.uniform_int(0, width / 40);
  }
  // Road: pavement edges converging to a vanishing point, dashed centre line.
  const cv::Point vp(width / 2, horizon);
  std::vector<cv::Point> road{{vp.x - width / 40, horizon + height / 20}, {vp.x + width / 40, horizon + height / 20}, {width, height}, {0, height}};
  cv::fillConvexPoly(img, road, cv::Scalar(55, 55, 58));
  cv::line(img, {vp.x - width / 40, horizon + height / 20}, {0, height}, cv::Scalar(230, 230, 230), std::max(2, width / 300), cv::LINE_AA);
  cv::line(img, {vp.x + width / 40, horizon + height / 20}, {width, height}, cv::Scalar(230, 230, 230), std::max(2, width / 300), cv::LINE_AA);
  for (int i = 0; i < 8; ++i) {
    const double a = std::pow((i + 0.0) / 8, 2), b = std::pow((i + 0.5) / 8, 2);
    const int ya = horizon + height / 20 + static_cast<int>(a * (height - horizon)), yb = horizon + height / 20 + static_cast<int>(b * (height - horizon));
    cv::line(img, {vp.x, ya}, {vp.x, std::min(yb, height - 1)}, cv::Scalar(240, 210, 60), std::max(2, static_cast<int>(width / 200 * (0.3 + b))), cv::LINE_AA);
  }
  cv::GaussianBlur(img, img, {3, 3}, 0.6);
  return img;
}

}  // namespace raindrop

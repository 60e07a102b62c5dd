#include "raindrop/render/background_defocus.h"

#include <cmath>

#include <opencv2/imgproc.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "raindrop/render/defocus.h"
#include "raindrop/render/disk_kernel.h"
#include "raindrop/render/linear_frame.h"
#include "raindrop/render/srgb.h"

namespace raindrop {

namespace {

// The linear image convolved with the antialiased disk of `diameter` pixels.
cv::Mat disk_convolve(const cv::Mat& linear, double diameter, int border) {
  const std::vector<KernelRow> rows = disk_rows(diameter, true, false);
  int radius = 0;
  for (const KernelRow& r : rows) {
    radius = std::max(radius, std::abs(r.dy));
    for (const auto& [dx, w] : r.taps) radius = std::max(radius, std::abs(dx));
  }
  cv::Mat kernel = cv::Mat::zeros(2 * radius + 1, 2 * radius + 1, CV_32F);
  for (const KernelRow& r : rows)
    for (const auto& [dx, w] : r.taps) kernel.at<float>(radius + r.dy, radius + dx) += w;
  kernel /= cv::sum(kernel)[0];
  cv::Mat out;
  cv::filter2D(linear, out, CV_32F, kernel, cv::Point(-1, -1), 0, border);
  return out;
}

// Linear RGB (CV_32FC3) convolved with the disk, on the grid where it is wide enough.
cv::Mat defocus_linear(const cv::Mat& linear, double coc_px, BorderMode border, BackgroundGrid grid) {
  const int mode = border == BorderMode::Clamp ? cv::BORDER_REPLICATE : cv::BORDER_REFLECT;
  const double diameter = std::min(coc_px, 2.0 * std::max(linear.cols, linear.rows));
  const int s = grid == BackgroundGrid::Exact ? 1 : background_grid_step(diameter);
  if (s == 1) return disk_convolve(linear, diameter, mode);
  // On a grid of s x s blocks: area-averaged, the disk of diameter / s, then bilinear back (block
  // centres are where INTER_AREA puts them). The frame is first continued by its border mode on
  // every side by more than the disk's reach, in whole blocks, so the small image's own border
  // never enters the crop: continuing the small image instead mirrors it about a line up to
  // s - 1 pixels off the frame's edge (up to 10 levels at the edges, measured, before this).
  const int margin = s * static_cast<int>(std::ceil((0.5 * diameter + 2.0 * s) / s));
  cv::Mat padded;
  cv::copyMakeBorder(linear, padded, margin, margin + (s - linear.rows % s) % s, margin,
                     margin + (s - linear.cols % s) % s, mode);
  cv::Mat small, blurred, up;
  cv::resize(padded, small, cv::Size(padded.cols / s, padded.rows / s), 0, 0, cv::INTER_AREA);
  blurred = disk_convolve(small, diameter / s, mode);
  cv::resize(blurred, up, padded.size(), 0, 0, cv::INTER_LINEAR);
  return up(cv::Rect(margin, margin, linear.cols, linear.rows)).clone();
}

}  // namespace

int background_grid_step(double diameter) {
  return std::max(1, static_cast<int>(diameter / kBackgroundGridDiameter));
}

cv::Mat defocus_background(const cv::Mat& clean, double coc_px, BorderMode border, const HighlightLift& lift,
                           BackgroundGrid grid) {
  CV_Assert(clean.type() == CV_8UC3);
  if (!(coc_px >= kMinVisibleCocPx)) return clean.clone();
  const SrgbTables& srgb = SrgbTables::get();
  cv::Mat blurred = defocus_linear(lifted_linear(clean, lift), coc_px, border, grid);
  cv::Mat result(clean.size(), CV_8UC3);
  tbb::parallel_for(tbb::blocked_range<int>(0, clean.rows, 16), [&](const tbb::blocked_range<int>& ys) {
    for (int y = ys.begin(); y < ys.end(); ++y) {
      auto* in = blurred.ptr<cv::Vec3f>(y);
      auto* out = result.ptr<cv::Vec3b>(y);
      for (int x = 0; x < clean.cols; ++x) {
        lift.restore(&in[x][0]);
        for (int c = 0; c < 3; ++c) out[x][c] = srgb.encode(in[x][c]);
      }
    }
  });
  return result;
}

}  // namespace raindrop

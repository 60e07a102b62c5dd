#pragma once
// An 8-bit sRGB frame as linear light, lifted where it was clipped: what the effects that mix
// light over the whole frame (the street's defocus, background_defocus.h; the wet glass' veil,
// veil.h) start from. Light adds only once decoded, and a clipped pixel stands for more light
// than it stores (highlights.h; a lift that is not active changes nothing).
#include <opencv2/core.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "raindrop/render/highlights.h"
#include "raindrop/render/srgb.h"

namespace raindrop {

// CV_8UC3 sRGB -> CV_32FC3 linear, each pixel lifted; rows on the calling thread's TBB arena.
inline cv::Mat lifted_linear(const cv::Mat& rgb8, const HighlightLift& lift) {
  CV_Assert(rgb8.type() == CV_8UC3);
  const auto& decode = srgb8_to_linear_table();
  cv::Mat linear(rgb8.size(), CV_32FC3);
  tbb::parallel_for(tbb::blocked_range<int>(0, rgb8.rows, 16), [&](const tbb::blocked_range<int>& ys) {
    for (int y = ys.begin(); y < ys.end(); ++y) {
      const auto* in = rgb8.ptr<cv::Vec3b>(y);
      auto* out = linear.ptr<cv::Vec3f>(y);
      for (int x = 0; x < rgb8.cols; ++x) {
        for (int c = 0; c < 3; ++c) out[x][c] = decode[in[x][c]];
        lift.apply(&out[x][0]);
      }
    }
  });
  return linear;
}

}  // namespace raindrop

#pragma once
// Defocus blur of the drop regions. Drops sit a few decimetres from a camera focused on the
// street, so each is seen through a disk-shaped circle of confusion (paper: a disk kernel
// 7-20 px wide at 2048 px). Only mask pixels are blurred; they read the unblurred rainy
// image around them (drop and background alike), so rainy == clean outside the mask.
//
// Methods (the accuracy/time knob):
//  - disk-aa:     antialiased disk, each tap weighted by the area of the pixel inside the
//                 disk (the most accurate; exact at any diameter, including the 2-5 px
//                 diameters of a 512 px frame);
//  - disk:        binary disk, a tap counts when its centre is inside the disk;
//  - disk-direct: the same binary disk summed tap by tap (reference timing for "disk");
//  - gaussian:    separable Gaussian with the disk's variance (sigma = d / 4).
// disk-aa and disk sum each kernel row's full-weight run with prefix sums and add the
// partial rim taps one by one, O(d) per pixel instead of O(d^2).
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "raindrop/render/scene_config.h"
#include "raindrop/render/spans.h"

namespace raindrop {

// label: CV_32S (>= 0 inside drops); color: CV_32FC3 traced colours, replaced in place by
// their blurred values inside drops; clean: CV_8UC3 frame seen outside drops.
// `drop_box`, if given, bounds the drop pixels (saves a pass over the frame); `spans`, if
// given, are per-row x-intervals holding every drop pixel (the tracer's), so that only the
// parts of the frame near drops are read.
void blur_drops(const cv::Mat& clean, const cv::Mat& label, cv::Mat& color, double diameter_px,
                BlurMethod method, const cv::Rect* drop_box = nullptr,
                const std::vector<std::vector<Span>>* spans = nullptr);

// The widest registers the disk blurs (and the thin lens's spread) use on this processor: 0 SSE2 (one pixel per register),
// 1 AVX (two), 2 AVX-512 (four). Every level gives the same bits (blur.cpp says why).
int blur_simd_level();
// Tests: use at most `level` from now on (-1: the processor's widest again).
void force_blur_simd_level(int level);
// The width in use: blur_simd_level(), or less where a test forced it. The thin lens's
// spread of drop layers (defocus_rows.cpp) uses it too.
int blur_simd_level_used();

// Per row y of `box`, the x-intervals blur_drops reads when given `spans`: the spans of rows
// y - reach .. y + reach, widened by `reach`, clipped to the box, merged (touching intervals
// joined). Without spans, the box's row. Exposed for tests.
std::vector<std::vector<Span>> blur_read_intervals(const std::vector<std::vector<Span>>* spans, int reach,
                                                   const cv::Rect& box);

// The kernel's weights as a dense (2R+1)^2 matrix, for tests and documentation.
cv::Mat blur_kernel(double diameter_px, BlurMethod method);

}  // namespace raindrop

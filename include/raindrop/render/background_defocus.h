#pragma once
// The street out of focus. A thin lens focused nearer than the background (on the glass: a phone
// held to a rained-on window focuses on the drops) spreads each background point over its circle
// of confusion, aperture * fx * |1/T - 1/F| pixels wide. The input photograph is the background
// as a sharp pinhole sees it, so the camera's view without drops is that photograph convolved
// with the disk, in linear light (and through the highlights' lift where the scene has one).
//
// To first order it is also what drops refract: a drop imaged in focus collects, at each of its
// points, a cone of rays as wide as the aperture, which the drop turns as a whole (refraction
// through one point keeps the cone's spread to first order), so the cone meets the background
// over the same circle. The renderer therefore traces and composites the drops against this
// defocused background (renderer.cpp), and it is the clean image written beside the rainy one.
#include <opencv2/core.hpp>

#include "raindrop/render/highlights.h"
#include "raindrop/render/scene_config.h"

namespace raindrop {

// Circles of 2 x kBackgroundGridDiameter pixels and more are convolved on a grid of s x s pixel
// blocks, s = diameter / kBackgroundGridDiameter rounded down (area-averaged, the disk of
// diameter / s, bilinear back); narrower ones exactly. What the grid smooths away is the disk's
// own edge: against the exact convolution at most 0.36 levels RMS and 3 levels on street frames
// with circles of 60-168 px (tests/render/test_focus.cpp). A grid of diameter / 8 or / 16 was
// tried: up to 1.15 levels RMS and 11 at most on a 34-60 px circle, over the tolerance.
inline constexpr double kBackgroundGridDiameter = 24;
enum class BackgroundGrid { Auto, Exact };
int background_grid_step(double diameter);

// `clean` (CV_8UC3 sRGB) convolved with the antialiased disk of `coc_px` pixels (the weights of
// disk_kernel.h) in linear light, borders continued as `border` says; the lift, when active,
// before the mix and undone after. Circles under kMinVisibleCocPx return a copy. `Exact`: at
// full resolution whatever the circle (the reference the grid is measured against).
cv::Mat defocus_background(const cv::Mat& clean, double coc_px, BorderMode border, const HighlightLift& lift = {},
                           BackgroundGrid grid = BackgroundGrid::Auto);

}  // namespace raindrop

#pragma once
// Small drops the working scale cannot see, found at a finer scale and filled from their
// surroundings (raindrop-remove --fine-drops; off by default: it costs a detector run on
// 2.25 times the working pixels).
//
// Photographs through a wet windshield or of droplets on glass hold hundreds of drops a few
// pixels across. With the long side brought to 512 (working_scale.h) a drop 8 px wide in a
// 1280x720 photograph is 3 px, and the detector misses it; running the whole pipeline at a
// larger scale found them, but took texture for drops and cost 1.7-5.4 dB on renders with
// ground truth (docs/RESULTS.md 4.32). This pass keeps the working-scale result and only
// adds: the deciding detector (the router's choice, detector_router.h) runs on the input at
// kFineDropScaleFactor times the working scale; of its mask, the small parts over smooth
// surroundings of the result are filled there by push-pull interpolation, exactly as the
// working-scale pass fills small drops (surround_fill.h: parts of at most kFineDropArea pixels
// at the reference scale, scaled, whose surround's median absolute deviation is at most the
// options' surround_fill_mad); the fill comes back to full size with a bilinear weight
// (detail::composite_upsampled), so pixels away from those parts stay the result's own.
// A texture taken for drops has a rough surround and is left as it is; the 3RN never runs
// at the finer scale. docs/RESULTS.md 4.45 has what it gains and costs.
#include <opencv2/core.hpp>

#include "raindrop/remove/surround_fill.h"

namespace raindrop::removal {

// The finer scale: this many times the working scale, at most 1.
inline constexpr double kFineDropScaleFactor = 1.5;
// The largest part filled, in pixels with the long side at 512: the working pass's default
// (larger drops the working scale sees).
inline constexpr int kFineDropArea = kSurroundFillArea;

// The scale of the fine pass for a working scale `scale` in (0, 1]: min(1, 1.5 scale), or 0
// where that is no finer than `scale` (the working scale is the image's own size).
double fine_drop_scale(double scale);

// The parts of `mask` (CV_8U, 0 or non-zero, the size of `rgb`) that surround_fill_mask
// chooses on `rgb` (CV_32FC3 RGB in [0, 1]) with `max_area` and `max_mad`, filled from their
// surroundings: returns the push-pull fill (CV_32FC3, `rgb` outside those parts) and sets
// `weight` (CV_32F, 1 in the filled parts, 0 elsewhere) and `parts` (how many were filled).
cv::Mat fill_fine_drops(const cv::Mat& rgb, const cv::Mat& mask, int max_area, double max_mad, cv::Mat* weight,
                        int* parts);

}  // namespace raindrop::removal

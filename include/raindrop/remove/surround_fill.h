#pragma once
// Small drops over smooth surroundings, filled from those surroundings instead of by the 3RN.
//
// The 3RN learned the paper preset's drops, which hold a refracted view of the street, and it
// keeps part of what it sees inside a drop. On real windshield photographs that is the drop's
// dark rim and bright centre: the drops it is given come out faded, not gone (docs/RESULTS.md
// 4.18-4.20; more training on the same data did not change it). A small drop over a smooth
// background (sky, a wall, a road's surface) hides almost nothing that its surroundings do not
// predict, so there the pipeline fills it from them, by push-pull interpolation (below), and
// the 3RN's output is used everywhere else. The RFN then runs on the blend as before.
//
// Which parts of the mask are filled: the connected parts (8-connected) of the final mask M at
// most `max_area` pixels, whose surround, the pixels outside M in the part's bounding box
// grown by kSurroundRing pixels on every side, is smooth: the median absolute deviation from
// the median of their luma (pixels.h, 8-bit levels) is at most `max_mad`. A median ignores the
// neighbouring drops that a dense windshield puts into most surrounds, where a standard
// deviation did not (docs/RESULTS.md 4.24). A false detection over a textured facade or foliage
// has a textured surround: the fill would smear it, and the 3RN, which returns such texture
// nearly unchanged, keeps it. A part with fewer than 4 surround pixels is not filled.
//
// Only the working-scale pass fills; the coarse pass's parts are large by definition. With
// tiles, the parts are those of each tile's window of the mask (a part cut by a tile's edge
// is judged by its piece; the default working scale runs one tile).
#include <vector>

#include <opencv2/core.hpp>

namespace raindrop::removal {

// Defaults of RemoveOptions::surround_fill_area / surround_fill_mad (chosen on validation sets,
// docs/RESULTS.md 4.24): a disk about 14 px across with the image's long side at 512 (scaled with
// the scale the image is processed at: surround_fill_area_at_scale), and 4 levels. The area is
// the deciding detector's where its rdn.onnx says (raindrop.surround_fill_area, ModelInfo):
// compact-windshield's 1500, whose drops on windshield photographs are larger and the 3RN leaves
// faded (docs/RESULTS.md 4.44); this where it does not.
inline constexpr int kSurroundFillArea = 150;
inline constexpr double kSurroundFillMad = 4.0;
// The area limit at the scale an image is processed at. The limit is given at the scale that
// brings the image's long side to kDefaultWorkingSize (512, the committed models' working size,
// where the limit was chosen), never enlarging: a drop covers (scale / that scale)^2 times as many
// pixels at another scale (--scale, or models with another working size), so the same drops
// stay below the limit. At that scale, and 0 (off), the limit is returned as given.
int surround_fill_area_at_scale(int area, cv::Size image_size, double scale);

// How far beyond a part's bounding box its surround reaches, in pixels.
inline constexpr int kSurroundRing = 4;
// The fill of a part interpolates within its bounding box grown on every side by this many
// times its larger side (at least 2 kSurroundRing pixels), clipped to the image.
inline constexpr int kSurroundWindow = 2;
// When the windows of all the parts to fill add up to more than this many times the image's
// pixels (thin or diagonal parts, whose boxes are large for their area), every part is filled
// from one push-pull over the whole image instead: the cost stays within a few whole-image fills.
inline constexpr double kSurroundWindowBudget = 4.0;

// Push-pull interpolation of planar RGB (3 planes of h x w floats) into the pixels where `hole`
// (CV_8U, h x w) is non-zero, written to `out` (3 planes; the pixels outside the hole get the
// input's values exactly). Level 0 holds N = W R with W = 1 outside the hole and 0 inside; each
// coarser level halves the size (rounding up) and holds the means of N and W over the 2x2
// blocks of the finer one (the pixels of a block that exist). From the 1x1 level down, V = N /
// W there (0 where W = 0), then V = N + (1 - W) U at each finer level, where U is V of the
// coarser level upsampled bilinearly (the fine pixel y sits at (y + 0.5) / 2 - 0.5 on the
// coarse grid, clamped to its edges). Every filled value is a convex combination of the pixels
// outside the hole, so it lies within their range. Returns false, writing nothing, when every
// pixel is in the hole.
bool push_pull_fill(const float* rgb, int h, int w, const cv::Mat& hole, float* out);

// The parts of `mask` (CV_8U, 0 or non-zero; h x w) to fill from their surroundings, as CV_8U
// 0/255 (the rule above); `rgb` is the image under it as 3 planes of h x w floats in [0, 1].
// `filled_parts`, when given, receives the number of parts chosen.
cv::Mat surround_fill_mask(const cv::Mat& mask, const float* rgb, int max_area, double max_mad,
                           int* filled_parts = nullptr);

// Replaces the 3RN's output `ihat` (3 planes of h x w) by the push-pull fill of `rgb` from
// outside `mask` wherever surround_fill_mask chooses, each part from its own window
// (kSurroundWindow; the whole image past kSurroundWindowBudget); the rest of `ihat` is left bit
// for bit. Returns the number of parts filled. `filled_parts`, when given, receives them as
// surround_fill_mask gives them (CV_8U 0/255).
//
// With `rim` > 0, each chosen part first grows into its rim (grow_into_rims in surround_fill.cpp):
// a real drop's dark rim or bright halo often lies just past the detector's mask, and the fill
// of the part alone leaves it as a ring. Up to `rim` steps outward, the pixels outside the mask
// whose luma is more than kRimLevels from the part's surround median join the part, unless that
// structure goes on past them (the next step would add more than kRimContinuation times what the
// last step took: a ring thins out to nothing past its width, while a pole, a kerb or an edge of
// the scenery adds about as much at every step). `mask` (0/1 or 0/255) is written there:
// its pixels grow with the parts (set to 1), so the blend and the final mask include them. A
// band that reaches the edge of `mask` (the image's, or a tile's window) may go on past it and is
// left alone. `filled_parts` then holds the grown parts (surround_fill_mask gives them as found).
// The working-scale pass grows them; the fine pass (fine_drops.h) does not (rim 0).
// The default reach (RemoveOptions::surround_fill_rim), at the reference scale of
// surround_fill_area_at_scale; surround_fill_rim_at_scale gives it at another (rounded, at least 1
// where it is on): a rim is as many pixels wide as the scale makes it. Chosen on validation sets
// and the photographs (docs/RESULTS.md 4.54).
inline constexpr int kSurroundFillRim = 3;
inline constexpr int kMaxSurroundFillRim = 16;  // RemoveOptions and --surround-fill-rim refuse more
int surround_fill_rim_at_scale(int rim, cv::Size image_size, double scale);
inline constexpr float kRimLevels = 12.0f;
inline constexpr double kRimContinuation = 0.25;
int fill_small_drops_from_surround(const float* rgb, cv::Mat& mask, int max_area, double max_mad,
                                   std::vector<float>& ihat, cv::Mat* filled_parts = nullptr, int rim = 0);

}  // namespace raindrop::removal

#pragma once
// A second, coarse pass for drops too large for the networks at the working scale.
//
// The networks learned drops 10-40 px across (the committed models: paper-preset renders at
// 512x256). A drop two or three times that size, as on a lens cover a few centimetres from the
// lens, is beyond their receptive field: the detector finds its rim at most, and the
// reconstruction smears it. Seen at a third of the working scale the same drop is 20-40 px
// again, which the networks handle. So after the pass at the working scale, the pipeline runs
// once more on a copy at a third of that scale, keeps only the drops that pass finds large
// (connected parts of its mask at least kLargeDropDiameter px across, i.e. 60 px or more at
// the working scale; measured on the coarse pass's dilated mask by area, so a cluster of
// touching small drops, or a large false detection, counts too), and takes the coarse pass's
// output there, blended in with the upsampled mask as working_scale.h describes; everywhere
// else the fine pass's result stays bit for bit.
// Small drops stay with the fine pass: in the coarse copy they are a few pixels wide and their
// reconstruction there is blurred.
//
// In the coarse pass each drop's mask dilation grows with the drop (RemoveOptions::
// large_drop_growth, default the models' raindrop.large_drop_growth: mask.h's dilate_mask_by_size).
// A drop on a lens cover a few centimetres from the lens is defocused: its light spreads past the
// outline the detector finds by a margin that grows with it, and a fixed k = 3 leaves that margin
// in place. Which parts count as large is decided on the grown mask, so the growth also lets
// slightly smaller parts, and neighbours it joins, count as large (at 0.35: from about 18 to 16
// coarse px across). Measured (docs/RESULTS.md 4.21): growth 0.35 takes the default from +3.00 to +3.43 dB
// on held-out real lens-cover pairs; the same growth at the working scale added nothing there and
// cost sparse drops 0.07 dB, so that pass keeps k.
//
// A large region is replaced only where the image there is smooth: the mean absolute
// Laplacian of its luma at the working scale (8-bit levels, sharpness_map) at most
// RemoveOptions::large_drop_max_sharpness (default kLargeDropMaxSharpness). The coarse pass is
// for defocused drops, which blur what is behind them; its fill is itself blurred (3x upsampled,
// kLargeDropSmoothing). A cluster of small sharp drops on a windshield, or a false detection
// over foliage or a facade, is a sharp region: replacing it with that fill smears the scene, and
// the working-scale pass already handles the small drops there. Chosen on validation sets
// (docs/RESULTS.md 4.22): at 8 levels the real lens-cover pairs keep every large region (their
// score is unchanged; at 7 one goes and they lose 0.05 dB), while the paper preset's clusters of
// sharp drops on street frames, where the coarse pass cost 0.1-0.2 dB, are left to the
// working-scale pass.
//
// The coarse copy's detector is the main models'; its 3RN and RFN can be another model's, one
// trained for drops at that scale: the folder named by the main models' LARGE_DROPS file
// (model_paths.h; every committed removal folder names paper-real-coarse or, the int8 ones, its int8 copy) or Remover's
// large_drop_dir.
// Measured (docs/RESULTS.md 4.8, 4.11): the default then gains +3.00 dB on real lens-cover pairs
// instead of +1.49, and nothing changes on the paper preset's drops or the sparse set.
//
// Measured with the shipped compact model (docs/RESULTS.md 4.6): on real lens-cover pairs the
// PSNR gain goes from +0.2 to about +1.5 dB, on thin-lens windshield renders it rises by
// 0.26 dB, and on the paper preset's drops it stays within 0.1 dB. The coarse copy has a ninth
// of the pixels (a third on each side). Its detector runs first; only when it finds a large
// drop do its 3RN and RFN run and its result get composited (one more pass over the full-size
// image's rows), so a photograph without large drops pays for a ninth-size detection only
// (`raindrop-bench remove` measures both cases). With two or more threads the coarse pass runs
// beside the working-scale pass, which it does not read (Remover::run): that detection, on
// one thread, had left the other core idle (docs/RESULTS.md 3.6).
#include <vector>

#include <opencv2/core.hpp>

#include "raindrop/remove/model.h"

namespace raindrop::removal {

// The largest sharpness (mean |Laplacian| of the working-scale luma inside a region, 8-bit
// levels) at which a large region is still replaced by the coarse pass (above).
inline constexpr double kLargeDropMaxSharpness = 8.0;

// The coarse pass runs at the working scale divided by this.
inline constexpr double kLargeDropScaleDivisor = 3.0;
// A connected part of the coarse pass's mask is a large drop when its area is at least that of
// a disk this wide (pixels of the coarse copy).
inline constexpr int kLargeDropDiameter = 20;
// Gaussian sigma, in pixels of the coarse copy, that smooths the coarse pass's result before it
// is upsampled over the large drops. The 3RN and RFN bring their half-resolution body back up
// with a stride-2 transposed convolution, whose output carries a faint 2-pixel checkerboard;
// at the working scale it is a pixel or two wide, but the coarse result is enlarged 3x or more,
// into visible blocks (docs/RESULTS.md 4.8, real photographs). Sigma 1 (OpenCV's 9-tap kernel)
// keeps 1.4% of a 2-pixel stripe and under 0.1% of the checkerboard; it also softens detail up to
// 4-6 coarse pixels, which cost nothing measurable on real pairs (4.8).
inline constexpr double kLargeDropSmoothing = 1.0;
// The coarse pass's 3RN and RFN each run on the coarse copy and on its mirror image (left to
// right), and the two results, the second mirrored back, are averaged: the reconstruction of a
// large drop is a guess at what it hides, and two guesses from two views average out part of
// their error. Measured (docs/RESULTS.md 4.11): +0.12 dB on the real pairs' train split, +0.06
// on lens-cover renders, +0.02 on windshield renders, the paper preset's drops unchanged; it
// doubles the coarse pass's 3RN and RFN, which run on a ninth of the working pixels and only
// on photographs with a large drop. Mirrored left to right only: drops are not symmetric top
// to bottom (gravity, the sky above), and the networks learned them upright.
inline constexpr bool kLargeDropMirrorAverage = true;

// The input's own fine detail, given back where the coarse fill replaced the image
// (RemoveOptions::large_drop_detail, raindrop-remove --large-drop-detail). A drop a few
// centimetres from the lens is defocused and semi-transparent: the lens sees around it, so the
// scene's fine detail shows through it, attenuated, under the drop's own smooth veil
// (I = (1 - a) B + V, with a and V smooth). The coarse fill, reconstructed at a third of the
// working scale and upsampled, holds none of that detail: where the coarse pass takes over, a
// lens-cover drop's street, or a building the detector took for a large drop, comes out as a
// smooth patch. So the fill gets back `gain` times the input's high frequencies there (the input
// minus its Gaussian blur of kLargeDropDetailSigma pixels at the working scale), in proportion to
// the fill's blend weight. Chosen on the real pairs' train split (docs/RESULTS.md 4.77): gain 0.5
// at sigma 3 gave +0.11 dB and SSIM-Y +0.014 there; stronger gains bring back the drops' own
// edges. 0: the fill alone, as before.
inline constexpr double kLargeDropDetail = 0.5;
inline constexpr double kLargeDropDetailSigma = 3.0;

// The factor by which add_input_detail shrinks a copy of the input before blurring it:
// floor(sigma / 4), at least 1. Up to sigma 8 (images up to about 1365 px on their long side at
// the default working size) the blur is exact; wider, it is computed on the copy area-averaged by
// that factor, blurred by sigma / factor (4 to 8 pixels there) and upsampled bilinearly.
int detail_blur_reduction(double sigma);

// Adds `gain` x (input - GaussianBlur(input, sigma)) x the upsampled `weight_small` (CV_32F,
// the coarse composite's weight; upsampled as working_scale.h does) to `result` (the input's
// size and type), in float RGB; where that weight is 0 `result` stays bit for bit, and its
// alpha channel always does. `result_rgb` (CV_32FC3, optional) is the float copy to update
// alike. `sigma` is in full-size pixels. gain 0: nothing.
void add_input_detail(const cv::Mat& input, const cv::Mat& weight_small, double sigma, double gain, cv::Mat& result,
                      cv::Mat* result_rgb = nullptr);

// `net` run on `inputs` (planar float images of `channels[i]` channels, h x w) and on their
// mirror image, the second output mirrored back, the two averaged into `output`
// (`out_channels` planes). Exactly mirror-equivariant: mirroring the inputs mirrors the output.
void run_mirror_averaged(Network& net, const std::vector<const float*>& inputs, const std::vector<int>& channels, int h,
                         int w, int out_channels, float* output);

// Whether a coarse copy of this size can hold a large drop at all (both sides at least two
// large-drop diameters); smaller images skip the coarse pass.
bool coarse_pass_fits(cv::Size coarse);

// The large drops of a coarse pass's mask (CV_8U, non-zero = drop): the 8-connected parts with
// area >= pi (kLargeDropDiameter / 2)^2, as CV_8U 0/255. `count` (optional): how many.
cv::Mat large_drop_mask(const cv::Mat& mask, int* count = nullptr);

// |Laplacian| (3x3: the four neighbours minus four times the centre) of the luma of `image`
// (any input raindrop-remove accepts: 1-4 channels, 8-bit, 16-bit or float), in 8-bit levels,
// CV_32F, the image's size; the border replicated.
cv::Mat sharpness_map(const cv::Mat& image);

// The parts of `large` (CV_8U 0/255, as large_drop_mask returns) whose mean sharpness is at most
// `max_sharpness`. `sharpness` (CV_32F) is area-averaged onto large's grid first, so each part's
// mean is that of the finer image's pixels under it. `count` (optional): how many parts stay.
cv::Mat smooth_large_drops(const cv::Mat& large, const cv::Mat& sharpness, double max_sharpness, int* count = nullptr);

}  // namespace raindrop::removal

#pragma once
// The scale at which the networks see an image, and the way their result is brought back to
// the image's own size.
//
// The networks learn drops of the sizes they were trained on: 10-40 px in 512x256 frames for
// the committed models. Drops on a windshield or lens cover take a roughly fixed fraction of
// the frame, so the same drops in a 2048x1024 or 1280x720 photograph are 2.5-4x larger in
// pixels, and the detector finds only their rims (measured: +2.1 dB at full size against
// +7.5 dB when the same scenes are rendered and processed at 512x256). So by default the
// networks run on a copy whose long side is the models' working size (512 unless the models
// say otherwise, metadata raindrop.working_size); images already that small run as they are
// (enlarging would only invent pixels). The choice is made from the image size, not from
// detected drops: it is predictable, costs nothing, and matches how renders and photographs
// scale (drop size is a fraction of the field of view). --scale overrides it.
//
// Bringing the result back: the copy is made with area averaging; the networks' output and
// their binary mask are upsampled bilinearly; at full size
//   out = (1 - a) in + a up(out_small),   a = up(mask_small) in [0, 1]
// Outside the mask (a == 0) every pixel is the input's own, bit for bit; the refine network's
// small changes there are not carried over (they are below the resolution the networks saw).
// Measured on 16 Cityscapes frames with paper drops at 2048x1024 (docs/RESULTS.md 3.4): this
// loses 0.02 dB against the gain the networks reach on the 512x256 copy itself; adding the
// upsampled correction to the full-size input instead (keeping its fine detail inside drops)
// lost 0.37 dB, and bicubic or Lanczos upsampling changed nothing (within 0.07 dB).
#include <opencv2/core.hpp>

namespace raindrop::removal {

// The working size's default when the models do not name one: the committed models' training
// frames are 512x256.
constexpr int kDefaultWorkingSize = 512;

// The scale in (0, 1] at which an image of `size` is processed: working_size / long side,
// at most 1.
double auto_working_scale(cv::Size size, int working_size);

// The size of the networks' copy at `scale` (each side rounded, at least 1 pixel).
cv::Size scaled_size(cv::Size size, double scale);

// `region` of `small` (CV_32F, 1 or 3 channels) upsampled bilinearly to `full` (pixel centres
// aligned, edges replicated: cv::resize's INTER_LINEAR mapping), without making the whole
// full-size image; exactly that part of the whole.
cv::Mat upsample_region(const cv::Mat& small, cv::Size full, const cv::Rect& region);

// The part of `region` (full-size pixels) that the non-zero samples of `small` (CV_32F, one
// channel, finite) reach when upsampled as above: outside it the upsampled image is exactly 0
// there (every pixel interpolates zeros). Empty when none reaches `region`. It may be wider than
// the pixels above 0 (a tap of weight 0 still counts). Where drops are few, most
// of a photograph needs no interpolation at all.
cv::Rect upsampled_reach(const cv::Mat& small, cv::Size full, const cv::Rect& region);

// `region` of the full-size float RGB result: the input's own pixels there, `in_region`
// (CV_32FC3, in [0, 1]), blended with the upsampled networks' output `output_small`
// (CV_32FC3) by the upsampled mask `mask_small` (CV_32F in [0, 1]). `full` is the image's
// full size. Returns the blended pixels and, in `alpha`, the blend weight (CV_32F).
cv::Mat blend_upsampled(const cv::Mat& in_region, const cv::Rect& region, cv::Size full, const cv::Mat& output_small,
                        const cv::Mat& mask_small, cv::Mat& alpha);
// The same for whole rows [y0, y0 + in_rows.rows).
inline cv::Mat blend_upsampled_rows(const cv::Mat& in_rows, int y0, cv::Size full, const cv::Mat& output_small,
                                    const cv::Mat& mask_small, cv::Mat& alpha_rows) {
  return blend_upsampled(in_rows, cv::Rect(0, y0, full.width, in_rows.rows), full, output_small, mask_small, alpha_rows);
}

}  // namespace raindrop::removal

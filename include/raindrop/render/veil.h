#pragma once
// The veil of wet glass (scene effect "veil", off unless the scene names it).
//
// Glass in the rain is not only drops: between them lies a thin layer of water with fine
// droplets, mist and dissolved grime that scatters part of the light passing it into a wide
// forward lobe. Seen through it, a scene loses contrast everywhere, not only behind the drops:
// on real wet-lens pairs the rainy image has 0.98 of the clean one's contrast outside the
// drops, where our renders without a veil keep 0.99-1.00 (docs/RESULTS.md 4.2, 4.13).
//
// Model, in linear light. A layer of optical depth tau (its thickness times its scattering
// coefficient) lets exp(-tau) of the light through unscattered (Beer-Lambert); the rest,
//     s = 1 - exp(-tau),
// leaves it spread by the lobe. Light that leaves the glass at an angle theta from its path
// lands fx * tan(theta) pixels away in the image, whatever the glass' distance, so a lobe of
// angular standard deviation `spread` is a Gaussian of sigma = fx * tan(spread) pixels:
//     rainy' = (1 - s) rainy + s (G_sigma * rainy).
// Energy is kept (the mean of the image changes only through the mirrored borders, light from
// beyond the frame being taken as the frame mirrored there, and 8-bit storage), and contrast at scales well below sigma falls to
// (1 - s). The layer lies over the drops, so it acts on the finished rainy image, before the
// camera's noise and JPEG (sensor.h). Clean image, mask and alpha are as without it: a veil is
// not a drop, and no model removes it; but rainy != clean outside the mask, as with "sensor".
// Where the scene's highlights were lifted (highlights.h), the veil scatters the lifted light,
// so a clipped lamp glows through the haze instead of a grey one.
//
// Skipped where it cannot change a pixel by half a level of 8 bits: the change in linear light
// is s |G * rainy - rainy| <= s (s x gain where the highlights' lift ran: lifted light reaches
// the gain), and the sRGB curve's steepest slope is 12.92, so a frame whose s (times the gain) is
// under 0.5 / (255 * 12.92) = 1.5e-4 keeps its pixels and costs nothing.
#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

#include "raindrop/render/highlights.h"
#include "raindrop/render/scene_config.h"

namespace raindrop {

struct VeilSample {
  double optical_depth = 0;  // tau, drawn per sample
  double spread_deg = 0;     // the lobe's angular standard deviation, drawn per sample
  double sigma_px = 0;       // fx * tan(spread)
  double scattered() const;  // s = 1 - exp(-tau)
  // false: skipped (s times the lift's gain, where a lift ran, below kVeilSkipFraction; or no veil)
  bool visible(const HighlightLift& lift = {}) const;
};

// Below this scattered fraction no pixel can move by half a level (see above).
constexpr double kVeilSkipFraction = 0.5 / (255.0 * 12.92);

// How the wide Gaussian is computed. Exact: a separable Gaussian at full resolution, the
// frame mirrored about its edges (its kernel spans 8 sigma, hundreds of taps: the reference).
// Fast: on a copy averaged down to cells of about k = floor(sigma / 4) pixels that tile the
// frame exactly, mirrored there, blurred with its sigma reduced by what the cells and the
// interpolation back add (variance r^2/12 + r^2/6 for cells of r pixels), and interpolated back
// at the pixel centres: within a level of the exact blur once mixed (tests/render/test_veil.cpp,
// and the veil rows of raindrop-bench render), at a cost that hardly depends on sigma.
enum class VeilMethod { Fast, Exact };

// The sample's draw, from a stream of its own (turning the veil on changes no other draw of
// the sample). `fx`: the camera's focal length in pixels at the output size.
VeilSample sample_veil(const SceneConfig& config, double fx, std::uint64_t sample_seed);

// Applies the veil to `rgb` (CV_8UC3, sRGB-encoded) in place; a no-op unless visible().
// `lift`: the sample's highlight lift where it ran on this frame (inactive otherwise).
void apply_veil(cv::Mat& rgb, const VeilSample& veil, const HighlightLift& lift = {},
                VeilMethod method = VeilMethod::Fast);

// The wide Gaussian of a CV_32FC3 image (mirrored borders), by either method.
cv::Mat veil_blur(const cv::Mat& linear, double sigma_px, VeilMethod method);

}  // namespace raindrop

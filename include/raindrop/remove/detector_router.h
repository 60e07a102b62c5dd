#pragma once
// Which of two detectors decides an image's mask: the models' own, or the alternative that the
// optional file ROUTER in their folder names.
//
// No one detector is best everywhere. The default's finds the soft drops of lens covers and of
// its synthetic training mix; compact-windshield's (fine-tuned on sharp windshield drops,
// threshold 0.75) finds the small sharp drops that photographs through a wet windshield are
// full of, and costs about 0.4 dB elsewhere. Both share the 3RN and RFN. Measured on held-out
// sets (docs/RESULTS.md 4.33, 4.34): routing each image to one of them keeps every target of
// the default and gains +1.9 dB on sharp windshield drops, where the default alone gains
// +3.6 dB and the alternative alone +5.5.
//
// The router reads what the main detector already computed, its probability map P at the
// automatic working scale (working_scale.h), so an image it keeps costs only the features (a few
// ms); one it sends away costs the alternative detector's run, unless the main detector's graph
// computes the alternative's map beside its own (model.h: kAlternativeOutput; the default's
// does, a head on its layers that gives compact-windshield-head's map: docs/RESULTS.md 4.48),
// which is then thresholded instead. Ten features of P (router_features), then a
// logistic regression fitted on validation images by tools/raindrop_tools/detector_router.py:
//   z = bias + sum_i weight_i (f_i - mean_i) / std_i;  z > 0: the alternative decides the mask.
// The file (docs/CONTRACTS.md, "Detector router"):
//   # comments
//   format 1
//   alternative <a sibling model folder: its rdn.onnx, threshold, dilation and growth>
//   mean <10 numbers>  std <10 positive numbers>  weight <10 numbers>  bias <number>
// one key per line.
#include <array>
#include <filesystem>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

namespace raindrop::removal {

inline constexpr int kRouterFeatures = 10;
using RouterFeatures = std::array<double, kRouterFeatures>;

// The features of a probability map (CV_32F, HxW, the image's own pixels, no padding), in this
// order: the shares of P > 0.3, of 0.05 < P <= 0.3, the mean of P, the share of P > 0.02; then
// for t = 0.05, 0.15, 0.3, of the 8-connected parts of P > t: how many have at most 30 pixels
// per 10^4 pixels, and their median area (the mean of the middle two for an even count; 0
// without parts). Each f as log(1 + 100 f). Comparisons in float, as the fitting tool's numpy.
RouterFeatures router_features(const cv::Mat& prob);

struct DetectorRouter {
  std::string alternative;  // the sibling model folder's name
  RouterFeatures mean{}, std{}, weight{};
  double bias = 0;

  // z of the features above: above 0, the alternative's detector decides the mask.
  double score(const RouterFeatures& f) const;
};

// The ROUTER file of `model_dir`; std::nullopt without one; raindrop::Error naming the file and
// what is wrong with it otherwise (so that a damaged file never routes silently).
std::optional<DetectorRouter> read_detector_router(const std::filesystem::path& model_dir);

}  // namespace raindrop::removal

#pragma once
// A camera's wet gate: whether an image holds drops at all, judged from the detector's maps,
// so that a frame of a dry lens is left exactly as it is.
//
// A pipeline runs raindrop-remove on every frame a camera takes, wet or dry, and on a dry frame
// every change is damage. On street frames the damage is small, but on a camera that looks into
// overexposed sky through a lens cover the detector takes sky, clouds and the edges of foliage
// for drops: on the real pairs' dry lens the default marked 39% of each frame and left it 27.8 dB
// from its input (docs/RESULTS.md 4.70). No gate fitted on many cameras at once tells such frames
// from wet ones (it passed over only 11-50% of the test sets' dry frames, and 5 of the 44 photographs, all with
// drops), but one fitted on a camera's own wet and dry frames does: a user labels frames, not
// pixels, and `python -m raindrop_tools.wet_gate fit` writes the file (docs/RESULTS.md 4.72).
//
// The features are the router's ten (detector_router.h) of the main detector's map at the
// automatic working scale, and with `maps 2` also of the second map the default's graph computes
// (model.h: kAlternativeOutput). A logistic score, its threshold folded into the bias:
//   z = bias + sum_i weight_i (f_i - mean_i) / std_i;  z > 0: wet (the image is processed),
//   z <= 0: dry (the output is the input, the mask empty).
// The file (docs/CONTRACTS.md, "Wet gate"):
//   # comments
//   format 1
//   models <the model folder whose detector it was fitted on>
//   maps <1 or 2>
//   mean <10 x maps numbers>  std <10 x maps positive numbers>  weight <10 x maps numbers>
//   bias <number>
// one key per line.
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "raindrop/remove/model.h"

namespace raindrop::removal {

struct WetGate {
  std::filesystem::path file;  // where it was read from, for messages
  std::string models;          // the model folder's name (its last path component)
  int maps = 1;
  std::vector<double> mean, std, weight;  // 10 x maps each
  double bias = 0;

  // z of the maps (CV_32F, the image's own pixels at the working scale); `alternative` is read
  // only with maps 2. Above 0: wet.
  double score(const cv::Mat& prob, const cv::Mat& alternative) const;
};

// Reads and checks a wet gate file; raindrop::Error naming it and what is wrong otherwise.
WetGate read_wet_gate(const std::filesystem::path& file);

// raindrop::Error unless `gate` was fitted on the detector of the models in `model_dir` (with
// `info`): the same folder name, or its int8 copy or the float folder that copy was made from
// (the name with or without the suffix -int8: the same detector, quantised), and with maps 2 a
// graph that computes the second map.
void check_wet_gate(const WetGate& gate, const std::filesystem::path& model_dir, const ModelInfo& info);

}  // namespace raindrop::removal

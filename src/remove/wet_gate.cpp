#include "raindrop/remove/wet_gate.h"

#include "raindrop/common/error.h"
#include "raindrop/remove/detector_router.h"
#include "raindrop/remove/key_file.h"

namespace raindrop::removal {
namespace fs = std::filesystem;
namespace {

// The name a model folder goes by: the last component of its absolute path, symbolic links not
// followed ("models/compact/" and "." inside it are "compact"), as wet_gate.py's folder_name.
std::string folder_name(const fs::path& dir) {
  std::error_code ec;
  fs::path normal = fs::absolute(dir, ec);
  normal = (ec ? dir : normal).lexically_normal();
  return (normal.has_filename() ? normal.filename() : normal.parent_path().filename()).string();
}

std::string float_twin(const std::string& name) {
  const std::string suffix = "-int8";
  const bool int8 = name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
  return int8 ? name.substr(0, name.size() - suffix.size()) : name;
}

}  // namespace

double WetGate::score(const cv::Mat& prob, const cv::Mat& alternative) const {
  double z = bias;
  for (int m = 0; m < maps; ++m) {
    const RouterFeatures f = router_features(m == 0 ? prob : alternative);
    for (int i = 0; i < kRouterFeatures; ++i) {
      const size_t k = static_cast<size_t>(m * kRouterFeatures + i);
      z += weight[k] * (f[i] - mean[k]) / std[k];
    }
  }
  return z;
}

WetGate read_wet_gate(const fs::path& file) {
  std::error_code ec;
  const auto fail = [file](const std::string& why) {
    return Error("wet gate " + quoted(file) + ": " + why + " (docs/CONTRACTS.md, \"Wet gate\")");
  };
  if (fs::is_directory(file, ec)) throw fail("is a folder, not a file");
  const KeyFile kf = read_key_file(file, fail);
  kf.expect_format("1");
  WetGate g;
  g.file = file;
  g.models = kf.folder_name("models", "one model folder");
  const auto& maps = kf.words("maps");
  if (maps != std::vector<std::string>{"1"} && maps != std::vector<std::string>{"2"}) throw kf.fail("'maps' must be 1 or 2");
  g.maps = maps[0] == "1" ? 1 : 2;
  const size_t n = static_cast<size_t>(g.maps * kRouterFeatures);
  g.mean = kf.numbers("mean", n);
  g.std = kf.numbers("std", n, /*positive=*/true);
  g.weight = kf.numbers("weight", n);
  g.bias = kf.numbers("bias", 1)[0];
  return g;
}

void check_wet_gate(const WetGate& gate, const fs::path& model_dir, const ModelInfo& info) {
  const std::string name = folder_name(model_dir);
  const auto fail = [&](const std::string& why) {
    return Error("wet gate " + quoted(gate.file) + ": " + why + " (fit one for these models: python -m raindrop_tools.wet_gate fit --models " +
                 model_dir.string() + ")");
  };
  if (float_twin(name) != float_twin(gate.models))
    throw fail("fitted on the detector of '" + gate.models + "', not of '" + name + "'");
  if (gate.maps > 1 && info.alternative_detector.empty())
    throw fail("fitted on two detector maps, and '" + name + "''s detector computes one");
}

}  // namespace raindrop::removal

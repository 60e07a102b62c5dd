#pragma once
// The three ONNX graphs of a model folder (docs/CONTRACTS.md section 2), loaded and checked
// against the contract before any image is touched: a wrong, corrupt or mismatched file is a
// one-line raindrop::Error that names the file, not a crash in the middle of a batch.
//
//   rdn.onnx  image [N,3,H,W]                 -> mask_prob [N,1,H,W]
//                                                [, alternative_mask_prob [N,1,H,W]]
//   rrn.onnx  image [N,3,H,W], edge [N,1,H,W] -> reconstruction [N,3,H,W]
//   rfn.onnx  blend [N,3,H,W]                 -> restored [N,3,H,W]
//
// float32 everywhere; H and W must be dynamic (any image size); N dynamic or 1.
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <onnxruntime_cxx_api.h>

#include "raindrop/remove/session.h"
#include "raindrop/remove/surround_fill.h"

namespace raindrop::removal {

// The largest mask dilation k (a k x k ellipse), for --dilation and the models'
// raindrop.dilation alike: the drops the networks see are 10-40 px across, so anything near
// this is already a mistake, and a k of 99999 would dilate for minutes.
inline constexpr int kMaxDilation = 1023;

// The largest large-drop growth (large_drops.h), for --large-drop-growth and the models'
// raindrop.large_drop_growth alike: at 10 a drop's mask grows by five diameters all round.
inline constexpr double kMaxLargeDropGrowth = 10.0;

// The optional second output of rdn.onnx: another detector's map, computed by the same graph
// (a second head on the same layers), so that a router's alternative costs one convolution
// instead of a second network (detector_router.h). rdn.onnx then names that detector's folder
// in raindrop.alternative_detector.
inline constexpr const char* kAlternativeOutput = "alternative_mask_prob";

// The raindrop.* metadata the three graphs agree on.
struct ModelInfo {
  std::string config;     // raindrop.config, e.g. "compact"
  int pad_multiple = 2;   // lcm of 2 and the graphs' raindrop.pad_multiple (model.cpp says why 2)
  double threshold = 0.5; // raindrop.threshold of rdn.onnx (the training default), in (0, 1)
  int dilation = 1;       // raindrop.dilation of rdn.onnx, 1..kMaxDilation
  // Optional raindrop.large_drop_growth of rdn.onnx, 0..kMaxLargeDropGrowth: in the coarse pass
  // for large drops, each drop's mask dilation grows with its size (large_drops.h); 0 (absent):
  // k for every drop there too.
  double large_drop_growth = 0;
  // Optional raindrop.surround_fill_area of rdn.onnx, a whole number >= 0: the largest part of
  // the mask this detector's images fill from their surroundings (surround_fill.h), given with
  // the long side at 512; RemoveOptions::surround_fill_area overrides it. kSurroundFillArea
  // where absent.
  int surround_fill_area = kSurroundFillArea;
  // Optional raindrop.working_size of rdn.onnx: the long side, in pixels, of the frames the
  // networks were trained on (working_scale.h); 512 when absent (the committed models).
  int working_size = 512;
  // raindrop.alternative_detector of an rdn.onnx with the output kAlternativeOutput: the sibling
  // model folder whose rdn.onnx computes that output's map as its own mask_prob (the same bits,
  // tools/raindrop_tools/shared_detector.py); empty for a graph without it.
  std::string alternative_detector;
};

// One graph and its session. Inputs and outputs are single images (N = 1) in NCHW float32.
class Network {
 public:
  // name: "rdn", "rrn" or "rfn" (decides the expected inputs and outputs).
  Network(const std::filesystem::path& file, const std::string& name, const SessionConfig& config);

  // inputs: one pointer per contract input, in contract order (rrn: image, edge), each
  // holding channels x h x w floats; output: out_channels x h x w floats, written in place;
  // alternative (only for a graph with has_alternative_output()): h x w floats, that output's.
  void run(const std::vector<const float*>& inputs, int h, int w, float* output, float* alternative = nullptr);

  const std::string& name() const { return name_; }
  const std::filesystem::path& file() const { return file_; }
  const std::map<std::string, std::string>& metadata() const { return metadata_; }
  int output_channels() const { return out_channels_; }
  bool has_alternative_output() const { return !alternative_output_.empty(); }

 private:
  std::string name_;
  std::filesystem::path file_;
  std::unique_ptr<Ort::Session> session_;
  std::vector<std::string> input_names_;  // contract order
  std::vector<int> input_channels_;
  std::string output_name_;
  std::string alternative_output_;  // kAlternativeOutput where the graph has it, else empty
  int out_channels_ = 0;
  std::map<std::string, std::string> metadata_;
  Ort::MemoryInfo memory_;
};

// rdn.onnx, rrn.onnx and rfn.onnx of one folder, with their metadata cross-checked.
//
// RDN and 3RN both read only the input, so with two or more CPU threads a single-tile image
// runs them side by side, each session on half the threads, and RFN after them on all. The
// narrow layers of a compact model scale poorly when one convolution is split over both
// cores (2 threads were slower than 1 at 256x512); two independent graphs on two cores do
// not share that cost. Tiled images run their tiles in order with every stage on all the
// threads (pairing tiles left a core idle on an odd tile count: 17% slower for the paper's
// networks on 2048x1024), from RDN and 3RN sessions made on the first tiled image (the RDN's
// alone on the first fine pass, fine_drops.h, which runs nothing beside its detector).
class Models {
 public:
  // Which graphs to load: all three; the 3RN and RFN only (models that reconstruct what
  // another model's detector found: the large drops of large_drops.h); or the RDN only (a
  // detector that decides another model's mask: detector_router.h). Without a detector,
  // info() holds the config name and pad multiple only, and rdn()/rdn_beside() throw; without
  // the reconstruction, rrn()/rrn_beside()/rfn() throw.
  // Or the RDN's metadata only, read from the file without a session (info() as for detection;
  // no graph runs): a router's alternative whose map the main graph computes (kAlternativeOutput).
  enum class Graphs { all, reconstruction, detection, metadata };
  Models(const std::filesystem::path& dir, const SessionConfig& config, Graphs graphs = Graphs::all);
  // 2 when RDN and 3RN run side by side (CPU, two or more threads), else 1.
  int branches() const { return branches_; }
  // Sessions on branches() == 2's half of the threads (all of them when branches() == 1).
  Network& rdn_beside();
  Network& rrn_beside();
  // Sessions on all the threads (thread-safe; made on first use when branches() == 2).
  Network& rdn();
  Network& rrn();
  Network& rfn();
  const ModelInfo& info() const { return info_; }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
  SessionConfig config_;
  std::unique_ptr<Network> rdn_, rrn_, rfn_;
  std::unique_ptr<Network> rdn_all_, rrn_all_;
  std::once_flag rdn_all_once_, rrn_all_once_;
  ModelInfo info_;
  int branches_ = 1;
};

}  // namespace raindrop::removal

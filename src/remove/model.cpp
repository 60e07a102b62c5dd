#include "raindrop/remove/model.h"

#include <algorithm>
#include <cmath>
#include <future>
#include <numeric>
#include <system_error>
#include <thread>

#include "raindrop/common/error.h"

namespace raindrop::removal {
namespace fs = std::filesystem;
namespace {

struct Contract {
  std::vector<std::string> inputs;
  std::vector<int> input_channels;
  std::string output;
  int output_channels;
};

const Contract& contract_for(const std::string& name) {
  static const std::map<std::string, Contract> contracts = {
      {"rdn", {{"image"}, {3}, "mask_prob", 1}},
      {"rrn", {{"image", "edge"}, {3, 1}, "reconstruction", 3}},
      {"rfn", {{"blend"}, {3}, "restored", 3}},
  };
  const auto it = contracts.find(name);
  if (it == contracts.end()) throw Error("unknown network '" + name + "' (expected rdn, rrn or rfn)");
  return it->second;
}

const char* const kMetaKeys[] = {"raindrop.pad_multiple", "raindrop.config", "raindrop.network",
                                 "raindrop.threshold", "raindrop.dilation"};

std::string join(const std::vector<std::string>& v) {
  std::string s = "[";
  for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + v[i];
  return s + "]";
}

std::string shape_text(const std::vector<int64_t>& shape) {
  std::string s = "[";
  for (size_t i = 0; i < shape.size(); ++i) s += (i ? "," : "") + (shape[i] < 0 ? std::string("?") : std::to_string(shape[i]));
  return s + "]";
}

// Checks one tensor declaration: float32, [N, channels, H, W] with H and W dynamic.
void check_tensor(const fs::path& file, const std::string& what, const Ort::TypeInfo& type, int channels) {
  if (type.GetONNXType() != ONNX_TYPE_TENSOR) throw Error(quoted(file) + ": " + what + " is not a tensor");
  const auto info = type.GetTensorTypeAndShapeInfo();
  if (info.GetElementType() != ONNX_TENSOR_ELEMENT_DATA_TYPE_FLOAT)
    throw Error(quoted(file) + ": " + what + " is not float32");
  const auto shape = info.GetShape();
  const std::string expected = "[N," + std::to_string(channels) + ",H,W]";
  if (shape.size() != 4)
    throw Error(quoted(file) + ": " + what + " has shape " + shape_text(shape) + ", expected " + expected);
  if (shape[1] != channels || (shape[0] >= 0 && shape[0] != 1))
    throw Error(quoted(file) + ": " + what + " has shape " + shape_text(shape) + ", expected " + expected);
  if (shape[2] >= 0 || shape[3] >= 0)
    throw Error(quoted(file) + ": " + what + " has a fixed height/width " + shape_text(shape) +
                "; the contract needs dynamic H and W");
}

int parse_int(const fs::path& file, const std::string& key, const std::string& text) {
  size_t used = 0;
  int v = 0;
  try {
    v = std::stoi(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || text.empty()) throw Error(quoted(file) + ": metadata " + key + " = '" + text + "' is not an integer");
  return v;
}

double parse_double(const fs::path& file, const std::string& key, const std::string& text) {
  size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || text.empty() || !std::isfinite(v))
    throw Error(quoted(file) + ": metadata " + key + " = '" + text + "' is not a number");
  return v;
}

}  // namespace

Network::Network(const fs::path& file, const std::string& name, const SessionConfig& config)
    : name_(name), file_(file), memory_(Ort::MemoryInfo::CreateCpu(OrtArenaAllocator, OrtMemTypeDefault)) {
  const Contract& c = contract_for(name);
  std::error_code ec;
  if (!fs::exists(file, ec)) throw Error(quoted(file) + ": model file missing (a model folder holds rdn.onnx, rrn.onnx, rfn.onnx)");
  if (!fs::is_regular_file(file, ec)) throw Error(quoted(file) + ": not a file");
  if (fs::file_size(file, ec) == 0) throw Error(quoted(file) + ": model file is empty");
  Ort::SessionOptions options = make_session_options(config);
  try {
    session_ = std::make_unique<Ort::Session>(ort_env(), file.c_str(), options);
  } catch (const Ort::Exception& e) {
    throw Error(quoted(file) + ": ONNX Runtime cannot load it (" + one_line(e.what()) + ")");
  }
  Ort::AllocatorWithDefaultOptions alloc;
  std::vector<std::string> inputs, outputs;
  for (size_t i = 0; i < session_->GetInputCount(); ++i) inputs.push_back(session_->GetInputNameAllocated(i, alloc).get());
  for (size_t i = 0; i < session_->GetOutputCount(); ++i) outputs.push_back(session_->GetOutputNameAllocated(i, alloc).get());
  std::vector<std::string> sorted_in = inputs, sorted_want = c.inputs;
  std::sort(sorted_in.begin(), sorted_in.end());
  std::sort(sorted_want.begin(), sorted_want.end());
  if (sorted_in != sorted_want || outputs != std::vector<std::string>{c.output})
    throw Error(quoted(file) + ": inputs " + join(inputs) + " / outputs " + join(outputs) + ", expected " + join(c.inputs) +
                " / [" + c.output + "] (is this the " + name + " graph?)");
  // Check every declared shape, matching inputs by name (their order in the graph is free).
  for (size_t i = 0; i < inputs.size(); ++i) {
    const size_t k = static_cast<size_t>(std::find(c.inputs.begin(), c.inputs.end(), inputs[i]) - c.inputs.begin());
    check_tensor(file, "input '" + inputs[i] + "'", session_->GetInputTypeInfo(i), c.input_channels[k]);
  }
  check_tensor(file, "output '" + c.output + "'", session_->GetOutputTypeInfo(0), c.output_channels);
  input_names_ = c.inputs;
  input_channels_ = c.input_channels;
  output_name_ = c.output;
  out_channels_ = c.output_channels;

  const Ort::ModelMetadata meta = session_->GetModelMetadata();
  for (const auto& key : meta.GetCustomMetadataMapKeysAllocated(alloc)) {
    const std::string k = key.get();
    metadata_[k] = meta.LookupCustomMetadataMapAllocated(k.c_str(), alloc).get();
  }
  std::vector<std::string> missing;
  for (const char* k : kMetaKeys) {
    if (!metadata_.count(k)) missing.push_back(k);
  }
  if (!missing.empty()) throw Error(quoted(file) + ": metadata missing " + join(missing) + " (export it with raindrop_tools.export)");
  if (metadata_["raindrop.network"] != name)
    throw Error(quoted(file) + ": raindrop.network is '" + metadata_["raindrop.network"] + "', expected '" + name + "'");
}

void Network::run(const std::vector<const float*>& inputs, int h, int w, float* output) {
  if (inputs.size() != input_names_.size()) throw Error(name_ + ": wrong number of inputs");
  std::vector<Ort::Value> values;
  std::vector<const char*> names;
  for (size_t i = 0; i < inputs.size(); ++i) {
    const int64_t shape[4] = {1, input_channels_[i], h, w};
    const size_t count = static_cast<size_t>(input_channels_[i]) * h * w;
    // ONNX Runtime does not write to inputs; the API just has no const overload.
    values.push_back(Ort::Value::CreateTensor<float>(memory_, const_cast<float*>(inputs[i]), count, shape, 4));
    names.push_back(input_names_[i].c_str());
  }
  const int64_t out_shape[4] = {1, out_channels_, h, w};
  Ort::Value out = Ort::Value::CreateTensor<float>(memory_, output, static_cast<size_t>(out_channels_) * h * w, out_shape, 4);
  const char* out_name = output_name_.c_str();
  try {
    session_->Run(Ort::RunOptions{nullptr}, names.data(), values.data(), values.size(), &out_name, &out, 1);
  } catch (const Ort::Exception& e) {
    throw Error(quoted(file_) + ": inference failed on a " + std::to_string(w) + "x" + std::to_string(h) + " image (" +
                one_line(e.what()) + ")");
  }
}

Models::Models(const fs::path& dir, const SessionConfig& config, Graphs graphs) : dir_(dir), config_(config) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error("model folder " + quoted(dir) + " does not exist");
  if (config.threads < 0) throw Error("--threads must be >= 0 (0: ONNX Runtime's default)");
  const int threads = config.threads > 0 ? config.threads : static_cast<int>(std::thread::hardware_concurrency());
  SessionConfig branch = config;
  if (config.device == Device::cpu && threads >= 2) {
    branches_ = 2;
    branch.threads = threads / 2;
  }
  // Loading a graph (parsing, optimising, packing its weights) runs on one thread: the first
  // graph loads on a second thread beside the others (on two cores, a process that removes
  // drops from a 32x32 image took a median 68 ms instead of 75: docs/RESULTS.md 3.6). An error
  // from either is thrown here.
  const bool detector = graphs != Graphs::reconstruction;
  auto load = [&dir](const char* name, const SessionConfig& c) {
    return std::make_unique<Network>(dir / (std::string(name) + ".onnx"), name, c);
  };
  // The environment first, on this thread: creating it sets the process environment
  // (turn_off_onnxruntime_telemetry), which must not race the loading thread's getenv calls.
  ort_env();
  if (graphs == Graphs::detection) {
    // One graph, on all the threads: a router's alternative detector runs after the first
    // detector and the 3RN beside it, when both cores are free (remover.cpp).
    rdn_ = load("rdn", config);
  } else {
    std::future<std::unique_ptr<Network>> first = std::async(std::launch::async, load, detector ? "rdn" : "rrn", branch);
    try {
      if (detector) rrn_ = load("rrn", branch);
      rfn_ = load("rfn", config);
    } catch (...) {
      first.wait();  // it reads `dir` and `branch`: done before they go
      throw;
    }
    (detector ? rdn_ : rrn_) = first.get();
  }
  std::vector<Network*> loaded;
  for (Network* n : {rdn_.get(), rrn_.get(), rfn_.get()})
    if (n) loaded.push_back(n);
  const std::string cfg = loaded.front()->metadata().at("raindrop.config");
  for (Network* n : loaded) {
    if (n->metadata().at("raindrop.config") != cfg)
      throw Error("model folder " + quoted(dir) + ": the graphs come from different configurations ('" + cfg + "' and '" +
                  n->metadata().at("raindrop.config") + "')");
  }
  info_.config = cfg;
  // At least 2, whatever the graphs say: the RDN and 3RN run their blocks at half resolution
  // (a stride-2 convolution), and were trained on even-sized crops. At an odd height the
  // bottom border falls on the other phase of that stride-2 grid, and the networks' last rows
  // there come out wrong: measured on real drops at 77 px (with the graphs of that time, which
  // replicated the border row inside; they pad with zeros since docs/RESULTS.md 3.11, as
  // unseen in training), the bottom 4 rows of the reconstruction differed from those of the
  // same image padded to even by 85 levels of 8 bits on average (up to 183), which cost 1-4 dB
  // per image once the working scale enlarged them.
  // Replicate-padding to even size removes that (tests/remove/test_trained_models.cpp,
  // TrainedModels.OddSizesAreRestoredAsWellAtTheirBorders).
  int multiple = 2;
  for (Network* n : loaded) {
    const int m = parse_int(n->file(), "raindrop.pad_multiple", n->metadata().at("raindrop.pad_multiple"));
    if (m < 1 || m > 1024) throw Error(quoted(n->file()) + ": raindrop.pad_multiple must be between 1 and 1024");
    multiple = std::lcm(multiple, m);
  }
  info_.pad_multiple = multiple;
  if (!rdn_) return;  // reconstruction only: threshold, dilation and working size are the detector's
  // Checked here, against the same ranges as --threshold and --dilation, so that a bad value
  // is blamed on the model file rather than on an option the user did not give.
  const std::string threshold = rdn_->metadata().at("raindrop.threshold");
  info_.threshold = parse_double(rdn_->file(), "raindrop.threshold", threshold);
  if (!(info_.threshold > 0 && info_.threshold < 1))
    throw Error(quoted(rdn_->file()) + ": metadata raindrop.threshold = " + threshold +
                " is not a probability strictly between 0 and 1");
  const std::string dilation = rdn_->metadata().at("raindrop.dilation");
  info_.dilation = parse_int(rdn_->file(), "raindrop.dilation", dilation);
  if (info_.dilation < 1 || info_.dilation > kMaxDilation)
    throw Error(quoted(rdn_->file()) + ": metadata raindrop.dilation = " + dilation + " must be between 1 and " +
                std::to_string(kMaxDilation));
  if (const auto it = rdn_->metadata().find("raindrop.large_drop_growth"); it != rdn_->metadata().end()) {
    info_.large_drop_growth = parse_double(rdn_->file(), "raindrop.large_drop_growth", it->second);
    if (!(info_.large_drop_growth >= 0 && info_.large_drop_growth <= kMaxLargeDropGrowth))
      throw Error(quoted(rdn_->file()) + ": metadata raindrop.large_drop_growth = " + it->second +
                  " must be between 0 and " + std::to_string(static_cast<int>(kMaxLargeDropGrowth)));
  }
  if (const auto it = rdn_->metadata().find("raindrop.surround_fill_area"); it != rdn_->metadata().end()) {
    info_.surround_fill_area = parse_int(rdn_->file(), "raindrop.surround_fill_area", it->second);
    if (info_.surround_fill_area < 0)
      throw Error(quoted(rdn_->file()) + ": metadata raindrop.surround_fill_area = " + it->second +
                  " must be a whole number >= 0 (0: off)");
  }
  if (const auto it = rdn_->metadata().find("raindrop.working_size"); it != rdn_->metadata().end()) {
    info_.working_size = parse_int(rdn_->file(), "raindrop.working_size", it->second);
    if (info_.working_size < 16 || info_.working_size > 65536)
      throw Error(quoted(rdn_->file()) + ": metadata raindrop.working_size must be between 16 and 65536");
  }
}

Network& Models::rdn_beside() {
  if (!rdn_) throw Error("model folder " + quoted(dir_) + " was loaded for reconstruction only (no detector)");
  return *rdn_;
}

Network& Models::rrn_beside() {
  if (!rrn_) throw Error("model folder " + quoted(dir_) + " was loaded for detection only (no 3RN)");
  return *rrn_;
}

Network& Models::rfn() {
  if (!rfn_) throw Error("model folder " + quoted(dir_) + " was loaded for detection only (no RFN)");
  return *rfn_;
}

// Each all-thread session is made on its own first use: the fine pass (fine_drops.h) wants the
// detector's alone, a tiled image both.
Network& Models::rdn() {
  // A detector loaded alone already runs on all the threads (the constructor says why).
  if (branches_ == 1 || !rrn_) return rdn_beside();
  rdn_beside();  // throws without a detector
  std::call_once(rdn_all_once_, [this] { rdn_all_ = std::make_unique<Network>(rdn_->file(), "rdn", config_); });
  return *rdn_all_;
}

Network& Models::rrn() {
  if (branches_ == 1) return rrn_beside();
  rrn_beside();  // throws without a 3RN
  std::call_once(rrn_all_once_, [this] { rrn_all_ = std::make_unique<Network>(rrn_->file(), "rrn", config_); });
  return *rrn_all_;
}

}  // namespace raindrop::removal

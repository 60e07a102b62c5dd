#include "raindrop/remove/model.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <future>
#include <iterator>
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
  std::string optional_output;  // a second output the graph may have (one channel), else empty
};

const Contract& contract_for(const std::string& name) {
  static const std::map<std::string, Contract> contracts = {
      {"rdn", {{"image"}, {3}, "mask_prob", 1, kAlternativeOutput}},
      {"rrn", {{"image", "edge"}, {3, 1}, "reconstruction", 3, ""}},
      {"rfn", {{"blend"}, {3}, "restored", 3, ""}},
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

// A graph's metadata holds every kMetaKeys entry and names the network `name`.
void check_metadata(const fs::path& file, const std::map<std::string, std::string>& metadata, const std::string& name) {
  std::vector<std::string> missing;
  for (const char* k : kMetaKeys) {
    if (!metadata.count(k)) missing.push_back(k);
  }
  if (!missing.empty()) throw Error(quoted(file) + ": metadata missing " + join(missing) + " (export it with raindrop_tools.export)");
  if (metadata.at("raindrop.network") != name)
    throw Error(quoted(file) + ": raindrop.network is '" + metadata.at("raindrop.network") + "', expected '" + name + "'");
}

// One varint of a protobuf message at `p` (advanced), or false past `end` or a varint too long.
bool read_varint(const unsigned char*& p, const unsigned char* end, uint64_t& v) {
  v = 0;
  for (int shift = 0; shift < 64 && p < end; shift += 7) {
    const unsigned char b = *p++;
    v |= static_cast<uint64_t>(b & 0x7f) << shift;
    if (!(b & 0x80)) return true;
  }
  return false;
}

// The metadata_props of an ONNX file (ModelProto field 14, each a message {1: key, 2: value}),
// read from the file's bytes without a session: a detector whose map another graph computes
// (model.h: kAlternativeOutput) is needed for its metadata only, and a session would parse,
// optimise and pack the whole graph for nothing (10-15 ms on a routed photograph's path).
std::map<std::string, std::string> read_metadata_only(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) throw Error(quoted(file) + ": model file missing");
  std::ifstream in(file, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!in.good() && !in.eof()) throw Error(quoted(file) + ": cannot read it");
  if (bytes.empty()) throw Error(quoted(file) + ": model file is empty");
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  const unsigned char* end = p + bytes.size();
  const std::string broken = quoted(file) + ": not an ONNX model (its metadata cannot be read)";
  std::map<std::string, std::string> meta;
  while (p < end) {
    uint64_t tag = 0, len = 0;
    if (!read_varint(p, end, tag)) throw Error(broken);
    const uint64_t field = tag >> 3, wire = tag & 7;
    if (wire == 0) {
      if (!read_varint(p, end, len)) throw Error(broken);
    } else if (wire == 1 || wire == 5) {
      const uint64_t n = wire == 1 ? 8 : 4;
      if (static_cast<uint64_t>(end - p) < n) throw Error(broken);
      p += n;
    } else if (wire == 2) {
      if (!read_varint(p, end, len) || len > static_cast<uint64_t>(end - p)) throw Error(broken);
      if (field == 14) {
        const unsigned char* q = p;
        const unsigned char* entry_end = p + len;
        std::string key, value;
        while (q < entry_end) {
          uint64_t t = 0, n = 0;
          if (!read_varint(q, entry_end, t) || (t & 7) != 2 || !read_varint(q, entry_end, n) ||
              n > static_cast<uint64_t>(entry_end - q))
            throw Error(broken);
          if ((t >> 3) == 1) key.assign(reinterpret_cast<const char*>(q), n);
          if ((t >> 3) == 2) value.assign(reinterpret_cast<const char*>(q), n);
          q += n;
        }
        meta[key] = value;
      }
      p += len;
    } else {
      throw Error(broken);
    }
  }
  return meta;
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
  const bool with_optional = !c.optional_output.empty() && outputs == std::vector<std::string>{c.output, c.optional_output};
  if (sorted_in != sorted_want || (outputs != std::vector<std::string>{c.output} && !with_optional))
    throw Error(quoted(file) + ": inputs " + join(inputs) + " / outputs " + join(outputs) + ", expected " + join(c.inputs) +
                " / [" + c.output + (c.optional_output.empty() ? "" : "] or [" + c.output + ", " + c.optional_output) +
                "] (is this the " + name + " graph?)");
  // Check every declared shape, matching inputs by name (their order in the graph is free).
  for (size_t i = 0; i < inputs.size(); ++i) {
    const size_t k = static_cast<size_t>(std::find(c.inputs.begin(), c.inputs.end(), inputs[i]) - c.inputs.begin());
    check_tensor(file, "input '" + inputs[i] + "'", session_->GetInputTypeInfo(i), c.input_channels[k]);
  }
  check_tensor(file, "output '" + c.output + "'", session_->GetOutputTypeInfo(0), c.output_channels);
  if (with_optional) {
    check_tensor(file, "output '" + c.optional_output + "'", session_->GetOutputTypeInfo(1), 1);
    alternative_output_ = c.optional_output;
  }
  input_names_ = c.inputs;
  input_channels_ = c.input_channels;
  output_name_ = c.output;
  out_channels_ = c.output_channels;

  const Ort::ModelMetadata meta = session_->GetModelMetadata();
  for (const auto& key : meta.GetCustomMetadataMapKeysAllocated(alloc)) {
    const std::string k = key.get();
    metadata_[k] = meta.LookupCustomMetadataMapAllocated(k.c_str(), alloc).get();
  }
  check_metadata(file, metadata_, name);
}

void Network::run(const std::vector<const float*>& inputs, int h, int w, float* output, float* alternative) {
  if (alternative && alternative_output_.empty())
    throw Error(quoted(file_) + ": has no output '" + std::string(kAlternativeOutput) + "'");
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
  const int64_t alternative_shape[4] = {1, 1, h, w};
  Ort::Value outs[2] = {
      Ort::Value::CreateTensor<float>(memory_, output, static_cast<size_t>(out_channels_) * h * w, out_shape, 4),
      alternative ? Ort::Value::CreateTensor<float>(memory_, alternative, static_cast<size_t>(h) * w, alternative_shape, 4)
                  : Ort::Value(nullptr)};
  const char* out_names[2] = {output_name_.c_str(), alternative_output_.c_str()};
  try {
    session_->Run(Ort::RunOptions{nullptr}, names.data(), values.data(), values.size(), out_names, outs, alternative ? 2 : 1);
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
  std::map<std::string, std::string> metadata_only;  // Graphs::metadata: rdn.onnx's, read without a session
  if (graphs == Graphs::metadata) {
    metadata_only = read_metadata_only(dir / "rdn.onnx");
    check_metadata(dir / "rdn.onnx", metadata_only, "rdn");
  } else if (graphs == Graphs::detection) {
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
  // Each graph's file and metadata (checked for the kMetaKeys already).
  std::vector<std::pair<fs::path, const std::map<std::string, std::string>*>> loaded;
  if (graphs == Graphs::metadata) loaded.emplace_back(dir / "rdn.onnx", &metadata_only);
  for (Network* n : {rdn_.get(), rrn_.get(), rfn_.get()})
    if (n) loaded.emplace_back(n->file(), &n->metadata());
  const std::string cfg = loaded.front().second->at("raindrop.config");
  for (const auto& [file, meta] : loaded) {
    if (meta->at("raindrop.config") != cfg)
      throw Error("model folder " + quoted(dir) + ": the graphs come from different configurations ('" + cfg + "' and '" +
                  meta->at("raindrop.config") + "')");
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
  for (const auto& [file, meta] : loaded) {
    const int m = parse_int(file, "raindrop.pad_multiple", meta->at("raindrop.pad_multiple"));
    if (m < 1 || m > 1024) throw Error(quoted(file) + ": raindrop.pad_multiple must be between 1 and 1024");
    multiple = std::lcm(multiple, m);
  }
  info_.pad_multiple = multiple;
  if (!detector) return;  // reconstruction only: threshold, dilation and working size are the detector's
  const fs::path& rdn_file = loaded.front().first;
  const std::map<std::string, std::string>& rdn_meta = *loaded.front().second;
  // Checked here, against the same ranges as --threshold and --dilation, so that a bad value
  // is blamed on the model file rather than on an option the user did not give.
  const std::string threshold = rdn_meta.at("raindrop.threshold");
  info_.threshold = parse_double(rdn_file, "raindrop.threshold", threshold);
  if (!(info_.threshold > 0 && info_.threshold < 1))
    throw Error(quoted(rdn_file) + ": metadata raindrop.threshold = " + threshold +
                " is not a probability strictly between 0 and 1");
  const std::string dilation = rdn_meta.at("raindrop.dilation");
  info_.dilation = parse_int(rdn_file, "raindrop.dilation", dilation);
  if (info_.dilation < 1 || info_.dilation > kMaxDilation)
    throw Error(quoted(rdn_file) + ": metadata raindrop.dilation = " + dilation + " must be between 1 and " +
                std::to_string(kMaxDilation));
  if (const auto it = rdn_meta.find("raindrop.large_drop_growth"); it != rdn_meta.end()) {
    info_.large_drop_growth = parse_double(rdn_file, "raindrop.large_drop_growth", it->second);
    if (!(info_.large_drop_growth >= 0 && info_.large_drop_growth <= kMaxLargeDropGrowth))
      throw Error(quoted(rdn_file) + ": metadata raindrop.large_drop_growth = " + it->second +
                  " must be between 0 and " + std::to_string(static_cast<int>(kMaxLargeDropGrowth)));
  }
  if (const auto it = rdn_meta.find("raindrop.surround_fill_area"); it != rdn_meta.end()) {
    info_.surround_fill_area = parse_int(rdn_file, "raindrop.surround_fill_area", it->second);
    if (info_.surround_fill_area < 0)
      throw Error(quoted(rdn_file) + ": metadata raindrop.surround_fill_area = " + it->second +
                  " must be a whole number >= 0 (0: off)");
  }
  // A second head's map must say whose it is; the name alone is no map.
  const auto alternative = rdn_meta.find("raindrop.alternative_detector");
  const bool named = alternative != rdn_meta.end();
  // (Without a session the outputs are not known: a detector loaded for its metadata is not run.)
  if (rdn_ && named != rdn_->has_alternative_output())
    throw Error(quoted(rdn_file) + (named ? ": metadata raindrop.alternative_detector without the output '"
                                              : ": the output '") +
                kAlternativeOutput + (named ? "'" : "' without metadata raindrop.alternative_detector"));
  if (named) {
    const std::string& folder = alternative->second;
    if (folder.empty() || folder == "." || folder == ".." || folder.find('/') != std::string::npos)
      throw Error(quoted(rdn_file) + ": metadata raindrop.alternative_detector = '" + folder +
                  "' must name one sibling model folder");
    info_.alternative_detector = folder;
  }
  if (const auto it = rdn_meta.find("raindrop.working_size"); it != rdn_meta.end()) {
    info_.working_size = parse_int(rdn_file, "raindrop.working_size", it->second);
    if (info_.working_size < 16 || info_.working_size > 65536)
      throw Error(quoted(rdn_file) + ": metadata raindrop.working_size must be between 16 and 65536");
  }
}

Network& Models::rdn_beside() {
  if (!rdn_) throw Error("model folder " + quoted(dir_) + " was loaded without its detector's graph");
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

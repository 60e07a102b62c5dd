#pragma once
// ONNX Runtime set-up shared by the three graphs: one process-wide environment and the
// session options raindrop-remove exposes (threads, graph optimisation level, device).
//
// The library is ONNX Runtime 1.31 from the PyPI wheel, compiled against the 1.21 headers
// (docs/DESIGN.md section 7). That wheel is CPU-only: asking for CUDA is an error that says
// which providers this build has, instead of a silent fall-back to the CPU. The opt-in GPU
// build (-DRAINDROP_ONNXRUNTIME_GPU=ON) has the CUDA provider.
#include <map>
#include <string>
#include <vector>

#include <onnxruntime_cxx_api.h>

namespace raindrop::removal {

enum class Device { cpu, cuda };
enum class GraphOpt { disable, basic, extended, all };

struct SessionConfig {
  int threads = 0;  // intra-op threads; 0: ONNX Runtime's default (one per physical core)
  Device device = Device::cpu;
  GraphOpt graph_opt = GraphOpt::all;  // what the Python reference uses too
  int cuda_device = 0;
};

// The names of the choices on the command line ("cpu", "cuda"; "disable", "basic",
// "extended", "all"), for parsing them straight into the enums, and back.
const std::map<std::string, Device>& device_names();
const std::map<std::string, GraphOpt>& graph_opt_names();
const char* to_string(Device d);
const char* to_string(GraphOpt g);

// The process-wide environment (created on first use; logs only errors, so that ONNX
// Runtime's warnings do not break the one-line-error rule of the command-line programs).
Ort::Env& ort_env();

// Execution providers compiled into the loaded library, e.g. {"CPUExecutionProvider"}.
std::vector<std::string> available_providers();

// Options for one session. Throws raindrop::Error naming the available providers when
// Device::cuda is asked for and the library has no CUDA provider.
Ort::SessionOptions make_session_options(const SessionConfig& config);

// "ONNX Runtime 1.31.1 (API 21)": the loaded library's version and the API level we use.
std::string ort_description();

}  // namespace raindrop::removal

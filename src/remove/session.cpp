#include "raindrop/remove/session.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>

#include <dlfcn.h>

#include "raindrop/common/error.h"
#include "raindrop/remove/int8_precision.h"

namespace raindrop::removal {

const std::map<std::string, Device>& device_names() {
  static const std::map<std::string, Device> names{{"cpu", Device::cpu}, {"cuda", Device::cuda}};
  return names;
}

const std::map<std::string, GraphOpt>& graph_opt_names() {
  static const std::map<std::string, GraphOpt> names{
      {"disable", GraphOpt::disable}, {"basic", GraphOpt::basic}, {"extended", GraphOpt::extended}, {"all", GraphOpt::all}};
  return names;
}

const char* to_string(Device d) { return d == Device::cuda ? "cuda" : "cpu"; }

const char* to_string(GraphOpt g) {
  switch (g) {
    case GraphOpt::disable: return "disable";
    case GraphOpt::basic: return "basic";
    case GraphOpt::extended: return "extended";
    case GraphOpt::all: return "all";
  }
  return "?";
}

void turn_off_onnxruntime_telemetry() {
  const char* set = std::getenv("ORT_DISABLE_TELEMETRY");
  if (!set || !*set) ::setenv("ORT_DISABLE_TELEMETRY", "1", /*overwrite=*/1);
}

std::string onnxruntime_telemetry_state() {
  const char* set = std::getenv("ORT_DISABLE_TELEMETRY");
  std::string v = set ? set : "";
  v.erase(0, v.find_first_not_of(" \t"));
  v.erase(v.find_last_not_of(" \t") + 1);
  for (char& c : v) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const bool off = v == "1" || v == "true" || v == "yes" || v == "y" || v == "on";
  const std::string said = set ? std::string("ORT_DISABLE_TELEMETRY=") + set : "ORT_DISABLE_TELEMETRY unset";
  return off ? "ONNX Runtime telemetry off (" + said + ")" : "ONNX Runtime telemetry ON (" + said + " in the environment)";
}

Ort::Env& ort_env() {
  // Function-local static: created on first use, after main() has started, and destroyed
  // after every session (sessions are owned by objects with shorter lives).
  // Logging at FATAL only: ONNX Runtime prints every failed operator (an allocation that does
  // not fit, say) as its own coloured, multi-line log record before returning the same error
  // as a status, which Network::run turns into our one-line message; at ERROR level the user
  // saw both. What it reports through the API is unchanged.
  //
  // One CPU memory arena for every session (session.use_env_allocators in
  // make_session_options): RDN and 3RN (side by side), then RFN, then the large-drop pass's
  // networks draw on the same memory, where each session's own arena would take its own fresh
  // memory. A process removes one image's drops through memory it touches for the first time,
  // and each first touch of a page costs a page fault: the shared arena saves a quarter of them
  // (95,000 to 69,000 on a rendered 1280x720 frame), 13-30 ms of its 0.4 s, and a third of the
  // peak memory (357 to 253 MB), with the same output (docs/RESULTS.md 3.6).
  static Ort::Env env = [] {
    turn_off_onnxruntime_telemetry();  // before the environment: ONNX Runtime reads it then
    Ort::Env e(ORT_LOGGING_LEVEL_FATAL, "raindrop-remove");
    const Ort::MemoryInfo cpu = Ort::MemoryInfo::CreateCpu(OrtArenaAllocator, OrtMemTypeDefault);
    const Ort::ArenaCfg arena(0, -1, -1, -1);  // ONNX Runtime's defaults: no limit, grow by powers of two
    e.CreateAndRegisterAllocator(cpu, arena);
    return e;
  }();
  return env;
}

std::vector<std::string> available_providers() { return Ort::GetAvailableProviders(); }

namespace {

// Why the CUDA provider library beside the loaded libonnxruntime does not load, in the
// dynamic loader's words ("libcublasLt.so.13: cannot open shared object file: ..."); empty if
// it loads. ONNX Runtime itself only says "Failed to load shared library" (its log, where the
// loader's reason goes, is off: ort_env).
std::string cuda_provider_load_error() {
  Dl_info info{};
  if (!::dladdr(reinterpret_cast<void*>(&OrtGetApiBase), &info) || !info.dli_fname) return {};
  const auto lib = std::filesystem::path(info.dli_fname).parent_path() / "libonnxruntime_providers_cuda.so";
  void* handle = ::dlopen(lib.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle) {
    ::dlclose(handle);
    return {};
  }
  const char* why = ::dlerror();
  return why ? why : "";
}

}  // namespace

Ort::SessionOptions make_session_options(const SessionConfig& config) {
  if (config.threads < 0) throw Error("--threads must be >= 0 (0: ONNX Runtime's default)");
  Ort::SessionOptions so;
  if (config.threads > 0) so.SetIntraOpNumThreads(config.threads);
  // The graphs are chains: parallelism is inside the operators, not between them.
  so.SetInterOpNumThreads(1);
  so.SetExecutionMode(ORT_SEQUENTIAL);
  // Idle workers sleep instead of spinning. The remover runs more threads than cores by design
  // (the 3RN beside the RDN, the coarse pass beside both, each session with its own pool), and
  // a worker that spins between operators takes a core from the thread beside it. On two
  // cores, process start to file, the same bytes: a routed 1280x720 photograph 1.15x faster, a
  // kept one 1.07x, int8 1.10x, a folder of 512x256 frames 1.19x; one thread has no workers
  // and does not change (docs/RESULTS.md 3.19).
  so.AddConfigEntry(kIntraOpSpinningKey, "0");
  if (config.device == Device::cpu) {
    // The environment's shared CPU arena (ort_env); a CUDA session keeps its own allocators.
    so.AddConfigEntry("session.use_env_allocators", "1");
    // int8 graphs: exact integer products where the CPU's fast ones saturate (int8_precision.h),
    // so that an int8 folder gives the same output on every x86 CPU.
    if (int8_products_saturate()) so.AddConfigEntry("session.x64quantprecision", "1");
  }
  switch (config.graph_opt) {
    case GraphOpt::disable: so.SetGraphOptimizationLevel(ORT_DISABLE_ALL); break;
    case GraphOpt::basic: so.SetGraphOptimizationLevel(ORT_ENABLE_BASIC); break;
    case GraphOpt::extended: so.SetGraphOptimizationLevel(ORT_ENABLE_EXTENDED); break;
    case GraphOpt::all: so.SetGraphOptimizationLevel(ORT_ENABLE_ALL); break;
  }
  if (config.device == Device::cuda) {
    const auto providers = available_providers();
    if (std::find(providers.begin(), providers.end(), "CUDAExecutionProvider") == providers.end()) {
      std::string list;
      for (const auto& p : providers) list += (list.empty() ? "" : ", ") + p;
      throw Error("--device cuda: this ONNX Runtime build (" + ort_description() +
                  ") has no CUDA execution provider (available: " + list +
                  "); use --device cpu, or build with cmake -DRAINDROP_ONNXRUNTIME_GPU=ON (README: GPU)");
    }
    OrtCUDAProviderOptions cuda{};
    cuda.device_id = config.cuda_device;
    // The environment first: the provider logs through it while it loads, and without one
    // ONNX Runtime reports "no default logger" instead of the library that failed to load.
    ort_env();
    try {
      so.AppendExecutionProvider_CUDA(cuda);
    } catch (const Ort::Exception& e) {
      const std::string why = cuda_provider_load_error();
      throw Error(std::string("--device cuda: ONNX Runtime cannot start the CUDA provider: ") + e.what() +
                  (why.empty() ? "" : " (" + why + "; CUDA 13, cuDNN 9 and the NVIDIA driver must be on the library path)"));
    }
  }
  return so;
}

std::string ort_description() {
  return "ONNX Runtime " + Ort::GetVersionString() + " (API " + std::to_string(ORT_API_VERSION) + ")";
}

}  // namespace raindrop::removal

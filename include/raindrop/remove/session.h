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
// Creating it turns ONNX Runtime's telemetry off first (turn_off_onnxruntime_telemetry).
Ort::Env& ort_env();

// ONNX Runtime's official Linux and macOS builds (the PyPI wheel this project links: 1.31
// does; older releases did not) collect usage telemetry: at start-up the library writes a
// persistent device id and an event cache (a SQLite database, synced to disk) under
// ~/.cache/Microsoft/DeveloperTools/.onnxruntime (or $XDG_CACHE_HOME/Microsoft/...) and a file
// in $TMPDIR, and its uploader sends the events to Microsoft. A tool that processes a fleet's
// camera images must not do that behind its users' backs, so raindrop turns it off: this sets
// ORT_DISABLE_TELEMETRY=1, ONNX Runtime's full opt-out, which it reads once, when the process's
// first environment is created (so it works only if raindrop creates that environment, or the
// host program set the variable before making its own). A non-empty value the user set is
// kept: ORT_DISABLE_TELEMETRY=0 opts back in. Call it before starting threads that read the
// environment; the programs do so first thing in main(), Models before it starts its loading
// thread, and ort_env() for everything else.
void turn_off_onnxruntime_telemetry();

// "ONNX Runtime telemetry off (ORT_DISABLE_TELEMETRY=1)", or "ON" with the value from the
// environment that leaves it on, read as ONNX Runtime reads it (off for 1, true, yes, y or on,
// in any case), for --version.
std::string onnxruntime_telemetry_state();

// Execution providers compiled into the loaded library, e.g. {"CPUExecutionProvider"}.
std::vector<std::string> available_providers();

// ONNX Runtime's session option for its intra-op workers' spinning; make_session_options turns
// it off ("0").
inline constexpr const char* kIntraOpSpinningKey = "session.intra_op.allow_spinning";

// Options for one session. Throws raindrop::Error naming the available providers when
// Device::cuda is asked for and the library has no CUDA provider.
Ort::SessionOptions make_session_options(const SessionConfig& config);

// "ONNX Runtime 1.31.1 (API 21)": the loaded library's version and the API level we use.
std::string ort_description();

}  // namespace raindrop::removal

#pragma once
// Where raindrop-remove finds its models when no --models is given, in this order:
//   1. --models DIR                         (the caller passes it as `explicit_dir`)
//   2. $RAINDROP_MODELS: a model folder (holding rdn.onnx) or a folder of configurations
//      (holding <name>/rdn.onnx);
//   3. the installed copy: <exe>/../share/raindrop/models/<name>;
//   4. the source tree's models/<name> (its path is compiled in), for a program run from
//      its build folder.
// <name> is --model-config NAME, or else what DEFAULT in that models folder names, or else
// "compact". DEFAULT's first line names the default configuration; a later line "vnni NAME"
// names its int8 copy, used instead where int8 graphs run fast (ModelSearch::int8_fast: an x86
// CPU with VNNI, the CPU device) and that folder holds models. The source tree's DEFAULT names
// "compact-multiscale" and "vnni compact-multiscale-int8": 0.05 dB lower on average (at most
// 0.10 on a validation set), 1.27-1.39x faster on such a CPU (docs/RESULTS.md 4.60).
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace raindrop::removal {

struct ModelSearch {
  std::optional<std::filesystem::path> explicit_dir;  // --models
  std::optional<std::string> config;                  // --model-config
  std::optional<std::filesystem::path> env_dir;       // $RAINDROP_MODELS (unset/empty: none)
  std::filesystem::path executable;                   // for the installed location; may be empty
  std::filesystem::path source_models;                // the source tree's models/; may be empty
  bool int8_fast = false;                             // DEFAULT's "vnni" line applies (int8_runs_fast)
};

// What DEFAULT in a models folder says: the default configuration and, optionally, its int8
// copy for CPUs where int8 runs fast.
struct DefaultConfig {
  std::string name;
  std::optional<std::string> int8_fast;  // "vnni NAME"
};

// The search of the current process: $RAINDROP_MODELS, /proc/self/exe, the compiled-in
// source folder and int8_fast (int8_runs_fast()) filled in.
ModelSearch default_model_search();

// The model folder to load, or raindrop::Error listing every place tried. `why`, if given,
// receives why DEFAULT's int8 copy was chosen ("" where it was not).
std::filesystem::path find_models(const ModelSearch& search, std::string* why = nullptr);

// What DEFAULT in `models_root` says, if the file exists and names one (trimmed); a
// raindrop::Error for a later line that is neither blank, a # comment nor "vnni NAME".
std::optional<DefaultConfig> read_default(const std::filesystem::path& models_root);

// The configuration DEFAULT names for a CPU where int8 runs fast or not (its int8 copy's name
// or its first line), if the file exists.
std::optional<std::string> read_default_config(const std::filesystem::path& models_root, bool int8_fast = false);

// The folder of the models that reconstruct the coarse pass's large drops for the models in
// `model_dir` (large_drops.h): the sibling configuration named by the one line of the
// optional file `model_dir`/LARGE_DROPS, e.g. models/compact/LARGE_DROPS naming
// paper-real-coarse. std::nullopt without the file; raindrop::Error for a name that is
// not a plain folder name.
std::optional<std::filesystem::path> large_drop_companion(const std::filesystem::path& model_dir);

// The configuration `name` beside `model_dir` (however that folder was written: "models/compact/",
// "."): how LARGE_DROPS and ROUTER (detector_router.h) name another folder. raindrop::Error for
// a name that is not a plain folder name.
std::filesystem::path sibling_model_folder(const std::filesystem::path& model_dir, const std::string& name);

// Throws a one-line raindrop::Error unless `dir` holds rdn.onnx (unless !detector), rrn.onnx
// and rfn.onnx (unless !reconstruction) (files only: their contract is checked when they load).
void check_model_files(const std::filesystem::path& dir, bool detector = true, bool reconstruction = true);

// Whether two paths name the same folder (after resolving links and dots).
bool same_folder(const std::filesystem::path& a, const std::filesystem::path& b);

}  // namespace raindrop::removal

#pragma once
// Where raindrop-remove finds its models when no --models is given, in this order:
//   1. --models DIR                         (the caller passes it as `explicit_dir`)
//   2. $RAINDROP_MODELS: a model folder (holding rdn.onnx) or a folder of configurations
//      (holding <name>/rdn.onnx);
//   3. the installed copy: <exe>/../share/raindrop/models/<name>;
//   4. the source tree's models/<name> (its path is compiled in), for a program run from
//      its build folder.
// <name> is --model-config NAME, or else the one line of DEFAULT in that models folder
// (models/DEFAULT in the source tree names "compact"), or else "compact".
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
};

// The search of the current process: $RAINDROP_MODELS, /proc/self/exe and the compiled-in
// source folder filled in.
ModelSearch default_model_search();

// The model folder to load, or raindrop::Error listing every place tried.
std::filesystem::path find_models(const ModelSearch& search);

// The configuration name DEFAULT in `models_root` names, if the file exists (trimmed).
std::optional<std::string> read_default_config(const std::filesystem::path& models_root);

}  // namespace raindrop::removal

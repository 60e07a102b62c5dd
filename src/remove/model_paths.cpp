#include "raindrop/remove/model_paths.h"

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <system_error>

#include "raindrop/common/error.h"
#include "raindrop/remove/int8_precision.h"

#ifndef RAINDROP_SOURCE_MODELS_DIR
#define RAINDROP_SOURCE_MODELS_DIR ""
#endif

namespace raindrop::removal {
namespace fs = std::filesystem;
namespace {

constexpr const char* kFallbackConfig = "compact";

bool has_models(const fs::path& dir) {
  std::error_code ec;
  return fs::is_regular_file(dir / "rdn.onnx", ec);
}

void check_config_name(const std::string& name) {
  if (name.empty() || name.find('/') != std::string::npos || name == "." || name == "..")
    throw Error("model configuration name '" + name + "' is not a plain folder name");
}

// The next line of `in`, trimmed; std::nullopt at the end or for a blank line.
std::optional<std::string> next_line_trimmed(std::istream& in) {
  std::string line;
  if (!std::getline(in, line)) return std::nullopt;
  const auto first = line.find_first_not_of(" \t\r");
  const auto last = line.find_last_not_of(" \t\r");
  if (first == std::string::npos) return std::nullopt;
  return line.substr(first, last - first + 1);
}

// The first line of a small text file, trimmed; std::nullopt if the file is missing or blank.
std::optional<std::string> read_first_line(const fs::path& file) {
  std::ifstream in(file);
  return next_line_trimmed(in);
}

}  // namespace

std::optional<DefaultConfig> read_default(const fs::path& models_root) {
  const fs::path file = models_root / "DEFAULT";
  std::ifstream in(file);
  const auto name = next_line_trimmed(in);
  if (!name) return std::nullopt;
  DefaultConfig d{*name, std::nullopt};
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string key, value, extra;
    if (!(words >> key) || key[0] == '#') continue;
    if (key != "vnni" || !(words >> value) || (words >> extra && extra[0] != '#'))
      throw Error("'" + file.string() + "': a line after the first must be 'vnni NAME' (the int8 copy for CPUs with VNNI), not '" +
                  line + "'");
    if (d.int8_fast) throw Error("'" + file.string() + "' has more than one 'vnni' line");
    check_config_name(value);
    d.int8_fast = value;
  }
  return d;
}

std::optional<std::string> read_default_config(const fs::path& models_root, bool int8_fast) {
  const auto d = read_default(models_root);
  if (!d) return std::nullopt;
  return int8_fast && d->int8_fast ? *d->int8_fast : d->name;
}

std::optional<fs::path> large_drop_companion(const fs::path& model_dir) {
  const auto name = read_first_line(model_dir / "LARGE_DROPS");
  if (!name) return std::nullopt;
  return sibling_model_folder(model_dir, *name);
}

fs::path sibling_model_folder(const fs::path& model_dir, const std::string& name) {
  check_config_name(name);
  // A sibling of the folder itself, however it was written ("models/compact/", ".").
  std::error_code ec;
  fs::path dir = fs::weakly_canonical(fs::absolute(model_dir, ec), ec);
  if (ec) dir = fs::absolute(model_dir).lexically_normal();
  if (!dir.has_filename()) dir = dir.parent_path();
  return dir.parent_path() / name;
}

void check_model_files(const fs::path& dir, bool detector, bool reconstruction) {
  std::error_code ec;
  std::vector<std::string> needed;
  if (detector) needed.push_back("rdn.onnx");
  if (reconstruction) needed.insert(needed.end(), {"rrn.onnx", "rfn.onnx"});
  std::string list;
  for (size_t i = 0; i < needed.size(); ++i)
    list += (i == 0 ? "" : i + 1 == needed.size() ? " and " : ", ") + needed[i];
  for (const std::string& file : needed) {
    if (!fs::is_regular_file(dir / file, ec))
      throw Error("model folder '" + dir.string() + "' has no " + file + " (it needs " + list + ")");
  }
}

bool same_folder(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  const fs::path ca = fs::weakly_canonical(a, ec);
  if (ec) return a.lexically_normal() == b.lexically_normal();
  const fs::path cb = fs::weakly_canonical(b, ec);
  if (ec) return a.lexically_normal() == b.lexically_normal();
  return ca == cb;
}

ModelSearch default_model_search() {
  ModelSearch s;
  if (const char* env = std::getenv("RAINDROP_MODELS"); env && *env) s.env_dir = fs::path(env);
  std::error_code ec;
  s.executable = fs::read_symlink("/proc/self/exe", ec);
  if (ec) s.executable.clear();
  s.source_models = RAINDROP_SOURCE_MODELS_DIR;
  s.int8_fast = int8_runs_fast();
  return s;
}

fs::path find_models(const ModelSearch& s, std::string* why) {
  if (why) why->clear();
  if (s.explicit_dir) return *s.explicit_dir;  // loading it says what is wrong with it
  if (s.config) check_config_name(*s.config);
  // The configuration to look for in `root`: --model-config, or what its DEFAULT names (its
  // int8 copy where that applies and holds models, said in `why`), or the fallback.
  const auto name_in = [&](const fs::path& root) {
    if (s.config) return *s.config;
    const auto d = read_default(root);
    if (!d) return std::string(kFallbackConfig);
    if (s.int8_fast && d->int8_fast && has_models(root / *d->int8_fast)) {
      if (why) *why = "DEFAULT's int8 copy of " + d->name + ": this CPU has VNNI";
      return *d->int8_fast;
    }
    check_config_name(d->name);
    return d->name;
  };
  if (s.env_dir) {
    // An explicit environment variable is authoritative: no fall-back past it.
    if (!s.config && has_models(*s.env_dir)) return *s.env_dir;
    const fs::path dir = *s.env_dir / name_in(*s.env_dir);
    if (has_models(dir)) return dir;
    throw Error("$RAINDROP_MODELS is '" + s.env_dir->string() + "', but neither it nor '" + dir.string() +
                "' holds rdn.onnx, rrn.onnx and rfn.onnx");
  }
  std::vector<fs::path> roots;
  if (!s.executable.empty()) roots.push_back(s.executable.parent_path().parent_path() / "share" / "raindrop" / "models");
  if (!s.source_models.empty()) roots.push_back(s.source_models);
  std::string tried;
  for (const auto& root : roots) {
    const fs::path dir = root / name_in(root);
    if (has_models(dir)) return dir;
    tried += (tried.empty() ? "" : ", ") + ("'" + dir.string() + "'");
  }
  throw Error("no models found (tried " + (tried.empty() ? std::string("nothing") : tried) +
              "); pass --models DIR or set RAINDROP_MODELS, or train and export a configuration into models/<name> "
              "(python -m raindrop_tools.export)");
}

}  // namespace raindrop::removal

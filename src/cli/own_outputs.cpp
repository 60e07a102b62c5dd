#include "own_outputs.h"

#include <fstream>

#include "raindrop/common/image_io.h"

namespace raindrop::cli {
namespace fs = std::filesystem;

namespace {
constexpr const char* kHeader = "raindrop-remove wrote the files listed below; a later run may replace them, and no other file here.";
}

std::set<std::string> read_own_outputs(const fs::path& folder) {
  std::set<std::string> names;
  std::ifstream in(folder / kOwnOutputsList);
  std::string line;
  if (!std::getline(in, line)) return names;  // no list (or an empty one)
  while (std::getline(in, line)) {
    if (!line.empty()) names.insert(line);
  }
  return names;
}

void add_own_outputs(const fs::path& folder, const std::set<std::string>& names) {
  std::set<std::string> all = read_own_outputs(folder);
  all.insert(names.begin(), names.end());
  std::string text = std::string(kHeader) + "\n";
  // A name with a line break cannot be listed: its file stays protected (a later run refuses
  // to replace it rather than misread the list).
  for (const auto& n : all)
    if (n.find_first_of("\r\n") == std::string::npos) text += n + "\n";
  write_text_atomic(text, folder / kOwnOutputsList);
}

}  // namespace raindrop::cli
